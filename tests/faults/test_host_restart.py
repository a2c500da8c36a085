"""The host restarted mid-run, twice: SIGTERM, then SIGKILL, then a run that ends by itself.

Each start is a new run (run_id). Workers and a compositor started without --once follow every
run by themselves; the compositor writes each run to OUT/runs/<run_id>/ (frames/, report.json),
OUT/latest pointing at the newest, and never touches a previous run's files.
"""

from __future__ import annotations

import json
import os
import time

import pytest

from .harness import (
    CompositeWatcher,
    RigProcs,
    compositor_report,
    host_status,
    poll,
    record,
    start_rig,
    tree_hashes,
    wait_serving,
    worker_status,
    write_rig,
)

pytestmark = pytest.mark.integration

RATE = 20.0
LAST_RUN_FRAMES = 21  # --duration 1 at RATE


@pytest.fixture(scope="module")
def restarts(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("host-restart")
    rig_path = tmp / "rig.toml"
    rig = write_rig(rig_path)
    out = tmp / "out"
    procs = RigProcs(tmp / "logs")
    result: dict = {"out": out, "runs": [], "follow": []}
    watcher = None
    # A restarted host gives up after 15 s on a compositor or worker that does not come back,
    # so that a rig that fails to follow fails the test in seconds, not minutes.
    host_args = ["host", "--rig", str(rig_path), "--rate", str(RATE), "--start-timeout", "15"]
    try:
        start_rig(procs, rig_path, rig, out, host_args=("--rate", str(RATE), "--duration", "100000"))
        watcher = CompositeWatcher(rig.compositor_address)
        for i, how in enumerate(("SIGTERM", "SIGKILL", None)):
            if i:
                # A new host on the same port: the workers and the compositor must find it.
                procs.start("host", host_args + (["--duration", "1"] if how is None else ["--duration", "100000"]))
                wait_serving(rig.host_address, procs.procs["host"], procs)
                t0 = time.monotonic()
            run_id = poll(lambda: host_status(rig.host_address).run_id, what="the host's run id")
            result["runs"].append(run_id)
            try:
                first = poll(lambda rid=run_id: next((c for c in watcher.snapshot() if c[1] == rid), None),
                             timeout_s=30, what=f"a composite of run {run_id}")
                if i:
                    result["follow"].append({"seconds": round(first[2] - t0, 2), "frame": first[0]})
                if how is not None:
                    poll(lambda rid=run_id: sum(1 for c in watcher.snapshot() if c[1] == rid) >= 10,
                         what=f"10 composites of run {run_id}")
            except AssertionError as exc:
                result.setdefault("errors", []).append(str(exc))
            if how == "SIGTERM":
                result["host_exit_sigterm"] = procs.terminate("host")
                # The compositor decides the run's last frames and writes its report.json.
                first_dir = out / "runs" / run_id
                try:
                    poll(lambda d=first_dir: (d / "report.json").exists(), timeout_s=15,
                         what="the first run's report.json")
                except AssertionError as exc:
                    result.setdefault("errors", []).append(str(exc))
                poll(_settled(rig.compositor_address), timeout_s=30, every_s=0.5, what="the recorder to settle")
                result["first_hashes"] = tree_hashes(first_dir) if first_dir.exists() else {}
            elif how == "SIGKILL":
                procs.kill("host")
            else:
                result["host_exit_last"] = procs.wait("host", timeout_s=120)
        last = result["runs"][-1]
        try:
            poll(lambda: (out / "runs" / last / "report.json").exists(), timeout_s=15,
                 what="the last run's report.json")
        except AssertionError as exc:
            result.setdefault("errors", []).append(str(exc))
        poll(_settled(rig.compositor_address), timeout_s=30, every_s=0.5, what="the recorder to settle")
        result["workers_run"] = {ch.name: worker_status(ch.address).run_id for ch in rig.channels}
        result["composites"] = watcher.snapshot()
        result["report"] = compositor_report(rig.compositor_address)
        result["alive"] = {n: p.poll() is None for n, p in procs.procs.items() if n != "host"}
    finally:
        if watcher is not None:
            watcher.close()
        procs.stop_all()
    result["logs"] = procs.logs_tail()
    record("host_restart", runs=result["runs"], follow_after_restart=result["follow"],
           run_dirs=sorted(p.name for p in (out / "runs").iterdir()) if (out / "runs").exists() else [],
           errors=result.get("errors", []))
    return result


def _settled(address: str):
    """A predicate true once the compositor's frames_written has not changed since the last call."""
    last: list[int] = []

    def check() -> bool:
        n = compositor_report(address)["frames_written"]
        done = bool(last) and last[-1] == n
        last.append(n)
        return done

    return check


def test_every_start_is_a_new_run(restarts):
    assert len(set(restarts["runs"])) == 3, restarts["runs"]


def test_workers_and_compositor_follow_every_run(restarts):
    assert not restarts.get("errors"), "\n".join(restarts["errors"]) + restarts["logs"]
    by_run = {rid: [c for c in restarts["composites"] if c[1] == rid] for rid in restarts["runs"]}
    assert all(by_run.values()), {rid: len(v) for rid, v in by_run.items()}
    assert len(by_run[restarts["runs"][-1]]) == LAST_RUN_FRAMES
    assert set(restarts["workers_run"].values()) == {restarts["runs"][-1]}
    assert all(restarts["alive"].values()), restarts["alive"]


def test_each_run_has_its_own_directory_and_latest_points_at_the_newest(restarts):
    runs_dir = restarts["out"] / "runs"
    assert sorted(p.name for p in runs_dir.iterdir()) == sorted(restarts["runs"])
    for rid in restarts["runs"]:
        assert list((runs_dir / rid / "frames").glob("frame_*.png")), rid
    latest = restarts["out"] / "latest"
    assert latest.is_symlink() and os.path.realpath(latest) == str((runs_dir / restarts["runs"][-1]).resolve())
    assert (latest / "report.json").exists()


def test_first_run_files_are_unchanged_by_later_runs(restarts):
    first = restarts["out"] / "runs" / restarts["runs"][0]
    assert restarts["first_hashes"], "the first run wrote nothing under runs/<run_id>/"
    assert "report.json" in restarts["first_hashes"]
    assert tree_hashes(first) == restarts["first_hashes"]


def test_hosts_exit_cleanly(restarts):
    assert restarts["host_exit_sigterm"] == 0
    assert restarts["host_exit_last"] == 0


def test_each_run_report_is_its_own_run(restarts):
    # Never two runs merged: each report names its run, and the last (21 frames, ended by
    # itself) counts exactly its own frames.
    runs_dir = restarts["out"] / "runs"
    reports = {rid: json.loads((runs_dir / rid / "report.json").read_text()) for rid in restarts["runs"]
               if (runs_dir / rid / "report.json").exists()}
    assert sorted(reports) == sorted(restarts["runs"])
    assert {rid: r["run_id"] for rid, r in reports.items()} == {rid: rid for rid in reports}
    last = reports[restarts["runs"][-1]]
    assert last["frames_published"] == last["frames_complete"] == LAST_RUN_FRAMES, last
    assert last["host"]["frames_published"] == LAST_RUN_FRAMES
