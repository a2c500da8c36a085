"""`ig latency`: pitch steps on a CAN bus to the first composite that shows them.

The end-to-end run is small and short; it checks that every response is found in the first
frame that could show it and that the chain of time stamps is causal and adds up, never how
long anything took (tests assert no wall-clock figures)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ig.v1 import compositor_pb2
from services.compositor.timing import HOPS
from services.latency import (
    CONTROL_HOP,
    PART60_LIMITS,
    StepResult,
    limits_verdict,
    measure_steps,
    profile_shift,
    summarise,
)

ROOT = Path(__file__).resolve().parent.parent.parent


def horizon(rows, at):
    """A row profile: bright sky down to row `at` (fractional: a partly covered row), dark below."""
    y = np.arange(rows) + 0.5
    return np.clip(at - y + 0.5, 0.0, 1.0) * 0.8 + 0.1


@pytest.mark.parametrize("moved", [0.0, 0.3, -0.3, 1.0, -2.5, 7.0])
def test_profile_shift_finds_how_far_the_horizon_moved(moved):
    reference = horizon(48, 20.0)
    assert profile_shift(horizon(48, 20.0 + moved), reference) == pytest.approx(moved, abs=0.15)


def test_profile_shift_is_zero_for_the_same_picture_and_refuses_other_sizes():
    p = np.random.default_rng(1).random(30)
    assert profile_shift(p, p) == 0.0
    with pytest.raises(ValueError, match=r"profile: \(30,\) rows against a reference of \(31,\)"):
        profile_shift(p, np.zeros(31))


def step(index, latency_ms, **kw):
    return StepResult(index, "up", 0.25, 0.75, 100.0, settled=True, threshold_px=0.25, detected=True,
                      latency_ms=latency_ms, chain_ms={CONTROL_HOP[0]: 1.0, **{k: 1.0 for k, _ in HOPS}}, **kw)


def test_the_summary_counts_only_clean_measurements_and_compares_the_limits():
    results = [step(1, 90.0), step(2, 120.0), step(3, 400.0, problem="1 composite(s) missed during the step")]
    summary = summarise(results)
    assert (summary["steps"], summary["measured"]) == (3, 2)
    assert summary["control_to_composite"]["max_ms"] == 120.0
    assert summary["chain"]["render"]["count"] == 2
    verdicts = {v["limit_ms"]: v for v in limits_verdict(summary)}
    assert sorted(verdicts) == sorted(round(limit * 1000.0, 3) for _, limit in PART60_LIMITS) == [100.0, 150.0]
    assert verdicts[150.0]["met_by_max"] is True and verdicts[100.0]["met_by_max"] is False


def test_bad_options_exit_2_before_starting_anything(tmp_path):
    from services.cli import main

    work = tmp_path / "work"
    assert main(["latency", "--step-size", "1.5", "--work", str(work)]) == 2
    assert main(["latency", "--channel", "middle", "--work", str(work), "--width", "16", "--height", "12"]) == 2
    assert not work.exists()


def test_auto_paces_the_host_by_the_rig_and_a_rate_is_a_fixed_rate():
    import argparse

    from host_sim import cli_host
    from services.demo import AUTO_RATE_MAX_HZ, host_pace_args

    parser = argparse.ArgumentParser()
    cli_host.add_arguments(parser)
    auto = parser.parse_args(host_pace_args(None))
    assert (auto.pace, auto.rate) == ("acks", AUTO_RATE_MAX_HZ)
    fixed = parser.parse_args(host_pace_args(15.0))
    assert (fixed.pace, fixed.rate) == ("ticks", 15.0)


class StillComposites:
    """A rig whose picture never moves, its composites at the given (repeating) simulated
    intervals: the settle and response waits must end on simulated time, whatever the frames."""

    def __init__(self, intervals):
        self.intervals = intervals
        self.k = 0
        self.sim = 0.0

    def next(self):
        c = compositor_pb2.WatchCompositesResponse(frame_number=self.k, sim_time_s=self.sim,
                                                   composite_time_unix_s=1e-6 * self.k)
        c.profiles.add(luminance=horizon(48, 20.0).tolist())
        self.sim += self.intervals[self.k % len(self.intervals)]
        self.k += 1
        return c

    def poll(self, deadline):
        return None

    def profile(self, c):
        return np.asarray(c.profiles[0].luminance, np.float32)

    def missed(self, c):
        return 0


class StillCockpit:
    def set_pitch(self, pitch):
        return 0.0


@pytest.mark.parametrize("intervals,frames", [((0.5,), 10), ((0.01,), 200), ((0.3, 0.01, 0.05), None)])
def test_a_step_without_response_gives_up_after_two_simulated_seconds_and_ten_frames(intervals, frames):
    rig = StillComposites(intervals)
    [result] = measure_steps(rig, StillCockpit(), steps=1, levels=(0.25, 0.75), threshold_px=0.1, log=lambda _: None)
    assert result.settled and not result.detected
    n = result.composites_after_step
    span = float(re.fullmatch(rf"no response within {n} composites \((.*) simulated s\)", result.problem)[1])
    # Both bounds were reached, and the last composite was the one that reached the later one.
    assert n >= 10 and span >= 2.0
    assert n == 10 or span - max(intervals) < 2.0
    if frames is not None:
        assert n == frames


@pytest.mark.integration
def test_every_step_is_seen_in_the_first_frame_that_can_show_it(tmp_path):
    out = tmp_path / "latency.json"
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "latency", "--width", "64", "--height", "48", "--samples", "4",
         "--rate", "15", "--steps", "3", "--work", str(tmp_path / "work"), "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Part 60" in proc.stdout and "150 ms" in proc.stdout and "100 ms" in proc.stdout
    doc = json.loads(out.read_text())
    assert doc["summary"]["measured"] == doc["summary"]["steps"] == 3
    assert [s["direction"] for s in doc["steps"]] == ["down", "up", "down"]
    for s in doc["steps"]:
        assert s["detected"] and s["problem"] == "" and s["shift_px"] > doc["threshold_px"]
        # The image showed the step in the first frame whose eyepoint had moved, the first
        # composite after the step: nothing in the path held the response back a frame.
        assert s["frames_after_eyepoint_change"] == 0
        chain = s["chain_ms"]
        assert list(chain) == [CONTROL_HOP[0]] + [k for k, _ in HOPS]
        assert sum(chain.values()) == pytest.approx(s["latency_ms"], abs=0.001 * len(chain))  # rounded to 1 us each
        # Within the rig every hop runs forwards in time. The host stamps its control sample
        # just before it reads the bus, so a CAN frame sent in that instant is read with a
        # sample time a few microseconds before it: the first hop is bounded by the next one.
        assert all(v >= 0 for k, v in chain.items() if k != CONTROL_HOP[0])
        assert chain[CONTROL_HOP[0]] + chain["host_sample_to_publish"] >= 0
    compositor = doc["compositor"]
    assert compositor["frames_incomplete"] == {"missing_channel": 0, "eyepoint_mismatch": 0}
    # Where it ran, and the worker -> compositor hop of every image.
    assert doc["machine"]["usable_cores"] >= 1 and doc["rig"]["threads_per_worker"] >= 1
    assert compositor["wire"]["render_end_to_compositor_receive"]["count"] >= compositor["frames_complete"]
    assert all(compositor["latency_chain"][k]["count"] == compositor["frames_complete"] for k, _ in HOPS)
