"""A worker's /metrics over HTTP: its counters are its GetWorkerStatus, and every rendered frame's
FrameReport lands in the stage histograms."""

import socket
import threading
import time

import pytest

from channel_worker.worker import ChannelWorker, serve_worker
from ig.v1 import frame_pb2
from services.rig.frame import ChannelSpec
from services.rig.metrics import sample_values, scrape, serve_metrics
from services.rig.options import RenderOptions


class FakeStub:
    def SubmitChannelImage(self, request, timeout):
        pass

    def AckFrame(self, request, timeout):
        pass


def frame(n, x=0.0):
    return frame_pb2.Frame(frame_number=n, eyepoint=frame_pb2.Eyepoint(x=x, y=-900.0, z=3.0), run_id="r")


def worker(make_scene, box_model_factory, *, fake_stubs=True):
    db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
    w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address="127.0.0.1:1",
                      compositor_address="127.0.0.1:1", options=RenderOptions(samples=1))
    if fake_stubs:
        w.host_stub = w.compositor_stub = FakeStub()
    return w


def by(family, label, suffix):
    return {dict(labels)[label]: v for labels, v in sample_values(family, suffix).items()}


def test_the_worker_counters_are_its_status_and_each_frame_its_stage_times(make_scene, box_model_factory):
    w = worker(make_scene, box_model_factory)
    for n in (0, 1, 4):
        w._handle(frame(n))
    w._handle(frame(5, x=float("nan")))  # refused: counted, not rendered, no stage times
    stages = dict(w.last_report.stage_seconds)
    status = w.status()
    with serve_metrics(w.metrics.registry, "127.0.0.1:0") as endpoint:
        m = scrape(f"127.0.0.1:{endpoint.port}")
    assert (status.frames_handled, status.frames_rendered, status.frames_skipped, status.frames_refused) == (4, 3, 2, 1)
    for field in ("frames_handled", "frames_rendered", "frames_skipped", "frames_refused", "submit_failures",
                  "ack_failures", "translucent_dropped", "terrain_voxels_total", "terrain_eye_clamped", "runs",
                  "malformed_requests", "resubscriptions"):
        name = "ig_worker_" + field.removesuffix("_total")
        assert sample_values(m[name], "_total") == {(("channel", "centre"),): getattr(status, field)}, field
    assert sample_values(m["ig_worker_last_frame_number"]) == {(("channel", "centre"),): 5}
    assert sample_values(m["ig_worker_ready"]) == {(("channel", "centre"),): 0}
    assert m["ig_worker_stage_seconds"].type == "histogram"
    # One observation per rendered frame, of every stage the pipeline ran.
    assert sample_values(m["ig_worker_render_seconds"], "_count") == {(("channel", "centre"),): 3}
    counts = by(m["ig_worker_stage_seconds"], "stage", "_count")
    assert stages and counts == dict.fromkeys(stages, 3)
    sums = by(m["ig_worker_stage_seconds"], "stage", "_sum")
    assert all(sums[s] >= stages[s] for s in stages)  # the last frame's time is one of the three
    assert sum(sums.values()) <= sample_values(m["ig_worker_render_seconds"], "_sum")[(("channel", "centre"),)]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_worker_serves_the_metrics_from_the_start(make_scene, box_model_factory):
    # Its host (port 1) never answers: the worker waits to subscribe until stopped.
    w = worker(make_scene, box_model_factory, fake_stubs=False)
    w.ready = True  # no warm-up: the kernels are the test's
    metrics = f"127.0.0.1:{free_port()}"
    stop = threading.Event()
    runner = threading.Thread(target=serve_worker, args=(w, f"127.0.0.1:{free_port()}", stop),
                              kwargs={"metrics_address": metrics})
    runner.start()
    try:
        deadline = time.monotonic() + 10.0
        while True:
            try:
                m = scrape(metrics)
                break
            except OSError:
                assert time.monotonic() < deadline
                time.sleep(0.05)
        assert sample_values(m["ig_worker_ready"]) == {(("channel", "centre"),): 1}
    finally:
        stop.set()
        runner.join()
    with pytest.raises(OSError):  # the metrics end with the worker
        scrape(metrics, timeout_s=1.0)
