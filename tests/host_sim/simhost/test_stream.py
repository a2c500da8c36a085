"""Poses to eyepoints: the eye offset, the geodetic conversion, and the timing between datagrams
(an injected clock: no test waits on the wall clock)."""

from __future__ import annotations

import numpy as np
import pytest

from host_sim.cigi.geometry import pose_of_geodetic
from host_sim.simhost.stream import Pose, PoseStream, blend, eyepoint_of_pose
from services.rig import geodetic
from services.rig.frame import Eyepoint

ORIGIN = (36.6089, -84.1708, 349.2)


def at_origin(h=0.0, p=0.0, r=0.0, alt=349.2) -> Pose:
    return Pose(ORIGIN[0], ORIGIN[1], alt, h, p, r)


@pytest.mark.parametrize("h,p,r,offset,expected", [
    # x forward, y right, z down in body axes -> east, north, up in the world.
    (0.0, 0.0, 0.0, (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    (90.0, 0.0, 0.0, (1.0, 0.0, 0.0), (1.0, 0.0, 0.0)),  # heading east: forward is east
    (0.0, 0.0, 0.0, (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)),  # right of a north-facing aircraft: east
    (0.0, 0.0, 0.0, (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)),  # z down negative: above
    (0.0, 30.0, 0.0, (1.0, 0.0, 0.0), (0.0, np.cos(np.radians(30)), 0.5)),  # nose up: forward rises
    (0.0, 0.0, 30.0, (0.0, 0.0, -1.0), (0.5, 0.0, np.cos(np.radians(30)))),  # right wing down: head goes right
    (0.0, 0.0, 30.0, (0.0, 1.0, 0.0), (np.cos(np.radians(30)), 0.0, -0.5)),  # and the right wing goes down
    (180.0, 0.0, 90.0, (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),  # facing south, knife edge: right points down
])
def test_eye_offset_in_body_axes(h, p, r, offset, expected):
    eye = eyepoint_of_pose(at_origin(h, p, r), origin=ORIGIN, eye_offset_m=offset)
    assert eye.position == pytest.approx(np.array(expected), abs=1e-9)
    assert (eye.heading_deg % 360.0, eye.pitch_deg, eye.roll_deg) == pytest.approx((h % 360.0, p, r), abs=1e-9)


def test_far_from_the_origin_position_and_attitude_are_the_cigi_conversion():
    lat, lon, alt = 37.2, -83.5, 1500.0  # about 90 km from the origin
    eye = eyepoint_of_pose(Pose(lat, lon, alt, 200.0, 5.0, -20.0), origin=ORIGIN, eye_offset_m=(0.0, 0.0, 0.0))
    assert eye.position == pytest.approx(geodetic.enu(np.array([lat]), np.array([lon]), np.array([alt]),
                                                      ORIGIN)[0], abs=1e-6)
    cigi = pose_of_geodetic(lat, lon, alt, 200.0, 5.0, -20.0, ORIGIN)
    assert (eye.heading_deg, eye.pitch_deg, eye.roll_deg) == (cigi.heading_deg, cigi.pitch_deg, cigi.roll_deg)
    # The local horizontal there is tilted against the origin's by about 0.8 degrees.
    assert abs(eye.heading_deg - 200.0) > 0.1


def test_c172x_eyepoint_example():
    """docs/sim-hosts.md's example: JSBSim c172x eye 0.216 m ahead and 0.319 m above the
    reported centre of gravity; level on heading 0 the eye is that far north and up."""
    eye = eyepoint_of_pose(at_origin(), origin=ORIGIN, eye_offset_m=(0.216, 0.0, -0.319))
    assert eye.position == pytest.approx([0.0, 0.216, 0.319], abs=1e-9)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def stream(clock: Clock, **kw) -> PoseStream:
    return PoseStream("test", origin=ORIGIN, clock=clock, wall=lambda: 1e9 + clock.t, **kw)


def north(metres: float, heading: float = 0.0) -> Pose:
    """A pose `metres` north of the origin (1 degree of latitude is about 111 km)."""
    return at_origin(h=heading, alt=ORIGIN[2]) if metres == 0 else Pose(
        ORIGIN[0] + metres / 111_000.0, ORIGIN[1], ORIGIN[2], heading, 0.0, 0.0)


def test_nothing_is_published_before_the_first_pose():
    clock = Clock()
    s = stream(clock)
    frame = s.frame_input(0.0)
    assert frame.eyepoint is None and frame.sample_time is None
    assert s.status().stale and s.status().last_input_age_s == -1.0


def test_interpolation_a_delay_behind_the_arrivals():
    clock = Clock()
    s = stream(clock, delay_s=0.05)
    for k in range(5):  # 20 Hz, 10 m apart
        s.accept(north(10.0 * k), arrival=100.0 + 0.05 * k)
    clock.t = 100.2 + 0.025  # 0.05 s behind now: halfway between arrivals 3 and 4
    frame = s.frame_input(0.0)
    assert frame.eyepoint is not None
    assert frame.eyepoint.position[1] == pytest.approx(35.0, abs=0.01)
    assert frame.sample_time == pytest.approx(1e9 + 100.2)  # arrival of the newest packet used (4)
    assert s.status().late == 0


def test_the_default_delay_is_one_and_a_half_measured_intervals():
    clock = Clock()
    s = stream(clock)
    for k in range(10):
        s.accept(north(10.0 * k), arrival=100.0 + 0.02 * k + (0.004 if k % 2 else 0.0))  # 50 Hz, jitter
    status = s.status()
    assert status.interval_s == pytest.approx(0.02, abs=0.0041)
    assert status.delay_s == pytest.approx(1.5 * status.interval_s)


def test_heading_interpolates_across_north():
    clock = Clock()
    s = stream(clock, delay_s=0.05)
    s.accept(north(0.0, heading=358.0), arrival=100.0)
    s.accept(north(0.0, heading=4.0), arrival=100.05)
    clock.t = 100.075
    eye = s.frame_input(0.0).eyepoint
    assert eye is not None and eye.heading_deg == pytest.approx(1.0, abs=1e-6)


def test_blend_takes_the_shorter_arc_of_roll_and_heading():
    a = Eyepoint.of(0, 0, 0, 350.0, 0.0, 179.0)
    b = Eyepoint.of(0, 0, 0, 10.0, 0.0, -179.0)
    mid = blend(a, b, 0.5)
    assert mid.heading_deg == pytest.approx(0.0, abs=1e-9) or mid.heading_deg == pytest.approx(360.0)
    assert abs(mid.roll_deg) == pytest.approx(180.0)


def test_a_late_packet_is_extrapolated_and_counted():
    clock = Clock()
    s = stream(clock, delay_s=0.05, max_extrapolate_s=0.1)
    for k in range(3):
        s.accept(north(10.0 * k), arrival=100.0 + 0.05 * k)
    clock.t = 100.1 + 0.05 + 0.02  # the moment shown is 0.02 s past the newest arrival
    eye = s.frame_input(0.0).eyepoint
    assert eye is not None and eye.position[1] == pytest.approx(24.0, abs=0.01)
    assert s.status().late == 1 and s.status().extrapolated == 1


def test_extrapolation_is_bounded():
    clock = Clock()
    s = stream(clock, timing="extrapolate", max_extrapolate_s=0.1)
    s.accept(north(0.0), arrival=100.0)
    s.accept(north(10.0), arrival=100.05)
    clock.t = 100.05 + 0.04
    eye = s.frame_input(0.0).eyepoint
    assert eye is not None and eye.position[1] == pytest.approx(18.0, abs=0.01)
    clock.t = 100.05 + 0.5  # far past the bound, not yet stale
    eye = s.frame_input(0.0).eyepoint
    assert eye is not None and eye.position[1] == pytest.approx(30.0, abs=0.01)
    assert s.status().held == 1


def test_a_silent_simulator_goes_stale_holds_its_last_pose_and_comes_back():
    clock = Clock()
    s = stream(clock, timing="extrapolate", stale_after_s=1.0)
    s.accept(north(0.0), arrival=100.0)
    s.accept(north(10.0), arrival=100.05)
    clock.t = 101.5
    eye = s.frame_input(0.0).eyepoint
    assert eye is not None and eye.position[1] == pytest.approx(10.0, abs=0.01)  # held, not carried on
    status = s.status()
    assert status.stale and status.stale_events == 1 and status.refused == {"stale": 1}
    assert status.last_input_age_s == pytest.approx(1.45)
    s.accept(north(20.0), arrival=101.6)
    assert not s.status().stale and s.status().stale_events == 1


def test_bad_timing_names_the_value():
    with pytest.raises(ValueError, match="timing: 'smooth' is not one of interpolate, extrapolate"):
        stream(Clock(), timing="smooth")


def test_poses_yields_each_pose_as_it_is_accepted():
    import itertools
    import threading

    s = stream(Clock())
    got = s.poses(timeout_s=30.0)

    def send() -> None:
        for k in range(3):
            s.accept(north(10.0 * k), arrival=100.0 + k)

    first = threading.Thread(target=send)  # poses() counts from its call, before these
    first.start()
    try:
        poses = list(itertools.islice(got, 3))
    finally:
        first.join()
    assert [round((p.lat_deg - ORIGIN[0]) * 111_000.0) for p in poses] == [0, 10, 20]
