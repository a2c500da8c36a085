"""The worker renders the newest frame only and counts what it skipped; bad frames are refused."""

import numpy as np
from ig.v1 import frame_pb2

from channel_worker.worker import ChannelWorker, LatestFrame, encode_rgb_f16
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
    from ig.v1 import worker_pb2, worker_pb2_grpc

    from channel_worker.worker import SERVICE, WorkerStatusServicer
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

    from ig.v1 import host_pb2_grpc

    from host_sim.publisher import FramePublisher
    from host_sim.server import HostServicer
    from services.rig.frame import Eyepoint
    from services.rig.grpc_util import make_server

    pub = FramePublisher(source=lambda t: Eyepoint.of(0, 0, 10, 0, 0, 0), channels=["left"], duration_s=0.0)
    stop = threading.Event()
    server = make_server(max_workers=4)
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(pub, stop), server)
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
