"""A worker SIGKILLed mid-run, and started again.

While it is dead, every frame is decided incomplete naming it (frames carry the channels the
host expects), and the compositor holds no more than its pending bounds: 320 x 240 channels, so
that keeping every partial frame of the dead spell (about 0.9 MB a frame for the two channels
still alive) would take the compositor's RSS far over the margin. Once the worker is SERVING
again frames complete within a few frames (measured: N).
"""

from __future__ import annotations

import re
import time

import pytest

from services.rig.rigfile import SyncSpec

from .harness import (
    SCENE,
    CompositeWatcher,
    RigProcs,
    compositor_report,
    host_status,
    poll,
    record,
    rss_mib,
    start_rig,
    wait_serving,
    write_rig,
)

pytestmark = pytest.mark.integration

W, H = 320, 240
RATE = 15.0
DEAD_S = 10.0  # RATE * DEAD_S frames of two 460 KB images each: 138 MB if every partial frame were held
MAX_PENDING = 8
RSS_MARGIN_MIB = 50.0


def rss_over(pid: int, seconds: float) -> float:
    """Median RSS of pid over seconds, MiB."""
    samples = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        samples.append(rss_mib(pid))
        time.sleep(0.2)
    return sorted(samples)[len(samples) // 2]


@pytest.fixture(scope="module")
def death(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("worker-death")
    rig = write_rig(tmp / "rig.toml", width=W, height=H,
                    sync=SyncSpec(frame_timeout_s=2.0, max_pending_frames=MAX_PENDING, max_pending_mib=16.0))
    procs = RigProcs(tmp / "logs")
    result: dict = {"rig": rig}
    watcher = None
    try:
        start_rig(procs, tmp / "rig.toml", rig, tmp / "out", compositor_args=("--record-every", "0"),
                  host_args=("--rate", str(RATE), "--duration", "100000"))
        watcher = CompositeWatcher(rig.compositor_address)
        comp = procs.pid("compositor")
        poll(lambda: len(watcher.snapshot()) >= 20, what="20 complete frames before the kill")
        result["rss_before"] = rss_over(comp, 4.0)

        timeouts_before = dict(host_status(rig.host_address).ack_timeouts)
        procs.kill("left")
        killed_at = host_status(rig.host_address).frames_published
        time.sleep(DEAD_S / 2)
        result["report_dead"] = compositor_report(rig.compositor_address)
        result["rss_dead"] = rss_over(comp, DEAD_S / 2)
        result["report_dead_late"] = compositor_report(rig.compositor_address)
        result["frames_while_dead"] = host_status(rig.host_address).frames_published - killed_at

        restarted = time.monotonic()
        procs.start("left", ["worker", "--rig", str(tmp / "rig.toml"), "--channel", "left", "--scene", str(SCENE)])
        wait_serving(rig.channel("left").address, procs.procs["left"], procs)
        serving_at = host_status(rig.host_address).frames_published
        t_serving = time.monotonic()
        result["serving_at"] = serving_at
        try:
            # Nothing completes while left is dead: the first composite after its restart is the recovery.
            first = poll(lambda: next((c for c in watcher.snapshot() if c[2] > restarted), None), timeout_s=60,
                         what="a complete frame after the worker's return")
            result["frames_to_recover"] = max(0, first[0] - serving_at)
            result["seconds_to_recover"] = round(max(0.0, first[2] - t_serving), 2)
            result["seconds_restart_to_serving"] = round(t_serving - restarted, 2)
            poll(lambda: sum(1 for c in watcher.snapshot() if c[0] >= first[0]) >= 20, what="20 more complete")
        except AssertionError as exc:
            result["recover_error"] = str(exc)
        result["rss_after"] = rss_over(comp, 4.0)
        result["timeouts"] = (timeouts_before, dict(host_status(rig.host_address).ack_timeouts))
        result["report_after"] = compositor_report(rig.compositor_address)
        result["alive"] = {n: p.poll() is None for n, p in procs.procs.items()}
    finally:
        if watcher is not None:
            watcher.close()
        procs.stop_all()
    result["logs"] = procs.logs_tail()
    record("worker_death", width=W, height=H, rate_hz=RATE, dead_s=DEAD_S,
           frames_while_dead=result.get("frames_while_dead"),
           rss_before_mib=result.get("rss_before"), rss_dead_mib=result.get("rss_dead"),
           rss_after_mib=result.get("rss_after"), frames_to_recover=result.get("frames_to_recover"),
           seconds_to_recover=result.get("seconds_to_recover"),
           seconds_restart_to_serving=result.get("seconds_restart_to_serving"),
           peak_pending_frames=result.get("report_after", {}).get("peak_pending_frames"),
           peak_pending_bytes=result.get("report_after", {}).get("peak_pending_bytes"),
           frames_evicted=result.get("report_after", {}).get("frames_evicted"),
           ack_timeouts_before_after=result.get("timeouts"),
           pending_dead=result.get("report_dead_late", {}).get("frames_pending"),
           incomplete_dead=result.get("report_dead_late", {}).get("frames_incomplete"),
           last_incomplete=result.get("report_dead_late", {}).get("last_incomplete"),
           missing_by_channel=result.get("report_dead_late", {}).get("missing_by_channel"))
    return result


def test_frames_without_the_dead_worker_are_incomplete_naming_it(death):
    report = death["report_dead_late"]
    assert report["frames_incomplete"]["missing_channel"] > 0, report
    assert re.match(r"frame \d+: missing_channel: missing left\b", report["last_incomplete"]), report["last_incomplete"]
    assert report.get("missing_by_channel", {}).get("left", 0) > 0, report


def test_dead_worker_frames_are_decided_at_once_not_held(death):
    # The present channels delivered: nothing to wait for, nothing pending beyond the bound.
    for key in ("report_dead", "report_dead_late"):
        assert death[key]["frames_pending"] <= MAX_PENDING, death[key]


def test_complete_frames_again_after_the_worker_returns(death):
    assert "recover_error" not in death, death.get("recover_error", "") + death["logs"]
    assert death["frames_to_recover"] <= 2 * RATE  # measured N; docs/faults.md


def test_returning_worker_is_not_timed_out_for_a_frame_it_never_got(death):
    # A frame published while the worker was away never reached it: the host must not hold the
    # others for the whole frame timeout waiting for its acknowledgement (a subscription that
    # lands during the barrier's wait used to be waited for).
    before, after = death["timeouts"]
    assert after == before, (before, after)


def test_compositor_memory_stays_flat(death):
    before, dead, after = death["rss_before"], death["rss_dead"], death["rss_after"]
    assert dead - before < RSS_MARGIN_MIB, (before, dead, after)
    assert after - before < RSS_MARGIN_MIB, (before, dead, after)


def test_every_process_still_running(death):
    assert all(death["alive"].values()), death["alive"]
