"""The compositor's /metrics over HTTP: its counters are its report's, summed over the runs it
followed and never going down; every composite's latency and hops land in the histograms."""

import json
import threading
import time

import numpy as np
import pytest

from ig.v1 import compositor_pb2, frame_pb2
from services.compositor.gather import InvalidSubmission
from services.compositor.server import Compositor
from services.compositor.timing import HOPS
from services.rig.metrics import sample_values, scrape, serve_metrics

CHANNELS = ("a", "b")


def eye(n):
    return frame_pb2.Eyepoint(x=10.0 + n, y=2.0, z=3.0)


def published(run_id, n, base):
    return frame_pb2.Frame(frame_number=n, eyepoint=eye(n), run_id=run_id, channels=list(CHANNELS),
                           control_sample_time_unix_s=base, publish_time_unix_s=base + 0.001)


def image(run_id, n, channel, base, *, eyepoint=None):
    """Channel's image of frame n, its worker's stamps 2 to 21 ms after the control sample."""
    return compositor_pb2.SubmitChannelImageRequest(
        frame_number=n, channel_name=channel, width=3, height=2, pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16,
        pixels=np.full((2, 3, 3), 0.5, "<f2").tobytes(), eyepoint=eyepoint or eye(n), run_id=run_id,
        render_time_s=0.017, control_sample_time_unix_s=base, frame_received_unix_s=base + 0.002,
        render_start_unix_s=base + 0.003, render_end_unix_s=base + 0.020, submit_unix_s=base + 0.021)


def complete(comp, run_id, n):
    base = time.time() - 0.05
    comp.on_published(published(run_id, n, base))
    for c in CHANNELS:
        comp.submit(image(run_id, n, c, base))


def refused(comp, request):
    with pytest.raises(InvalidSubmission):
        comp.submit(request)


def metrics(comp):
    with serve_metrics(comp.metrics.registry, "127.0.0.1:0") as endpoint:
        return scrape(f"127.0.0.1:{endpoint.port}")


def total(m, name, **labels):
    return sample_values(m[name], "_total").get(tuple(sorted(labels.items())), 0)


def by(m, name, label, suffix="_total"):
    return {dict(k)[label]: v for k, v in sample_values(m[name], suffix).items()}


@pytest.fixture
def comp(tmp_path):
    c = Compositor(CHANNELS, tmp_path, record_every=0, exr_every=0)
    yield c
    c.finish(grace_s=0.0)


def test_the_compositor_counters_are_its_report(comp):
    for n in range(3):
        complete(comp, "r1", n)
    base = time.time()
    comp.on_published(published("r1", 3, base))  # frame 3: channel b rendered another eyepoint
    comp.submit(image("r1", 3, "a", base))
    comp.submit(image("r1", 3, "b", base, eyepoint=eye(99)))
    comp.on_published(published("r1", 4, base))  # frame 4: channel b never delivers it
    comp.submit(image("r1", 4, "a", base))
    refused(comp, image("r1", 4, "a", base))  # a second image of it
    complete(comp, "r1", 5)  # ... which frame 5, complete, decides
    comp.submit(image("r1", 4, "b", base))  # too late: counted late
    refused(comp, image("r1", 6, "zz", base))
    comp.refuse("malformed", "bytes that are not the request")
    report = comp.report()
    m = metrics(comp)

    assert report["frames_complete"] == 4 and report["frames_incomplete"] == {"missing_channel": 1,
                                                                              "eyepoint_mismatch": 1}
    assert total(m, "ig_compositor_frames_published") == report["frames_published"] == 6
    assert total(m, "ig_compositor_frames_complete") == 4
    assert by(m, "ig_compositor_frames_incomplete", "cause") == report["frames_incomplete"]
    assert by(m, "ig_compositor_submissions_rejected", "cause") == report["rejected_submissions"] == {
        "duplicate_image": 1, "malformed": 1, "unknown_channel": 1}
    assert by(m, "ig_compositor_images_late", "channel") == report["late_by_channel"] == {"a": 0, "b": 1}
    assert by(m, "ig_compositor_images_missing", "channel") == report["missing_by_channel"] == {"a": 0, "b": 1}
    assert total(m, "ig_compositor_images", channel="a", wire="half") == report["wire"]["channels"]["a"]["half"] == 6
    assert total(m, "ig_compositor_images_shared_memory", channel="b") == 0
    assert by(m, "ig_compositor_composites", "format") == report["wire"]["composites"] == {"half": 4}
    assert total(m, "ig_compositor_stitch_errors") == report["stitch_errors"] == 0
    assert total(m, "ig_compositor_frames_written") == report["frames_written"] == 0
    assert sample_values(m["ig_compositor_frames_pending"]) == {(): report["frames_pending"]}
    assert sample_values(m["ig_compositor_run_info"]) == {(("run_id", "r1"),): 1}
    # Every composite's latency and its chain, as the report's figures count them.
    latency = report["control_to_composite_latency"]
    assert sample_values(m["ig_compositor_control_to_composite_seconds"], "_count") == {(): latency["count"]}
    assert sample_values(m["ig_compositor_control_to_composite_seconds"], "_sum")[()] == pytest.approx(
        sum(comp._run.timing.latencies))
    assert by(m, "ig_compositor_latency_hop_seconds", "hop", "_count") == {
        key: report["latency_chain"][key]["count"] for key, _ in HOPS}
    assert by(m, "ig_compositor_latency_hop_seconds", "hop", "_sum")["render"] == pytest.approx(4 * 0.017, abs=1e-5)
    assert sample_values(m["ig_compositor_composite_interval_seconds"], "_count") == {(): 3}


def test_the_counters_add_up_the_runs_and_never_go_down(comp):
    seen = []

    def scraped():
        m = metrics(comp)
        now = {name: total(m, name) for name in ("ig_compositor_frames_published", "ig_compositor_frames_complete")}
        now["late"] = sum(by(m, "ig_compositor_images_late", "channel").values())
        assert not seen or all(now[k] >= seen[-1][k] for k in now), (seen[-1], now)
        seen.append(now)

    complete(comp, "r1", 0)
    complete(comp, "r1", 1)
    scraped()
    comp.end_run("r1")
    first = comp.report()
    comp.submit(image("r1", 0, "a", time.time()))  # after its run ended: late, still the run's
    scraped()
    complete(comp, "r2", 0)  # the host's next run: r1 is over and gone, its counts folded
    scraped()
    # A third run, from another thread, while the second has not ended: the host restarted
    # without ending its stream, and the second ends on a thread of its own.
    third = threading.Thread(target=complete, args=(comp, "r3", 0))
    third.start()
    scraped()
    third.join()
    scraped()
    comp.finish(grace_s=0.0)
    scraped()
    assert [first["frames_complete"]] + [_report_of(comp, run)["frames_complete"] for run in ("r2", "r3")] == [2, 1, 1]
    assert seen[-1] == {"ig_compositor_frames_published": 4, "ig_compositor_frames_complete": 4, "late": 1}


def _report_of(comp, run_id):
    return json.loads((comp.out_dir / "runs" / run_id / "report.json").read_text())
