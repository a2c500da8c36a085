"""A slow channel and a slow link: the swap barrier waits at most [sync] frame_timeout_s.

- A worker SIGSTOPped for several frame timeouts, then SIGCONTed.
- A worker whose traffic to the host goes through a TCP proxy that holds it for longer than
  the frame timeout (its rig file names the proxy as the host; the channels are the same).

Either way the host counts ack_timeouts for that channel and publishes the others' frames about
one timeout apart, never held for the whole stall; once the fault is gone frames complete again.
"""

from __future__ import annotations

import statistics
import time

import pytest

from services.rig.rigfile import SyncSpec

from .harness import (
    CompositeWatcher,
    DelayProxy,
    RigProcs,
    host_status,
    poll,
    published_intervals,
    record,
    start_rig,
    write_rig,
    write_rig_via,
)

pytestmark = pytest.mark.integration

RATE = 20.0
FRAME_TIMEOUT_S = 0.8
STALL_S = 4.0  # five frame timeouts
LINK_DELAY_S = 2.5  # the delayed link holds every byte to the host this long


@pytest.fixture(scope="module")
def rig(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("slow")
    rig_path = tmp / "rig.toml"
    rig = write_rig(rig_path, sync=SyncSpec(frame_timeout_s=FRAME_TIMEOUT_S))
    proxy = DelayProxy(rig.host_address)
    # The right worker reaches the host through the proxy (its acknowledgements, its stream).
    right_rig = write_rig_via(tmp / "right.toml", rig, host_address=proxy.address)
    procs = RigProcs(tmp / "logs")
    watcher = None
    try:
        # No --sync-timeout: the rig file's [sync] frame_timeout_s is the barrier's timeout.
        start_rig(procs, rig_path, rig, tmp / "out", compositor_args=("--record-every", "0"),
                  worker_rigs={"right": right_rig}, host_args=("--rate", str(RATE), "--duration", "100000"))
        watcher = CompositeWatcher(rig.compositor_address)
        poll(lambda: len(watcher.snapshot()) >= 10, what="10 complete frames")
        yield {"rig": rig, "procs": procs, "proxy": proxy, "watcher": watcher}
    finally:
        if watcher is not None:
            watcher.close()
        procs.stop_all()
        proxy.close()


def _fault(rig, watcher, channel: str, start, end) -> dict:
    """Apply a fault (start()), watch the host's publication for STALL_S, end it (end()), and
    measure: ack_timeouts before/after, intervals during, frames to the first composite after."""
    host = rig["rig"].host_address
    before = dict(host_status(host).ack_timeouts)
    start()
    intervals = published_intervals(host, STALL_S)
    end()
    ended_at = host_status(host).frames_published
    t_end = time.monotonic()
    after = dict(host_status(host).ack_timeouts)
    result = {"timeouts_before": before, "timeouts_after": after, "intervals": intervals,
              "published_during": len(intervals) + 1 if intervals else 0}
    try:
        first = poll(lambda: next((c for c in watcher.snapshot() if c[0] >= ended_at), None), timeout_s=60,
                     what="a complete frame after the fault")
        result["frames_to_recover"] = first[0] - ended_at
        result["seconds_to_recover"] = round(first[2] - t_end, 2)
    except AssertionError as exc:
        result["recover_error"] = str(exc)
    return result


def _summary(m: dict, channel: str) -> dict:
    return {"ack_timeouts_added": {c: m["timeouts_after"].get(c, 0) - m["timeouts_before"].get(c, 0)
                                   for c in m["timeouts_after"]},
            "publication_interval_median_s": round(statistics.median(m["intervals"]), 3) if m["intervals"] else None,
            "publication_interval_max_s": round(max(m["intervals"]), 3) if m["intervals"] else None,
            "frames_published_during": m["published_during"],
            "frames_to_recover": m.get("frames_to_recover"), "seconds_to_recover": m.get("seconds_to_recover"),
            "frame_timeout_s": FRAME_TIMEOUT_S, "stall_s": STALL_S}


def _check(m: dict, channel: str, others: list[str]) -> None:
    late = m["timeouts_after"].get(channel, 0) - m["timeouts_before"].get(channel, 0)
    # About one timeout per frame of the stall: at least two, whatever the load.
    assert late >= 2, m
    for c in others:
        assert m["timeouts_after"].get(c, 0) - m["timeouts_before"].get(c, 0) < late, m
    # The other channels' frames went on, one frame timeout apart, not once per stall: a host
    # holding frames for the stalled channel would publish one frame (or none) in STALL_S.
    assert m["published_during"] >= 3, m
    assert statistics.median(m["intervals"]) < STALL_S / 2, m
    assert "recover_error" not in m, m


def test_stopped_worker_is_timed_out_and_the_others_go_on(rig):
    procs = rig["procs"]
    m = _fault(rig, rig["watcher"], "centre", lambda: procs.signal("centre", 19),  # SIGSTOP
               lambda: procs.signal("centre", 18))  # SIGCONT
    record("stopped_worker", **_summary(m, "centre"))
    _check(m, "centre", ["left", "right"])


def test_delayed_link_is_timed_out_and_the_others_go_on(rig):
    proxy = rig["proxy"]

    def slow() -> None:
        proxy.delay_s = LINK_DELAY_S

    def fast() -> None:
        proxy.delay_s = 0.0

    m = _fault(rig, rig["watcher"], "right", slow, fast)
    record("delayed_link", link_delay_s=LINK_DELAY_S, **_summary(m, "right"))
    _check(m, "right", ["left", "centre"])


def test_every_process_still_running(rig):
    assert {n: p.poll() for n, p in rig["procs"].procs.items()} == dict.fromkeys(rig["procs"].procs, None)
