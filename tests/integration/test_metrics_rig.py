"""The metrics of a real rig: host, one worker and the compositor as processes, each serving
/metrics at its rig file's metrics_port, scraped over HTTP while and after they fly a short run;
the numbers agree across the processes and with the compositor's report.json."""

from __future__ import annotations

import json
import signal
import time
from dataclasses import replace

import pytest

from services.demo import local_rig
from services.rig.metrics import sample_values, scrape
from services.rig.rigfile import default_rig_path, load_rig, rig_toml

from .conftest import kill_all, start, wait_all

pytestmark = pytest.mark.integration

RATE, DURATION = 10.0, 1.0
FRAMES = int(round(RATE * DURATION)) + 1


def value(families, name, suffix="_total", **labels):
    return sample_values(families[name], suffix).get(tuple(sorted(labels.items())))


def poll(address, until, timeout_s=120.0):
    """The last families scraped at address once until(families) holds (None if it never did)."""
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        try:
            last = scrape(address, timeout_s=2.0)
            if until(last):
                return last
        except OSError:
            pass  # not up yet, or already gone
        time.sleep(0.1)
    return None


def test_a_short_run_scraped_from_every_process(tmp_path):
    base = load_rig(default_rig_path()).with_size(160, 120)
    centre = replace(base.channels[1], metrics_port=1)
    rig = local_rig(replace(base, channels=(centre,), host_metrics_port=1, compositor_metrics_port=1))
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    host, compositor = f"127.0.0.1:{rig.host_metrics_port}", f"127.0.0.1:{rig.compositor_metrics_port}"
    worker = f"127.0.0.1:{rig.channels[0].metrics_port}"
    out = tmp_path / "out"
    procs, logs = {}, {}

    def launch(name, argv):
        logs[name] = open(tmp_path / f"{name}.log", "w")  # noqa: SIM115  (closed by kill_all)
        procs[name] = start(argv, logs[name])

    try:
        launch("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), "--record-every", "0",
                              "--exr-every", "0"])
        launch("worker", ["worker", "--rig", str(rig_path), "--channel", "centre"])
        launch("host", ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", str(DURATION),
                        "--sync-timeout", "20"])
        # The host serves its metrics while it runs, and ends with its run.
        during = poll(host, lambda m: value(m, "ig_host_frames_published") >= 3)
        assert wait_all({"host": procs["host"]})["host"] == 0
        # Compositor and worker follow run after run: their counters stay, final, after the run.
        after = poll(compositor, lambda m: value(m, "ig_compositor_frames_complete") == FRAMES, timeout_s=30.0)
        rendered = poll(worker, lambda m: value(m, "ig_worker_frames_rendered", channel="centre") == FRAMES,
                        timeout_s=30.0)
        report_path = out / "latest" / "report.json"
        deadline = time.monotonic() + 30.0
        while not report_path.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        report = json.loads(report_path.read_text())
        for name in ("compositor", "worker"):
            procs[name].send_signal(signal.SIGTERM)
        codes = wait_all(procs, timeout_s=60.0)
    finally:
        kill_all(procs, logs)
    assert codes == {"host": 0, "compositor": 0, "worker": 0}, codes
    assert during is not None and after is not None and rendered is not None
    run_id = report["run_id"]
    assert value(during, "ig_host_run_info", "", eyepoint_source="bundled", run_id=run_id) == 1
    assert 3 <= value(during, "ig_host_frames_published") <= report["host"]["frames_published"] == FRAMES
    assert value(after, "ig_compositor_frames_published") == report["frames_published"] == FRAMES
    assert value(after, "ig_compositor_frames_incomplete", cause="missing_channel") == 0
    assert value(after, "ig_compositor_control_to_composite_seconds", "_count") == \
        report["control_to_composite_latency"]["count"] == FRAMES
    assert value(after, "ig_compositor_images", channel="centre", wire="srgb8") == FRAMES
    assert value(rendered, "ig_worker_render_seconds", "_count", channel="centre") == FRAMES
    stages = {dict(k)["stage"]: v for k, v in sample_values(rendered["ig_worker_stage_seconds"], "_count").items()}
    assert stages and set(stages.values()) == {FRAMES}
