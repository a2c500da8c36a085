"""The compositor servicer in an in-process server on port 0."""

import json

import grpc
import numpy as np
import pytest

from ig.v1 import compositor_pb2, compositor_pb2_grpc, frame_pb2
from services.compositor.server import Compositor, CompositorServicer
from services.rig.grpc_util import add_health, check_health, make_channel, make_server
from services.rig.image_io import read_image


@pytest.fixture
def served(tmp_path):
    comp = Compositor(("a", "b"), tmp_path, exr_every=1)
    server = make_server()
    compositor_pb2_grpc.add_CompositorServiceServicer_to_server(CompositorServicer(comp), server)
    add_health(server, ["ig.v1.CompositorService"])
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    yield comp, f"127.0.0.1:{port}"
    server.stop(0).wait()


def req(n, ch, **kw):
    px = np.full((2, 3, 3), 0.5, "<f2")
    e = frame_pb2.Eyepoint(x=1.0, y=2.0, z=3.0)
    base = dict(frame_number=n, channel_name=ch, width=3, height=2, pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16,
                pixels=px.tobytes(), eyepoint=e)
    base.update(kw)
    return compositor_pb2.SubmitChannelImageRequest(**base)


def test_submit_report_health_and_invalid_argument(served, tmp_path):
    comp, address = served
    assert check_health(address) == "SERVING"
    comp.on_published(frame_pb2.Frame(frame_number=0, eyepoint=frame_pb2.Eyepoint(x=1.0, y=2.0, z=3.0)))
    with make_channel(address) as ch:
        stub = compositor_pb2_grpc.CompositorServiceStub(ch)
        stub.SubmitChannelImage(req(0, "a"), timeout=5)
        stub.SubmitChannelImage(req(0, "b"), timeout=5)
        with pytest.raises(grpc.RpcError) as err:
            stub.SubmitChannelImage(req(0, "zz"), timeout=5)
        assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        assert "channel_name: 'zz'" in err.value.details()
        with pytest.raises(grpc.RpcError) as err:
            stub.SubmitChannelImage(req(0, "a", eyepoint=frame_pb2.Eyepoint(x=1.0, y=float("inf"))), timeout=5)
        assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        assert "eyepoint.y: inf is not finite" in err.value.details()
        progress = stub.GetCompositorReport(compositor_pb2.GetCompositorReportRequest(), timeout=5)
        assert (progress.frames_published, progress.frames_complete, progress.finished) == (1, 1, False)
        doc = comp.finish(grace_s=1.0)
        assert doc["frames_complete"] == 1 and doc["frames_written"] == 1
        response = stub.GetCompositorReport(compositor_pb2.GetCompositorReportRequest(), timeout=5)
        report = json.loads(response.report_json)
        assert response.finished and response.frames_written == 1 and response.frames_incomplete == 0
        assert report["rejected_submissions"] == {"non_finite_eyepoint": 1, "unknown_channel": 1}
        with pytest.raises(grpc.RpcError) as err:  # after the report, nothing more is accepted
            stub.SubmitChannelImage(req(1, "a"), timeout=5)
        assert err.value.code() == grpc.StatusCode.FAILED_PRECONDITION
    pixels, attrs = read_image(tmp_path / "latest" / "frames" / "frame_000000.exr")
    assert pixels.shape == (2, 6, 3) and attrs["channels"] == "a,b"
    assert json.loads((tmp_path / "latest" / "report.json").read_text())["frames_complete"] == 1


def wait_until(predicate, timeout_s=10.0):
    import time
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def stamped(n, ch, base, pixels):
    """A submission of frame n whose worker stamps start at base (UNIX seconds)."""
    return req(n, ch, pixels=pixels.tobytes(), run_id="r", control_sample_time_unix_s=base,
               frame_received_unix_s=base + 0.002, render_start_unix_s=base + 0.003,
               render_end_unix_s=base + 0.020, submit_unix_s=base + 0.021)


def test_watch_composites_streams_time_stamps_and_row_profiles(served):
    comp, address = served
    rows = np.zeros((2, 3, 3), "<f2")
    rows[1] = 1.0  # the second row white: luminance 0, then 1
    with make_channel(address) as ch:
        stub = compositor_pb2_grpc.CompositorServiceStub(ch)
        with pytest.raises(grpc.RpcError) as err:
            next(stub.WatchComposites(compositor_pb2.WatchCompositesRequest(profile_channels=["zz"]), timeout=5))
        assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        assert "profile_channels: 'zz' is not a channel of the rig (a, b)" in err.value.details()
        stream = stub.WatchComposites(compositor_pb2.WatchCompositesRequest(watcher="test", profile_channels=["b"]),
                                      timeout=30)
        wait_until(lambda: len(comp.watchers) == 1)
        base = 1_700_000_000.0
        comp.on_published(frame_pb2.Frame(
            frame_number=0, run_id="r", sim_time_s=0.5, eyepoint=frame_pb2.Eyepoint(x=1.0, y=2.0, z=3.0),
            control_sample_time_unix_s=base, publish_time_unix_s=base + 0.001))
        stub.SubmitChannelImage(stamped(0, "a", base, np.zeros((2, 3, 3), "<f2")), timeout=5)
        stub.SubmitChannelImage(stamped(0, "b", base, rows), timeout=5)
        first = next(stream)
        assert (first.frame_number, first.run_id, first.sim_time_s) == (0, "r", 0.5)
        assert (first.eyepoint.x, first.eyepoint.z) == (1.0, 3.0)
        assert first.control_sample_time_unix_s == base and first.publish_time_unix_s == base + 0.001
        assert [c.channel_name for c in first.channels] == ["a", "b"]
        b = first.channels[1]
        assert (b.frame_received_unix_s, b.render_start_unix_s, b.render_end_unix_s, b.submit_unix_s) == (
            base + 0.002, base + 0.003, base + 0.020, base + 0.021)
        assert b.submit_unix_s <= b.compositor_receive_unix_s <= first.composite_time_unix_s
        assert [p.channel_name for p in first.profiles] == ["b"]
        np.testing.assert_allclose(first.profiles[0].luminance, [0.0, 1.0], atol=1e-6)
        assert first.watcher_drops == 0
        comp.finish(grace_s=0.0)  # the run is over: the stream ends
        assert list(stream) == []
    report = comp.report()
    assert report["latency_chain"]["render"]["count"] == 1
    assert report["latency_chain"]["render"]["p50_ms"] == pytest.approx(17.0)
    assert report["control_to_composite_latency"]["count"] == 1
    assert report["record_every"] == 1 and report["frames_not_recorded"] == 0 and report["frames_written"] == 1
