"""The host servicer in an in-process server on port 0."""

import threading

import grpc
import pytest

from host_sim.publisher import FramePublisher
from host_sim.server import SERVICE, HostServicer
from ig.v1 import host_pb2, host_pb2_grpc
from services.rig.frame import Eyepoint
from services.rig.grpc_util import add_health, check_health, make_channel, make_server


@pytest.fixture
def host():
    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0.0, 10.0, 0.0, 0.0, 0.0), channels=["left", "right"],
                         rate_hz=100.0, duration_s=0.05, observers=1, start_timeout_s=60.0)
    stop = threading.Event()
    server = make_server()
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(pub), server)
    add_health(server, [SERVICE])
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    yield pub, stop, f"127.0.0.1:{port}"
    stop.set()
    server.stop(0).wait()


def test_stream_ack_status_health_and_refusals(host):
    pub, stop, address = host
    assert check_health(address) == "SERVING"
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    with make_channel(address) as ch:
        stub = host_pb2_grpc.HostServiceStub(ch)
        with pytest.raises(grpc.RpcError) as err:
            next(iter(stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="x", channel_name="middle"),
                                           timeout=10)))
        assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        assert "channel_name: 'middle' is not a channel of the rig (left, right)" in err.value.details()

        got = {}

        def channel(name):
            frames = []
            for r in stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber=name, channel_name=name),
                                          timeout=60):
                if not r.HasField("frame"):
                    continue
                frames.append(r.frame.frame_number)
                stub.AckFrame(host_pb2.AckFrameRequest(channel_name=name, frame_number=r.frame.frame_number,
                                                       ok=True), timeout=10)
            got[name] = frames

        threads = [threading.Thread(target=channel, args=(n,)) for n in ("left", "right")]
        for t in threads:
            t.start()
        *messages, last = stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="obs"), timeout=60)
        observed = [r.frame for r in messages]
        for t in threads:
            t.join()
        runner.join()
        assert [f.frame_number for f in observed] == list(range(pub.tick_count))
        # The stream's last message is the end of the run, with the final counters.
        assert last.WhichOneof("content") == "run_end"
        assert last.run_end.reason == host_pb2.RUN_END_REASON_COMPLETED
        assert last.run_end.host_status.finished and last.run_end.host_status.frames_published == pub.tick_count
        assert got == {"left": list(range(pub.tick_count)), "right": list(range(pub.tick_count))}
        assert observed[1].eyepoint.x == pytest.approx(0.01)

        with pytest.raises(grpc.RpcError) as err:
            stub.AckFrame(host_pb2.AckFrameRequest(channel_name="bogus", frame_number=0), timeout=10)
        assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT and "'bogus'" in err.value.details()

        status = stub.GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=10)
        assert status.finished and status.frames_published == pub.tick_count
        # The refused subscription is counted; the last error is the refused acknowledgement's.
        assert status.subscriptions_rejected == 1 and "'bogus'" in status.last_error
        assert dict(status.requests_refused) == {"unknown_channel": 1}
        assert dict(status.ack_timeouts) == {"left": 0, "right": 0}
        assert dict(status.channel_absent) == {"left": 0, "right": 0}


def serve_in_process(pub, eyepoints):
    stop = threading.Event()
    server = make_server()
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(pub, eyepoints=eyepoints), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    return server, stop, f"127.0.0.1:{port}"


def test_status_shows_the_control_sources_and_their_refusals():
    can = pytest.importorskip("can", reason="python-can is in the devices extra")
    from host_sim.controlled import ControlledFlight
    from host_sim.inputs import canaerospace as ca
    from host_sim.inputs import open_source

    flight = ControlledFlight([open_source("can://virtual/status-test?stale_after=0.2")])
    tx = can.Bus(interface="virtual", channel="status-test")
    try:
        can_id, data = ca.encode("throttle_1_lever_position", 0.5)
        tx.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
        can_id, data = ca.encode("pitch_control_position", 7.0)
        tx.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
        pub = FramePublisher(source=flight.eyepoint_at, channels=["left"], rate_hz=100.0, duration_s=0.05,
                             start_timeout_s=0.0)
        server, stop, address = serve_in_process(pub, flight)
        try:
            pub.run(stop)
            with make_channel(address) as ch:
                status = host_pb2_grpc.HostServiceStub(ch).GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=10)
        finally:
            server.stop(0).wait()
    finally:
        tx.shutdown()
        flight.close()
    assert status.eyepoint_source == "controls"
    [src] = status.inputs
    assert src.name == "can://virtual/status-test?stale_after=0.2"
    assert src.accepted == 1 and src.rejected["out_of_range"] == 1 and src.rejected["bad_crc"] == 0
    assert "pitch_control_position (400): 7 is outside [-1, 1]" in src.last_rejection
    assert dict(src.values) == {"throttle_1_lever_position": 0.5}
    assert status.flight_model.steps == 6 and status.flight_model.on_ground


def test_status_shows_the_replay(tmp_path):
    from host_sim.replay import Replay, load_track

    path = tmp_path / "f.csv"
    path.write_text("time_s,x_m,y_m,z_m\n0,0,0,10\n1,0,40,10\n1,0,40,10\n2,0,80,12\n")
    track, fmt = load_track(path)
    replay = Replay(track, speed=2.0, path=str(path), format=fmt)
    pub = FramePublisher(source=replay.eyepoint_at, channels=["left"], rate_hz=100.0, duration_s=replay.duration_s,
                         start_timeout_s=0.0)
    server, stop, address = serve_in_process(pub, replay)
    try:
        pub.run(stop)
        with make_channel(address) as ch:
            status = host_pb2_grpc.HostServiceStub(ch).GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=10)
    finally:
        server.stop(0).wait()
    assert status.eyepoint_source == "replay" and status.frames_published == 101
    r = status.replay
    assert (r.format, r.records, r.log_duration_s, r.log_time_s, r.loops) == ("csv", 3, 2.0, 2.0, 0)
    assert dict(r.problems)["duplicate"] == 1 and r.attitude_estimated


def test_status_of_the_bundled_flight(host):
    _, _, address = host
    with make_channel(address) as ch:
        status = host_pb2_grpc.HostServiceStub(ch).GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=10)
    assert status.eyepoint_source == "bundled" and not status.inputs and not status.HasField("replay")


def test_a_stopped_host_ends_every_stream_with_every_frame_and_its_final_counters():
    # SIGTERM mid-run (issue 33): the streams still deliver every frame published, then the end
    # of the run with the host's counters, so the compositor need not ask a host that is going.
    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0.0, 10.0, 0.0, 0.0, 0.0), channels=["left"],
                         rate_hz=100.0, duration_s=3600.0, observers=1, start_timeout_s=60.0)
    server, stop, address = serve_in_process(pub, None)
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    try:
        with make_channel(address) as ch:
            stub = host_pb2_grpc.HostServiceStub(ch)

            def channel():
                for r in stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="w", channel_name="left"),
                                              timeout=60):
                    if r.HasField("frame"):
                        stub.AckFrame(host_pb2.AckFrameRequest(channel_name="left", frame_number=r.frame.frame_number,
                                                               ok=True, run_id=r.frame.run_id), timeout=10)

            worker = threading.Thread(target=channel)
            worker.start()
            messages = []
            for r in stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="obs"), timeout=60):
                messages.append(r)
                if len(messages) == 5:
                    stop.set()
            worker.join()
            runner.join()
            *frames, last = messages
            assert all(m.HasField("frame") for m in frames)
            assert last.WhichOneof("content") == "run_end"
            assert last.run_end.reason == host_pb2.RUN_END_REASON_STOPPED
            status = last.run_end.host_status
            assert status.finished and status.run_id == pub.status.run_id
            assert status.frames_published == len(frames) == [f.frame.frame_number for f in frames][-1] + 1
            assert status.eyepoint_source == "bundled"
            assert pub.wait_streams_ended(10.0)  # each handler forgot its subscription
    finally:
        stop.set()
        runner.join()
        server.stop(0).wait()


def test_a_subscription_after_the_run_is_failed_precondition_saying_so(host):
    from services.rig.resubscribe import run_ended

    pub, stop, address = host
    pub.start_timeout_s = 0.0
    pub.run(stop)
    with make_channel(address) as ch:
        stub = host_pb2_grpc.HostServiceStub(ch)
        with pytest.raises(grpc.RpcError) as err:
            next(iter(stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="late", channel_name="left"),
                                           timeout=10)))
        assert err.value.code() == grpc.StatusCode.FAILED_PRECONDITION and run_ended(err.value)
        assert f"run_id '{pub.status.run_id}' has ended" in err.value.details()
        status = stub.GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=10)
        assert dict(status.requests_refused) == {"run_ended": 1} and not status.subscribers
