"""The bundled scripted flight: deterministic, finite, smooth, and it flies the script it claims."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from host_sim.flight import G_MPS2, PHASES, TABLE_HZ, bundled_flight

FLIGHT = bundled_flight()
DT_60 = 1.0 / 60.0
TIMES = np.arange(0.0, FLIGHT.duration_s + 1e-9, DT_60)


def _fields(t: float) -> np.ndarray:
    """x, y, z, heading, pitch, roll at t."""
    e = FLIGHT.eyepoint_at(t)
    return np.array([*e.position, e.heading_deg, e.pitch_deg, e.roll_deg])


ALL = np.array([_fields(t) for t in TIMES])


def _wrapped(dh: np.ndarray) -> np.ndarray:
    return (dh + 180.0) % 360.0 - 180.0


def test_duration_covers_a_20_s_demo_with_margin():
    assert 22.0 <= FLIGHT.duration_s <= 30.0
    assert FLIGHT.position.shape == (int(round(FLIGHT.duration_s * TABLE_HZ)) + 1, 3)


def test_deterministic():
    other = bundled_flight()
    for a, b in zip((FLIGHT.position, FLIGHT.heading_deg, FLIGHT.pitch_deg, FLIGHT.roll_deg),
                    (other.position, other.heading_deg, other.pitch_deg, other.roll_deg),
                    strict=True):
        assert np.array_equal(a, b)
    assert [_fields(t).tolist() for t in (0.0, 3.3, 12.345, 23.9)] == [
        np.array([*e.position, e.heading_deg, e.pitch_deg, e.roll_deg]).tolist()
        for e in (other.eyepoint_at(t) for t in (0.0, 3.3, 12.345, 23.9))]


def test_table_is_read_only():
    with pytest.raises(ValueError):
        FLIGHT.position[0, 0] = 1.0


@given(st.floats(allow_nan=False, allow_infinity=True))
def test_finite_for_any_time(t):
    f = _fields(t)
    assert np.isfinite(f).all()
    assert 0.0 <= f[3] < 360.0


def test_nan_time_is_an_error():
    with pytest.raises(ValueError, match="t_s"):
        FLIGHT.eyepoint_at(float("nan"))
    with pytest.raises(ValueError, match="t_s"):
        FLIGHT.phase_at(float("nan"))


def test_clamps_time_outside_the_script():
    for before in (-0.001, -1e9, float("-inf")):
        assert _fields(before).tolist() == _fields(0.0).tolist()
    for after in (FLIGHT.duration_s + 0.001, 1e9, float("inf")):
        assert _fields(after).tolist() == _fields(FLIGHT.duration_s).tolist()


def test_continuous_at_60_hz():
    step = np.diff(ALL, axis=0)
    assert np.linalg.norm(step[:, :3], axis=1).max() < 1.5  # metres per frame: < 90 m/s
    assert np.abs(_wrapped(step[:, 3])).max() < 0.25  # heading, degrees per frame
    assert np.abs(step[:, 4:]).max() < 1.0  # pitch and roll, degrees per frame


def test_attitude_rates_change_smoothly():
    # No step in roll or pitch rate: the change of rate from one frame to the next stays small
    # (a step to the 20 deg/s roll-in rate would be 0.33 degrees per frame per frame).
    step = np.diff(ALL[:, 3:], axis=0)
    step[:, 0] = _wrapped(step[:, 0])
    assert np.abs(np.diff(step, axis=0)).max() < 0.05


def test_heading_stays_in_range_and_wraps_through_north_on_the_shortest_arc():
    h = FLIGHT.heading_deg
    assert ((h >= 0.0) & (h < 360.0)).all()
    jumps = np.flatnonzero(np.abs(np.diff(h)) > 180.0)
    assert jumps.size >= 1  # the left turn passes from 0 to 359.x
    for i in jumps:
        t0 = i / TABLE_HZ
        for frac in np.linspace(0.0, 1.0, 11):
            e = FLIGHT.eyepoint_at(t0 + frac / TABLE_HZ)
            assert 0.0 <= e.heading_deg < 360.0
            assert min(e.heading_deg, 360.0 - e.heading_deg) < 1.0  # near north, never ~180


def test_stays_above_ground():
    assert ALL[:, 2].min() >= 3.0 - 1e-9


def test_starts_on_the_runway_near_the_threshold_and_rolls_north():
    x, y, z, h, p, r = _fields(0.0)
    assert abs(x) < 1.0 and -1000.0 < y < -850.0 and z == pytest.approx(3.0)
    assert (h, p, r) == (0.0, 0.0, 0.0)
    roll = ALL[TIMES <= 6.0]
    assert np.all(np.abs(roll[:, 2] - 3.0) < 1e-9) and np.all(roll[:, 0] == 0.0)  # on the wheels
    assert np.all(np.diff(np.diff(roll[:, 1])) > 0.0)  # accelerating
    assert roll[-1, 1] < 1000.0 - 22.5  # still on the runway


def test_climbs_above_50_m():
    assert ALL[:, 2].max() > 50.0


def test_banks_beyond_20_degrees():
    assert np.abs(ALL[:, 5]).max() > 20.0


def test_turn_is_coordinated():
    # Heading rate = g tan(bank) / speed, with the speed measured along the flown path.
    for t in (13.0, 14.5, 16.0):  # wings held at full bank
        e0, e, e1 = (FLIGHT.eyepoint_at(t + d) for d in (-0.05, 0.0, 0.05))
        rate = _wrapped(np.array(e1.heading_deg - e0.heading_deg)) / 0.1
        speed = np.linalg.norm(e1.position - e0.position) / 0.1
        expected = math.degrees(G_MPS2 * math.tan(math.radians(e.roll_deg)) / speed)
        assert rate == pytest.approx(expected, rel=0.01), t


def test_ends_in_a_wings_level_descent():
    z = [FLIGHT.eyepoint_at(t).position[2] for t in (19.5, 21.0, 22.5, FLIGHT.duration_s)]
    assert z[0] > z[1] > z[2] > z[3]
    assert abs(FLIGHT.eyepoint_at(20.0).roll_deg) < 1e-9


def test_phases_are_in_order_and_cover_the_script():
    starts = [start for _, start, _ in PHASES]
    assert starts == sorted(starts) and starts[0] == 0.0
    assert max(end for _, _, end in PHASES) == FLIGHT.duration_s
    assert [FLIGHT.phase_at(t) for t in (0.0, 7.0, 10.0, 14.0, 20.0, 99.0)] == [
        "take-off roll", "rotation", "climb", "turn", "descent", "descent"]
