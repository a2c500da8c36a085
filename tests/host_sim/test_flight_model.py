"""The flight model: bounded for any control sequence, deterministic, and it flies."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.flight_model import GAMMA_LIMIT_DEG, Aircraft, State, on_runway, step
from host_sim.inputs.base import Controls

A = Aircraft()
DT = 0.01
FLOOR = A.ground_z_m + A.eye_height_m


def fly(state: State, controls: Controls, seconds: float) -> State:
    for _ in range(int(round(seconds / DT))):
        state = step(state, controls, DT, A)
    return state


def airborne() -> State:
    """Trimmed-ish cruise at 300 m."""
    return State(0.0, 0.0, 300.0, speed_mps=50.0, on_ground=False, alpha_rad=math.radians(2.0))


def check(s: State) -> None:
    values = [s.x_m, s.y_m, s.z_m, s.speed_mps, s.gamma_rad, s.track_rad, s.bank_rad, s.stick, s.alpha_rad,
              s.slip_rad]
    assert all(math.isfinite(v) for v in values), s
    assert s.z_m >= FLOOR - 1e-9
    assert 0.0 <= s.speed_mps < 250.0  # terminal speed in a full-power dive is about 190 m/s
    assert abs(s.gamma_rad) <= math.radians(GAMMA_LIMIT_DEG) + 1e-12
    assert abs(s.bank_rad) <= math.radians(A.bank_max_deg) + 1e-12
    assert 0.0 <= s.track_rad < 2 * math.pi
    h, p, r = s.attitude_deg(A)
    assert 0.0 <= h < 360.0 and all(math.isfinite(v) for v in (h, p, r))


any_value = st.one_of(st.floats(-2.0, 2.0), st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 1.0, 0.0]))
controls = st.builds(Controls, pitch=any_value, roll=any_value, yaw=any_value, throttle=any_value, flaps=any_value,
                     speed_brake=any_value, park_brake=any_value, brake_left=any_value, brake_right=any_value)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(controls, st.integers(1, 800)), min_size=1, max_size=8), st.booleans())
def test_no_nan_or_runaway_for_any_control_sequence(sequence, start_in_air):
    s = airborne() if start_in_air else on_runway(0.0, 0.0, 0.0, A)
    for c, steps in sequence:
        for _ in range(steps):
            s = step(s, c, DT, A)
        check(s)


def test_deterministic():
    seq = [(Controls(throttle=1.0), 10.0), (Controls(throttle=1.0, pitch=0.3), 3.0),
           (Controls(throttle=0.6, roll=-0.5, yaw=0.2), 8.0)]

    def run():
        s = on_runway(0.0, 0.0, 0.0, A)
        for c, t in seq:
            s = fly(s, c, t)
        return s
    assert run() == run()


def test_rests_with_the_park_brake_and_idle_thrust():
    s = fly(on_runway(5.0, -10.0, 90.0, A), Controls(throttle=0.1, park_brake=1.0), 5.0)
    assert (s.x_m, s.y_m, s.z_m, s.speed_mps) == (5.0, -10.0, FLOOR, 0.0) and s.on_ground


def test_toe_brakes_hold_and_slow_the_aircraft_as_far_as_they_are_pressed():
    # Both pressed in full: held like the park brake. Pressed apart they brake as their mean:
    # the point mass has no wheel track to turn on.
    s = fly(on_runway(5.0, -10.0, 90.0, A), Controls(throttle=0.1, brake_left=1.0, brake_right=1.0), 5.0)
    assert (s.x_m, s.y_m, s.speed_mps) == (5.0, -10.0, 0.0)
    rolling = fly(on_runway(0.0, 0.0, 0.0, A), Controls(throttle=1.0), 8.0)
    speeds = [fly(rolling, Controls(throttle=0.0, brake_left=b, brake_right=b), 3.0).speed_mps for b in (0.0, 0.5, 1.0)]
    assert speeds[0] > speeds[1] > speeds[2] >= 0.0
    one_side = fly(rolling, Controls(throttle=0.0, brake_left=1.0), 3.0)
    assert one_side.speed_mps == pytest.approx(speeds[1]) and one_side.track_rad == rolling.track_rad


def test_takes_off_climbs_and_holds_the_flight_path():
    s = fly(on_runway(0.0, 0.0, 0.0, A), Controls(throttle=1.0), 12.0)
    assert s.on_ground and s.speed_mps > 25.0 and abs(s.x_m) < 1e-9  # straight down the runway
    pitch_on_ground = s.attitude_deg(A)[1]
    rotate = Controls(throttle=1.0, pitch=0.3)
    s = fly(s, rotate, 0.5)
    assert s.attitude_deg(A)[1] > pitch_on_ground + 1.0  # the nose comes up on the wheels
    while s.on_ground:
        s = fly(s, rotate, 0.1)
    s = fly(s, Controls(throttle=1.0, pitch=0.1), 1.0)
    assert not s.on_ground and s.z_m > FLOOR and s.gamma_rad > math.radians(2.0)
    s = fly(s, Controls(throttle=1.0), 1.5)  # stick released: the flight path holds
    gamma = s.gamma_rad
    s2 = fly(s, Controls(throttle=1.0), 5.0)
    assert abs(s2.gamma_rad - gamma) < math.radians(0.5)
    assert s2.z_m > s.z_m + 5.0


def test_level_flight_settles_at_the_speed_where_thrust_meets_drag():
    s = State(0.0, 0.0, 500.0, speed_mps=40.0, on_ground=False)
    s = fly(s, Controls(throttle=0.6), 120.0)
    speed = s.speed_mps
    s = fly(s, Controls(throttle=0.6), 10.0)
    assert abs(s.speed_mps - speed) < 0.5 and abs(math.degrees(s.gamma_rad)) < 0.5
    assert s.z_m == pytest.approx(500.0, abs=20.0)


def test_bank_turns_the_right_way_in_a_coordinated_turn():
    s = fly(airborne(), Controls(throttle=0.6, roll=0.5), 20.0)  # right wing down
    _, _, r = s.attitude_deg(A)
    assert r == pytest.approx(30.0, abs=0.5)
    rate = (fly(s, Controls(throttle=0.6, roll=0.5), 1.0).track_rad - s.track_rad) % (2 * math.pi)
    expected = 9.80665 * math.tan(math.radians(r)) / s.speed_mps
    assert rate == pytest.approx(expected, rel=0.05)  # clockwise: heading increases


def test_the_ground_stops_a_dive():
    s = fly(airborne(), Controls(throttle=1.0, pitch=-1.0), 30.0)
    check(s)
    assert s.z_m == FLOOR


def test_the_step_is_the_callers_choice():
    # Half the step, twice the steps: the same flight to within the integration error.
    a = fly(airborne(), Controls(throttle=0.7, roll=0.3), 10.0)
    b = airborne()
    for _ in range(2000):
        b = step(b, Controls(throttle=0.7, roll=0.3), DT / 2, A)
    assert math.dist((a.x_m, a.y_m, a.z_m), (b.x_m, b.y_m, b.z_m)) < 5.0
