"""Cleaning logs into tracks and sampling them: smooth positions, shortest-arc attitudes,
estimated attitudes, and every problem reported."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from host_sim.replay import attitude
from host_sim.replay.track import RawLog, build_track


def world_log(times, positions, hpr=None):
    raw = RawLog(times=list(times), coords=[tuple(p) for p in positions], geodetic=False,
                 hpr=None if hpr is None else [tuple(a) for a in hpr])
    return raw


def test_heading_359_to_1_passes_through_north():
    track = build_track(world_log([0.0, 1.0], [(0, 0, 10), (0, 50, 10)], [(359.0, 0, 0), (1.0, 0, 0)]))
    headings = [track.sample(t).heading_deg for t in np.linspace(0.0, 1.0, 21)]
    assert all(min(h, 360.0 - h) <= 1.0 + 1e-9 for h in headings)
    h = track.sample(0.5).heading_deg
    assert min(h, 360.0 - h) < 1e-9


def test_attitude_interpolation_is_slerp_not_per_angle():
    # Rolling 170 -> -170 is 20 degrees through 180 (inverted), not 340 degrees back through 0.
    track = build_track(world_log([0.0, 1.0], [(0, 0, 10), (0, 50, 10)], [(90.0, 0, 170.0), (90.0, 0, -170.0)]))
    r = track.sample(0.5).roll_deg
    assert abs(abs(r) - 180.0) < 1e-6


def test_positions_pass_through_the_records_with_a_continuous_velocity():
    t = np.array([0.0, 1.0, 2.5, 3.0, 5.0])
    p = np.stack([t * 40.0, 100.0 * np.sin(t), 3.0 + t ** 2], axis=1)
    track = build_track(world_log(t, p, [(0, 0, 0)] * 5))
    for ti, pi in zip(t, p, strict=True):
        np.testing.assert_allclose(track.sample(ti).position, pi, atol=1e-9)
    eps = 1e-6
    for ti in t[1:-1]:  # left and right velocities agree at the records
        left = (track.sample(ti).position - track.sample(ti - eps).position) / eps
        right = (track.sample(ti + eps).position - track.sample(ti).position) / eps
        np.testing.assert_allclose(left, right, rtol=1e-3, atol=1e-3)


def test_out_of_order_duplicates_and_gaps_are_handled_and_reported():
    times = [0.0, 1.0, 3.0, 2.0, 2.0, 4.0, 30.0, 31.0]
    pos = [(10.0 * t, 0.0, 5.0) for t in times]
    pos[4] = (999.0, 999.0, 999.0)  # the duplicate of t=2 (kept: the first one in file order)
    track = build_track(world_log(times, pos))
    assert {k: v for k, v in track.problems.items() if v} == {"duplicate": 1, "out_of_order": 1, "gap": 1}
    assert any("record 3 at t=3.000 s is out of time order" in n for n in track.notes)  # one record moved
    assert list(track.t_s) == [0.0, 1.0, 2.0, 3.0, 4.0, 30.0, 31.0]
    assert track.sample(2.0).position[0] == pytest.approx(20.0)
    # straight across the gap
    np.testing.assert_allclose(track.sample(17.0).position, [170.0, 0.0, 5.0], atol=1e-9)
    assert any("gap" in n for n in track.notes) and any("duplicate" in n for n in track.notes)


def test_too_few_records_is_an_error_naming_the_log():
    with pytest.raises(ValueError, match=r"f.csv: 1 usable record\(s\), need at least 2 \(duplicate 1\)"):
        build_track(world_log([1.0, 1.0], [(0, 0, 0), (1, 1, 1)]), name="f.csv")


def test_estimated_attitude_of_a_coordinated_turn():
    # A circle flown clockwise (a right turn) at 50 m/s and 3 deg/s, climbing at 2 m/s.
    v, w = 50.0, math.radians(3.0)
    radius = v / w
    t = np.arange(0.0, 60.0, 1.0)
    p = np.stack([radius * (1 - np.cos(w * t)), radius * np.sin(w * t), 100.0 + 2.0 * t], axis=1)
    track = build_track(world_log(t, p))
    assert track.attitude_estimated
    e = track.sample(30.0)
    assert e.heading_deg == pytest.approx(math.degrees(w * 30.0), abs=0.1)  # the track
    assert e.roll_deg == pytest.approx(math.degrees(math.atan(v * w / 9.80665)), abs=0.2)  # right wing down
    assert e.pitch_deg == pytest.approx(math.degrees(math.atan2(2.0, v)), abs=0.05)


def test_estimate_holds_the_heading_when_not_moving():
    t = np.arange(6.0)
    p = np.array([(0, 0, 0), (0, 0, 0), (10, 10, 0), (20, 20, 0), (20, 20, 0), (20, 20, 0)], float)
    hpr = attitude.estimate(t, p)
    assert np.allclose(hpr[:, 0], 45.0)  # before moving: the first moving heading; after: held
    assert hpr[0, 1] == 0.0 and hpr[-1, 2] == 0.0


@given(st.floats(0.0, 360.0), st.floats(-89.0, 89.0), st.floats(-180.0, 180.0),
       st.floats(0.0, 360.0), st.floats(-89.0, 89.0), st.floats(-180.0, 180.0), st.floats(0.0, 1.0))
def test_sampled_attitudes_stay_finite_and_in_range(h0, p0, r0, h1, p1, r1, f):
    track = build_track(world_log([0.0, 2.0], [(0, 0, 0), (1, 1, 1)], [(h0, p0, r0), (h1, p1, r1)]))
    e = track.sample(2.0 * f)
    assert 0.0 <= e.heading_deg < 360.0 and -90.0 <= e.pitch_deg <= 90.0 and -180.0 <= e.roll_deg <= 180.0
    # the slerp never turns further than the angle between the two attitudes
    qa, qb, qf = attitude.from_hpr(np.array([h0, p0, r0])), attitude.from_hpr(np.array([h1, p1, r1])), \
        attitude.from_hpr(np.array([e.heading_deg, e.pitch_deg, e.roll_deg]))
    total = 2 * math.acos(min(1.0, abs(float(np.dot(qa, qb)))))
    part = 2 * math.acos(min(1.0, abs(float(np.dot(qa, qf)))))
    assert part <= total + 1e-6
