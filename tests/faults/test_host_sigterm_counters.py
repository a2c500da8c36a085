"""The host stopped by SIGTERM mid-run: its final counters still reach the run's report.json.

Issue 33: the compositor asked GetHostStatus once the stream had ended, and a host stopped by
SIGTERM stopped its server at once, so the question was refused (UNAVAILABLE, CANCELLED) and
`"host": null` was written, in 4 of 6 runs of a soak ended by SIGTERM. The host now sends its
counters as the stream's last message. Three runs are stopped at different moments, as in the
issue's reproducer, and one more while the compositor is stopped (SIGSTOP), so that it sees the end
of the stream only after the host has exited: a GetHostStatus then can never be answered, which
made the old rig fail every time, however lightly loaded the machine.
"""

from __future__ import annotations

import json
import signal

import pytest

from .harness import RigProcs, host_status, poll, record, start_rig, wait_serving, write_rig

pytestmark = pytest.mark.integration

RATE = 10.0
#: Frames published before each SIGTERM: the moment in the run varies.
STOP_AFTER = (5, 13, 22)


@pytest.fixture(scope="module")
def stopped(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("host-sigterm")
    rig_path = tmp / "rig.toml"
    rig = write_rig(rig_path)
    out = tmp / "out"
    procs = RigProcs(tmp / "logs")
    host_args = ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", "100000"]
    result: dict = {"runs": []}
    try:
        start_rig(procs, rig_path, rig, out, host_args=tuple(host_args[3:]))
        for i, frames in enumerate((*STOP_AFTER, None)):
            if i:
                procs.start("host", host_args)
                wait_serving(rig.host_address, procs.procs["host"], procs)
            run_id = poll(lambda: host_status(rig.host_address).run_id, what="the host's run id")
            poll(lambda n=frames or 10: host_status(rig.host_address).frames_published >= n,
                 what="frames of the run")
            late = frames is None
            if late:
                # The compositor learns of the end only once the host has gone.
                procs.signal("compositor", signal.SIGSTOP)
            exit_code = procs.terminate("host")
            if late:
                procs.signal("compositor", signal.SIGCONT)
            path = out / "runs" / run_id / "report.json"
            try:
                poll(path.exists, timeout_s=30, what=f"{path}")
                report = json.loads(path.read_text())
            except AssertionError as exc:
                report = {"error": str(exc)}
            result["runs"].append({"run_id": run_id, "compositor_stopped": late, "host_exit": exit_code,
                                   "report": report})
    finally:
        procs.stop_all()
    result["logs"] = procs.logs_tail()
    result["compositor_log"] = procs.log("compositor")
    record("host_sigterm_counters", runs=[
        {"run_id": r["run_id"], "compositor_stopped": r["compositor_stopped"], "host_exit": r["host_exit"],
         "host_counters": bool(r["report"].get("host")),
         "frames_published": r["report"].get("frames_published"),
         "host_frames_published": (r["report"].get("host") or {}).get("frames_published")}
        for r in result["runs"]])
    return result


def test_every_run_stopped_by_sigterm_has_the_hosts_final_counters(stopped):
    missing = [r["run_id"] for r in stopped["runs"] if not r["report"].get("host")]
    assert not missing, f"runs with \"host\": null: {missing}\n{stopped['logs']}"
    for r in stopped["runs"]:
        report, host = r["report"], r["report"]["host"]
        assert host["run_id"] == report["run_id"] == r["run_id"]
        assert host["run_end"] == "stopped"
        # The stream delivers every frame published before its end: the compositor saw them all.
        assert host["frames_published"] == report["frames_published"] > 0, (host, report["frames_published"])
        assert set(host["ack_timeouts"]) == {"left", "centre", "right"}


def test_the_compositor_never_had_to_ask(stopped):
    assert "host status unavailable" not in stopped["compositor_log"]


def test_the_stopped_hosts_exit_cleanly(stopped):
    assert [r["host_exit"] for r in stopped["runs"]] == [0] * len(stopped["runs"])
