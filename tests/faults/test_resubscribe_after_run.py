"""A run that ends by itself (--duration 3): the workers and the compositor do not subscribe again
in a tight loop while the host lingers, and still follow the next host.

Issue 33: after the end of a run the host stays up about 2 s and closed every new stream at once;
the workers took that for the end of a run and subscribed again with no pause: 3,916 `subscriber
... joined` lines in the host's log in 2 s, where 4 would be normal. The host now refuses a
subscription to an ended run (FAILED_PRECONDITION, "run_id '...' has ended ...") and every
subscriber pauses before asking again, longer after each refusal (services/rig/resubscribe.py).
Counted, never timed: the host's log holds one `joined` per subscriber, and a handful of refusals
at most.
"""

from __future__ import annotations

import json
import re
from collections import Counter

import pytest

from services.rig.resubscribe import RUN_ENDED_FIRST_PAUSE_S, RUN_ENDED_MAX_PAUSE_S

from .harness import RigProcs, host_status, poll, record, start_rig, wait_serving, worker_status, write_rig

pytestmark = pytest.mark.integration

RATE = 10.0
FIRST_RUN_FRAMES = 31  # --duration 3 at RATE
NEXT_RUN_FRAMES = 11  # --duration 1
SUBSCRIBERS = ("compositor", "worker-left", "worker-centre", "worker-right")

#: Host linger after a run (host_sim/server.py serve's linger_s) and the server's grace after it.
LINGER_S, GRACE_S = 2.0, 1.0
#: Refusals a subscriber can get while the host lingers: the first after RUN_ENDED_FIRST_PAUSE_S,
#: then one each RUN_ENDED_MAX_PAUSE_S at most.
MAX_REFUSALS = 1 + int((LINGER_S + GRACE_S - RUN_ENDED_FIRST_PAUSE_S) / RUN_ENDED_MAX_PAUSE_S)

_JOINED = re.compile(r"subscriber (\S+) \(channel '[^']*'\) joined")
_REFUSED = re.compile(r"subscriber (\S+) \(channel '[^']*'\) refused: run_id '[0-9a-f]+' has ended")


def _subscriptions(log: str) -> tuple[Counter[str], Counter[str]]:
    """(joins, refusals as the run had ended) by subscriber, from a host's log."""
    return Counter(_JOINED.findall(log)), Counter(_REFUSED.findall(log))


@pytest.fixture(scope="module")
def ended(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("resubscribe")
    rig_path = tmp / "rig.toml"
    rig = write_rig(rig_path)
    out = tmp / "out"
    procs = RigProcs(tmp / "logs")
    result: dict = {"runs": [], "reports": [], "host_exits": []}
    try:
        start_rig(procs, rig_path, rig, out, host_args=("--rate", str(RATE), "--duration", "3"))
        for name, duration in (("host", None), ("host2", "1")):
            if duration is not None:
                procs.start(name, ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", duration])
                wait_serving(rig.host_address, procs.procs[name], procs)
            run_id = poll(lambda: host_status(rig.host_address).run_id, what="the host's run id")
            result["runs"].append(run_id)
            result["host_exits"].append(procs.wait(name, timeout_s=120))
            path = out / "runs" / run_id / "report.json"
            poll(path.exists, timeout_s=30, what=str(path))
            result["reports"].append(json.loads(path.read_text()))
            if duration is None:
                # The host has gone: every subscriber now waits for the next one, asking nothing.
                result["resubscriptions"] = {ch.name: worker_status(ch.address).resubscriptions
                                             for ch in rig.channels}
        result["workers_runs"] = {ch.name: worker_status(ch.address).runs for ch in rig.channels}
    finally:
        procs.stop_all()
    result["logs"] = procs.logs_tail()
    result["host_logs"] = (procs.log("host"), procs.log("host2"))
    joins, refusals = _subscriptions(result["host_logs"][0])
    record("resubscribe_after_run", joins=dict(joins), refusals_while_lingering=dict(refusals),
           worker_resubscriptions=result.get("resubscriptions"), max_refusals=MAX_REFUSALS,
           frames_complete=[r["frames_complete"] for r in result["reports"]])
    return result


def test_no_subscriber_joins_the_ended_run_again(ended):
    joins, _ = _subscriptions(ended["host_logs"][0])
    assert joins == dict.fromkeys(SUBSCRIBERS, 1), f"{joins}\n{ended['logs']}"


def test_refusals_while_the_host_lingers_are_a_handful(ended):
    _, refusals = _subscriptions(ended["host_logs"][0])
    assert set(refusals) <= set(SUBSCRIBERS), refusals
    assert all(n <= MAX_REFUSALS for n in refusals.values()), (refusals, MAX_REFUSALS)


def test_workers_asked_again_a_handful_of_times(ended):
    # The end of the stream, then one more for each refusal (or stream refused as the server stopped).
    assert all(1 <= n <= 1 + MAX_REFUSALS for n in ended["resubscriptions"].values()), ended["resubscriptions"]


def test_the_rig_follows_the_next_host(ended):
    assert ended["host_exits"] == [0, 0]
    assert [r["run_id"] for r in ended["reports"]] == ended["runs"] and len(set(ended["runs"])) == 2
    assert [(r["frames_published"], r["frames_complete"]) for r in ended["reports"]] == [
        (FIRST_RUN_FRAMES, FIRST_RUN_FRAMES), (NEXT_RUN_FRAMES, NEXT_RUN_FRAMES)]
    assert [r["host"]["run_end"] for r in ended["reports"]] == ["completed", "completed"]
    assert ended["workers_runs"] == {"left": 2, "centre": 2, "right": 2}
    joins, _ = _subscriptions(ended["host_logs"][1])
    assert joins == dict.fromkeys(SUBSCRIBERS, 1), joins
