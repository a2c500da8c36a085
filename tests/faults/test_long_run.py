"""An hour of the demo, accelerated: 3,600 frames (one hour at the demo's rate: 0.97-1.09 Hz
measured by `ig demo` on the 2-core development machine, whose frames grew richer since the ~3 Hz
this test first ran 10,800 frames for) of tiny channels, as fast as the rig renders them (about
160 Hz on that machine). IG_FAULTS_LONG_FRAMES=10800 runs the hour at 3 Hz.

Every process's RSS and open file descriptors are sampled each second: the last quarter of the
run must hold what the first quarter held. No frame is lost without being counted: the host's
frames_published equals the compositor's, which equals complete + incomplete.
"""

from __future__ import annotations

import os
import time

import pytest

from services.rig.rigfile import SyncSpec

from .harness import RigProcs, final_report, quarters, record, sampled, start_rig, write_rig

pytestmark = pytest.mark.integration

#: One hour at the demo's rate; IG_FAULTS_LONG_FRAMES runs fewer (or more).
FRAMES = int(os.environ.get("IG_FAULTS_LONG_FRAMES", "3600"))
RATE = 1000.0  # above what the rig sustains: the host publishes as soon as every channel acknowledged
RSS_GROWTH_MIB = 16.0
FD_GROWTH = 2


@pytest.fixture(scope="module")
def long_run(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("long")
    rig_path = tmp / "rig.toml"
    rig = write_rig(rig_path, sync=SyncSpec(frame_timeout_s=5.0))
    out = tmp / "out"
    procs = RigProcs(tmp / "logs")
    result: dict = {}
    try:
        # Everyone --once: the run ends by itself and every process exits, the compositor after
        # writing its report.
        start_rig(procs, rig_path, rig, out, compositor_args=("--once", "--record-every", "1000"),
                  worker_args=("--once",), host_args=("--rate", str(RATE), "--duration", repr((FRAMES - 1) / RATE)))
        t0 = time.monotonic()
        with sampled({n: p.pid for n, p in procs.procs.items()}) as sampler:
            result["host_exit"] = procs.wait("host", timeout_s=900)
            result["seconds"] = time.monotonic() - t0
        result["exit"] = {n: procs.wait(n, timeout_s=120) for n in procs.procs}
        result["samples"] = sampler.samples
    finally:
        procs.stop_all()
    result["logs"] = procs.logs_tail()
    result["report"] = final_report(out)
    memory = {}
    for name, samples in result["samples"].items():
        rss = quarters([s[1] for s in samples])
        fds = quarters([s[2] for s in samples])
        memory[name] = {"rss_mib_first_quarter": round(rss[0], 1), "rss_mib_last_quarter": round(rss[1], 1),
                        "fds_first_quarter": fds[0], "fds_last_quarter": fds[1],
                        "fds_max": max(s[2] for s in samples), "samples": len(samples)}
    result["memory"] = memory
    report = result["report"]
    record("long_run", frames=FRAMES, seconds=round(result["seconds"], 1),
           frames_per_s=round(FRAMES / result["seconds"], 1), processes=memory,
           frames_published=report.get("frames_published"), frames_complete=report.get("frames_complete"),
           frames_incomplete=report.get("frames_incomplete"),
           host_frames_published=report.get("host", {}).get("frames_published"))
    return result


def test_every_process_exits_cleanly(long_run):
    assert long_run["exit"] == dict.fromkeys(long_run["exit"], 0), long_run["logs"]


def test_no_frame_lost_without_being_counted(long_run):
    report = long_run["report"]
    assert report, long_run["logs"]
    assert report["host"]["frames_published"] == report["frames_published"] == FRAMES
    assert report["frames_published"] == report["frames_complete"] + sum(report["frames_incomplete"].values()), report
    assert report["frames_pending"] == 0


def test_memory_and_file_descriptors_flat(long_run):
    for name, m in long_run["memory"].items():
        assert m["samples"] >= 8, (name, m)
        assert m["rss_mib_last_quarter"] - m["rss_mib_first_quarter"] < RSS_GROWTH_MIB, (name, m)
        assert m["fds_last_quarter"] <= m["fds_first_quarter"] + FD_GROWTH, (name, m)
