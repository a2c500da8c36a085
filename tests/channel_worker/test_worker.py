"""The worker renders the newest frame only and counts what it skipped; bad frames are refused."""

import logging
import threading

import numpy as np

from channel_worker.submit import encode_rgb_f16
from channel_worker.worker import ChannelWorker, LatestFrame
from ig.v1 import frame_pb2
from services.rig.frame import ChannelSpec
from services.rig.options import RenderOptions


def frame(n, x=0.0):
    return frame_pb2.Frame(frame_number=n, eyepoint=frame_pb2.Eyepoint(x=x, y=-900.0, z=3.0), run_id="r")


def test_mailbox_keeps_only_the_newest_frame():
    box = LatestFrame()
    for n in range(5):
        box.put(frame(n))
    assert box.take(0.01).frame_number == 4
    assert box.take(0.01) is None
    box.end()
    assert box.ended


class FakeStub:
    def __init__(self):
        self.calls = []

    def SubmitChannelImage(self, request, timeout):
        assert timeout > 0
        self.calls.append(("submit", request.frame_number, request.frames_skipped))

    def AckFrame(self, request, timeout):
        assert timeout > 0
        self.calls.append(("ack", request.frame_number, request.ok, request.error))


def worker(make_scene, box_model_factory):
    db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
    w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address="127.0.0.1:1",
                      compositor_address="127.0.0.1:1", options=RenderOptions(samples=1))
    stub = FakeStub()
    w.host_stub = w.compositor_stub = stub
    return w, stub


def test_skipped_frames_are_counted_and_reported(make_scene, box_model_factory):
    w, stub = worker(make_scene, box_model_factory)
    for n in (0, 1, 4, 5, 9):
        w._handle(frame(n))
    assert w.counters.frames_skipped == 2 + 3
    assert w.counters.frames_rendered == 5
    submits = [c for c in stub.calls if c[0] == "submit"]
    assert [c[1] for c in submits] == [0, 1, 4, 5, 9]
    assert submits[-1][2] == 5


def test_nan_eyepoint_is_refused_acked_as_failed_and_the_worker_goes_on(make_scene, box_model_factory):
    w, stub = worker(make_scene, box_model_factory)
    w._handle(frame(0, x=float("nan")))
    w._handle(frame(1))
    assert w.counters.frames_refused == 1
    assert stub.calls[0][0] == "ack" and stub.calls[0][2] is False
    assert "eyepoint.position[0]: nan is not finite" in stub.calls[0][3]
    assert ("submit", 1, 0) in stub.calls


def test_pixels_are_little_endian_half_rows_top_first():
    rgb = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    raw = encode_rgb_f16(rgb)
    assert len(raw) == 2 * 3 * 3 * 2
    np.testing.assert_array_equal(np.frombuffer(raw, "<f2").reshape(2, 3, 3), rgb)


def test_status_rpc_reports_the_counters(make_scene, box_model_factory):
    from channel_worker.worker import SERVICE, WorkerStatusServicer
    from ig.v1 import worker_pb2, worker_pb2_grpc
    from services.rig.grpc_util import add_health, check_health, make_channel, make_server

    w, _ = worker(make_scene, box_model_factory)
    w._handle(frame(0))
    w._handle(frame(3, x=float("nan")))
    server = make_server(max_workers=2)
    worker_pb2_grpc.add_ChannelWorkerServiceServicer_to_server(WorkerStatusServicer(w), server)
    add_health(server, [SERVICE])
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        address = f"127.0.0.1:{port}"
        assert check_health(address) == "SERVING"
        with make_channel(address) as ch:
            s = worker_pb2_grpc.ChannelWorkerServiceStub(ch).GetWorkerStatus(worker_pb2.GetWorkerStatusRequest(),
                                                                             timeout=5)
        assert (s.channel_name, s.frames_handled, s.frames_rendered, s.frames_refused, s.frames_skipped) == \
            ("centre", 2, 1, 1, 2)
        assert s.last_frame_number == 3 and s.run_id == "r" and not s.subscribed
        assert "frame 3 refused: eyepoint.position[0]: nan is not finite" in s.last_error
    finally:
        server.stop(0).wait()


def test_a_refused_subscription_ends_the_worker_with_the_reason(make_scene, box_model_factory):
    import threading

    from host_sim.publisher import FramePublisher
    from host_sim.server import HostServicer
    from ig.v1 import host_pb2_grpc
    from services.rig.frame import Eyepoint
    from services.rig.grpc_util import make_server

    pub = FramePublisher(source=lambda t: Eyepoint.of(0, 0, 10, 0, 0, 0), channels=["left"], duration_s=0.0)
    stop = threading.Event()
    server = make_server(max_workers=4)
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(pub), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
        w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address=f"127.0.0.1:{port}",
                          compositor_address=f"127.0.0.1:{port}", options=RenderOptions(samples=1))
        w.run(threading.Event())  # returns: the host does not know "centre"
        assert "channel_name: 'centre' is not a channel of the rig (left)" in w.refused
        assert w.counters.frames_handled == 0
    finally:
        stop.set()
        server.stop(0).wait()


def test_terrain_voxels_are_reported_per_frame_and_in_total(make_scene, box_model_factory):
    import dataclasses

    from channel_worker.testing.terrain_reference import single_level_database

    heights = np.zeros((9, 9))
    heights[4, 4] = 30.0  # a hill ahead of the eye
    colours = np.full((9, 9, 3), 120, np.uint8)
    db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
    db = dataclasses.replace(db, terrain=single_level_database(heights, colours, 50.0, (-200.0, -950.0, 0.0)))
    w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address="127.0.0.1:1",
                      compositor_address="127.0.0.1:1", options=RenderOptions(samples=1))
    w.host_stub = w.compositor_stub = FakeStub()
    w._handle(frame(0))
    first = w.counters.terrain_voxels_last_frame
    assert first > 0
    w._handle(frame(1, x=1.0))
    assert w.counters.terrain_voxels_total == first + w.counters.terrain_voxels_last_frame
    assert w.counters.terrain_eye_clamped == 0
    w._handle(frame(2))  # eye 3 m up at y = -900 is inside the database, above the flat ground
    status = w.status()
    assert status.terrain_voxels_last_frame == w.counters.terrain_voxels_last_frame
    assert status.terrain_voxels_total == w.counters.terrain_voxels_total
    # The background stage's parts: each measured, together inside the stage's time.
    stages = {s.stage: s.seconds for s in status.last_frame_report.stages}
    parts = {s.stage: s.seconds for s in status.last_frame_report.parts}
    assert set(parts) == {"background.cast", "background.depth", "background.clouds"}
    assert all(v >= 0.0 for v in parts.values())
    assert sum(parts.values()) <= stages["background"]


def test_health_is_not_serving_until_the_worker_can_render(make_scene, box_model_factory):
    """A worker serves health at once, NOT_SERVING while its kernels compile (the host knows it
    is alive and waits), SERVING once its warm-up frame rendered; its status says the same and
    names its options and its last frame's report."""
    import socket
    import threading
    import time

    import grpc

    from channel_worker.worker import serve_worker
    from services.rig.grpc_util import check_health
    from services.rig.wire import options_from_proto

    w, _ = worker(make_scene, box_model_factory)
    release = threading.Event()
    warm_up = w.warm_up

    def slow_warm_up():
        assert release.wait(60.0)
        warm_up()

    w.warm_up = slow_warm_up
    stop = threading.Event()
    w.run = lambda event: event.wait()  # no host: serve until stopped
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{s.getsockname()[1]}"
    server = threading.Thread(target=serve_worker, args=(w, address, stop))
    server.start()

    def health():
        for _ in range(600):
            try:
                return check_health(address, timeout_s=1.0)
            except grpc.RpcError:
                time.sleep(0.05)
        raise AssertionError("the worker never answered")

    try:
        assert health() == "NOT_SERVING"
        status = w.status()
        assert not status.ready and options_from_proto(status.render_options) == w.options
        release.set()
        for _ in range(600):
            if health() == "SERVING":
                break
            time.sleep(0.05)
        assert health() == "SERVING" and w.status().ready
    finally:
        release.set()
        stop.set()
        server.join()


def test_the_status_reports_the_last_frames_stage_times(make_scene, box_model_factory):
    from services.rig.wire import report_from_proto

    w, _ = worker(make_scene, box_model_factory)
    w._handle(frame(0))
    report = report_from_proto(w.status().last_frame_report)
    assert report == w.last_report  # the frame's own report, every stage and counter
    assert list(report.stage_seconds)[:2] == ["view", "cull"] and "visibility" in report.stage_seconds
    assert "entries_skipped_by_depth" in report.counters


def test_the_log_shows_the_frame_report_at_the_start_of_a_run_and_every_few_seconds(
        make_scene, box_model_factory, caplog):
    from channel_worker.worker import REPORT_EVERY

    w, _ = worker(make_scene, box_model_factory)
    with caplog.at_level(logging.INFO, logger="ig.worker"):
        for n in (0, 1, 2, REPORT_EVERY):
            w._handle(frame(n))
    info = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
    assert [m.split(":")[0] for m in info] == ["worker centre frame 0", f"worker centre frame {REPORT_EVERY}"]
    assert "visibility" in info[0] and "total" in info[0]


def test_the_shared_memory_segment_goes_when_the_worker_stops(make_scene, box_model_factory):
    """SIGTERM sets the stop event (grpc_util.stop_on_signals); run's way out removes the segment."""
    import threading

    from services.rig.shared_images import SHM_DIR, shared_memory_supported

    w, _ = worker(make_scene, box_model_factory)
    if not shared_memory_supported():
        assert not w.sender.shared
        return
    assert w.sender.shared  # the compositor's address is this machine's
    segment = SHM_DIR / w.sender.ring.name
    assert segment.exists()
    stop = threading.Event()
    stop.set()
    w.run(stop)
    assert not segment.exists() and not w.sender.shared


def _serve_host(pub):
    """HostService over pub on an in-process server: (server, address)."""
    from host_sim.server import HostServicer
    from ig.v1 import host_pb2_grpc
    from services.rig.grpc_util import make_server

    server = make_server(max_workers=4)
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(pub), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    return server, f"127.0.0.1:{port}"


class _CountedStop(threading.Event):
    """A stop event that records every pause asked of it and sets itself after `pauses` of them."""

    def __init__(self, pauses):
        super().__init__()
        self.pauses = pauses
        self.asked = []

    def wait(self, timeout=None):
        self.asked.append(timeout)
        if len(self.asked) >= self.pauses:
            self.set()
        return self.is_set()


def test_a_worker_pauses_before_asking_an_ended_run_again(make_scene, box_model_factory):
    # After a run the host lingers and refuses new subscriptions; the worker used to ask again at
    # once, thousands of times a second (issue 33). It now pauses, longer after each refusal.
    from host_sim.publisher import FramePublisher
    from services.rig.frame import Eyepoint
    from services.rig.resubscribe import RUN_ENDED_FIRST_PAUSE_S, RUN_ENDED_MAX_PAUSE_S

    pub = FramePublisher(source=lambda t: Eyepoint.of(0, 0, 10, 0, 0, 0), channels=["centre"], duration_s=0.0,
                         start_timeout_s=0.0)
    pub.run(threading.Event())
    server, address = _serve_host(pub)
    try:
        db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
        w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address=address,
                          compositor_address=address, options=RenderOptions(samples=1))
        stop = _CountedStop(4)
        w.run(stop)
    finally:
        server.stop(0).wait()
    assert stop.asked == [RUN_ENDED_FIRST_PAUSE_S, *[RUN_ENDED_MAX_PAUSE_S] * 3]
    assert w.counters.resubscriptions == 4 and w.counters.frames_handled == 0 and not w.refused
    assert pub.snapshot().requests_refused == {"run_ended": 4}


def test_a_once_worker_ends_with_the_run_and_does_not_render_its_end(make_scene, box_model_factory):
    from host_sim.publisher import FramePublisher
    from services.rig.frame import Eyepoint

    pub = FramePublisher(source=lambda t: Eyepoint.of(0, -900.0 + t, 3, 0, 0, 0), channels=["centre"],
                         rate_hz=100.0, duration_s=0.04, start_timeout_s=60.0)
    server, address = _serve_host(pub)
    stop = threading.Event()
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    try:
        db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
        w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address=address,
                          compositor_address=address, options=RenderOptions(samples=1), once=True)
        w.run(stop)  # returns at the end of the run: the stream's last message is not a frame
        runner.join()
    finally:
        stop.set()
        server.stop(0).wait()
    assert w.counters.frames_handled == pub.tick_count == 5
    assert w.counters.run_id == pub.status.run_id and w.counters.last_frame_number == 4
    assert w.counters.resubscriptions == 0
