"""JSBSim as the host's flight model: on our runway, the controls' signs, the eye, a take-off.

JSBSim is stepped directly, far faster than real time: a minute of flight takes a few seconds
of CPU.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from host_sim.controlled import ControlledFlight
from host_sim.fdm import RUNWAY_HEADING_DEG, RUNWAY_START_XY_M, open_model, parse_fdm
from host_sim.fdm.ground import Plane, QueryGround
from host_sim.fdm.jsbsim_model import FT_M, IN_M, JSBSimModel
from host_sim.fdm.takeoff import VR_MPS, ScriptedTakeoff
from host_sim.inputs.base import Controls
from services.rig.rigfile import CigiSpec

from .analytic_ground import AnalyticGround, serving

pytest.importorskip("jsbsim")

ORIGIN = CigiSpec().origin  # the bundled airfield's geodetic origin (the rig file's default)
STEP_HZ = 120


def c172(**kw) -> JSBSimModel:
    return JSBSimModel("c172x", origin=ORIGIN, start_xy_m=RUNWAY_START_XY_M, **kw)


def fly(model: JSBSimModel, controls: Controls, seconds: float) -> None:
    for _ in range(int(seconds * STEP_HZ)):
        model.step(controls)


def test_at_rest_on_our_runway_at_the_start():
    m = c172()
    assert m.step_hz == 120.0 and m.on_ground()
    cg = m.world_cg()
    eye = m.eyepoint()
    # On the centreline where it was put, wheels on the runway (world z = 0): the centre of
    # gravity sits at its height above the lowest wheel (c172x: 1.31 m), the eye above that.
    assert abs(cg[0] - RUNWAY_START_XY_M[0]) < 0.5 and abs(cg[1] - RUNWAY_START_XY_M[1]) < 0.5
    assert 1.1 < cg[2] < 1.5
    assert eye.position[2] == pytest.approx(cg[2] + 0.319, abs=0.05)
    assert abs((eye.heading_deg + 180.0) % 360.0 - 180.0) < 1.0 and abs(eye.roll_deg) < 1.0
    # JSBSim's terrain is ours: the height it keeps above it is the height above z = 0.
    assert m.fdm["position/h-agl-ft"] * FT_M == pytest.approx(cg[2], abs=0.02)


def test_rolls_on_the_runway_at_runway_height_until_rotation():
    m = c172()
    heights = []
    for _ in range(15 * STEP_HZ):  # full throttle, stick neutral: a take-off roll without rotation
        m.step(Controls(throttle=1.0))
        heights.append(m.world_cg()[2])
    assert m.speed_mps() > 15.0 and m.on_ground()
    # The wheels stay on the runway: the centre of gravity within 5 cm of its height at rest.
    assert max(heights) - min(heights) < 0.05 and abs(heights[-1] - heights[0]) < 0.05
    assert m.world_cg()[1] > RUNWAY_START_XY_M[1] + 80.0


def test_the_wheels_follow_a_raised_ground():
    # Our ground, not JSBSim's sea level, carries the aircraft: with the ground 10 m higher
    # everywhere, the aircraft rests 10 m higher.
    low = c172().world_cg()[2]
    high = c172(ground=Plane(10.0)).world_cg()[2]
    assert high - low == pytest.approx(10.0, abs=0.05)


def test_the_wheels_roll_on_the_query_services_ground_up_a_slope():
    # The rig's ground from a query service (host_sim.fdm.ground), rising 1 m per 100 m north
    # (a runway's steepest usual gradient): rolling 15 s at full throttle, the centre of gravity
    # keeps its height above the ground under it. JSBSim takes the ground as level under the
    # aircraft at each step, so up a slope it sees level ground rising under its wheels and its
    # strut dampers give: about 8 cm at 18 m/s here (docs/host-flight-model.md).
    def rising(x, y):
        return 0.01 * (y - RUNWAY_START_XY_M[1])

    with serving(AnalyticGround(rising)) as address:
        m = c172(ground=QueryGround(address, start_xy_m=RUNWAY_START_XY_M))
        try:
            above = []
            for _ in range(15 * STEP_HZ):
                m.step(Controls(throttle=1.0))
                cg = m.world_cg()
                above.append(cg[2] - rising(cg[0], cg[1]))
            assert m.world_cg()[1] > RUNWAY_START_XY_M[1] + 80.0 and m.on_ground()
            assert rising(0.0, m.world_cg()[1]) > 0.8  # it climbed the slope
            assert 1.1 < above[0] < 1.5 and max(above) - min(above) < 0.1
            assert m.ground.status()["outside"] == 0
        finally:
            m.close()


def test_toe_brakes_turn_the_aircraft_on_the_ground():
    # Differential braking: the c172x does not steer its nose wheel from the pedals
    # (jsbsim_model's module doc), so a pilot turns it on the ground with a toe brake.
    turns = {}
    for side in ("left", "right"):
        m = c172()
        fly(m, Controls(throttle=0.6), 6.0)
        before = m.eyepoint().heading_deg
        fly(m, Controls(throttle=0.6, **{f"brake_{side}": 0.6}), 3.0)
        turns[side] = (m.eyepoint().heading_deg - before + 180.0) % 360.0 - 180.0
    assert turns["left"] < -5.0 and turns["right"] > 5.0


def test_controls_map_to_fcs_properties_with_signs():
    m = c172()
    m.step(Controls(pitch=1.0, roll=0.5, yaw=0.25, throttle=0.7, flaps=0.5, park_brake=1.0))
    f = m.fdm
    assert f["fcs/elevator-cmd-norm"] == -1.0  # stick aft: JSBSim's nose-up elevator is negative
    assert f["fcs/aileron-cmd-norm"] == 0.5
    assert f["fcs/rudder-cmd-norm"] == -0.25  # right pedal: JSBSim's right yaw is negative rudder
    assert f["fcs/throttle-cmd-norm[0]"] == pytest.approx(0.7)
    assert f["fcs/flap-cmd-norm"] == 0.5
    assert f["fcs/left-brake-cmd-norm"] == 1.0 and f["fcs/right-brake-cmd-norm"] == 1.0
    m.step(Controls(pitch=5.0, throttle=float("nan")))  # clamped, non-finite reads as neutral
    assert f["fcs/elevator-cmd-norm"] == -1.0 and f["fcs/throttle-cmd-norm[0]"] == 0.0
    assert f["fcs/left-brake-cmd-norm"] == 0.0
    m.step(Controls(brake_left=0.3, brake_right=2.0))  # toe brakes, each its wheel's, clamped
    assert f["fcs/left-brake-cmd-norm"] == pytest.approx(0.3) and f["fcs/right-brake-cmd-norm"] == 1.0
    m.step(Controls(brake_left=0.3, park_brake=1.0))  # the park brake sets both in full
    assert f["fcs/left-brake-cmd-norm"] == 1.0 and f["fcs/right-brake-cmd-norm"] == 1.0


def airborne_model() -> JSBSimModel:
    m = c172()
    f = m.fdm
    f["ic/h-agl-ft"] = 3000.0
    f["ic/vc-kts"] = 90.0
    f["ic/psi-true-deg"] = 0.0
    f.run_ic()
    f["propulsion/set-running"] = -1
    return m


@pytest.mark.parametrize("controls, rises", [
    (Controls(throttle=0.7, roll=0.5), "roll"),       # right wheel: right wing down
    (Controls(throttle=0.7, yaw=1.0), "heading"),     # right pedal: nose right
    (Controls(throttle=0.7, pitch=0.5), "pitch"),     # stick aft: nose up
])
def test_controls_move_the_aircraft_the_way_they_say(controls, rises):
    m = airborne_model()
    before = m.eyepoint()
    fly(m, controls, 1.0)
    after = m.eyepoint()
    change = {"roll": after.roll_deg - before.roll_deg,
              "heading": (after.heading_deg - before.heading_deg + 180.0) % 360.0 - 180.0,
              "pitch": after.pitch_deg - before.pitch_deg}[rises]
    assert change > 2.0


def test_eye_offset_is_the_aircraft_eyepoint_less_the_centre_of_gravity():
    m = airborne_model()
    f = m.fdm
    # c172x: eyepoint (37, 0, 48) in, structural x aft, z up.
    assert (f["metrics/eyepoint-x-in"], f["metrics/eyepoint-y-in"], f["metrics/eyepoint-z-in"]) == (37.0, 0.0, 48.0)
    expected = np.array([f["inertia/cg-x-in"] - 37.0, 0.0 - f["inertia/cg-y-in"], f["inertia/cg-z-in"] - 48.0]) * IN_M
    np.testing.assert_allclose(m.eye_offset_m, expected, atol=1e-12)
    # In a 30 degree right bank, nose 10 degrees up, heading 90: the offset turned by that attitude.
    f["ic/psi-true-deg"], f["ic/theta-deg"], f["ic/phi-deg"] = 90.0, 10.0, 30.0
    f.run_ic()
    eye = m.eyepoint()
    fwd, right, down = m.eye_offset_m
    h, p, r = (math.radians(v) for v in (90.0, 10.0, 30.0))
    # Body axes in world (east, north, up) for heading h, pitch p, roll r.
    x_b = np.array([math.sin(h) * math.cos(p), math.cos(h) * math.cos(p), math.sin(p)])
    y_b = np.array([math.cos(h) * math.cos(r) + math.sin(h) * math.sin(p) * math.sin(r),
                    -math.sin(h) * math.cos(r) + math.cos(h) * math.sin(p) * math.sin(r),
                    -math.cos(p) * math.sin(r)])
    z_up = np.cross(y_b, x_b)  # body "up" (minus body z)
    np.testing.assert_allclose(eye.position - m.world_cg(), fwd * x_b + right * y_b - down * z_up, atol=2e-3)
    assert (eye.heading_deg, eye.pitch_deg, eye.roll_deg) == pytest.approx((90.0, 10.0, 30.0), abs=0.05)


def test_scripted_take_off_leaves_the_runway_and_climbs_on_its_heading():
    model = open_model(parse_fdm("jsbsim:c172x"), origin=ORIGIN)
    pilot = ScriptedTakeoff(model, runway_heading_deg=RUNWAY_HEADING_DEG, centreline_xy_m=RUNWAY_START_XY_M)
    flight = ControlledFlight([pilot], model=model)
    lift_off = None
    track = []
    for k in range(60 * 4 + 1):
        t = k / 4
        eye = flight.eyepoint_at(t)
        track.append(eye)
        if lift_off is None and not model.on_ground():
            lift_off = (t, eye.position.copy(), model.speed_mps())
        if lift_off is None:
            # On the runway's centreline within 5 m (the runway is 45 m wide), eye at the height
            # it had at rest: below 20 m/s the toe brakes steer, above it the rudder.
            assert abs(eye.position[0]) < 5.0
            assert eye.position[2] == pytest.approx(track[0].position[2], abs=0.2)
    assert lift_off is not None
    t_off, at, v = lift_off
    # Lifts off within the runway (threshold y = -1000, end +1000) near the rotation speed.
    assert 10.0 < t_off < 40.0 and at[1] < 0.0 and v > 0.9 * VR_MPS
    end = track[-1]
    # Climbs: at least 2 m/s since lift-off, and still climbing at the end; on the runway
    # heading within 5 degrees over the last 20 s, within 30 m of the extended centreline.
    climb = (end.position[2] - at[2]) / (60.0 - t_off)
    assert climb > 2.0 and end.position[2] > track[-40].position[2] + 10.0
    for eye in track[-80:]:
        assert abs((eye.heading_deg - RUNWAY_HEADING_DEG + 180.0) % 360.0 - 180.0) < 5.0
        assert abs(eye.position[0]) < 30.0
    _, model_status = flight.status()
    assert model_status.steps == 60 * STEP_HZ + 1 and not model_status.on_ground
