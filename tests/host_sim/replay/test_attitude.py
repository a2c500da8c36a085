"""The attitude estimate of logs without attitude, on tracks shaped like real ones (GNSS noise,
taxiing, take-off, turns, hovering, IGC quantisation), and logged attitudes carried from the
local frame at the aircraft into the world frame at the origin, checked against an
independent ECEF computation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.replay import attitude
from services.rig import geodetic

G = 9.80665


def path_of(segments, *, start=(0.0, 0.0, 0.0), heading=0.0, dt=1.0):
    """(t, positions, label per record) of a track flown segment by segment at dt seconds:
    each segment (label, seconds, speed m/s at its start, speed at its end, turn deg/s, climb m/s)."""
    t, pos, labels = [], [], []
    x, y, z = start
    now = 0.0
    for label, seconds, v0, v1, turn, climb in segments:
        steps = round(seconds / dt)
        for k in range(steps):
            t.append(now)
            pos.append((x, y, z))
            labels.append(label)
            v = v0 + (v1 - v0) * (k + 0.5) / steps
            heading += 0.5 * turn * dt  # midpoint heading: a circle's chord, exactly
            x += v * dt * math.sin(math.radians(heading))
            y += v * dt * math.cos(math.radians(heading))
            heading += 0.5 * turn * dt
            z += climb * dt
            now += dt
    return np.array(t), np.array(pos), np.array(labels)


def noisy(rng, pos, *, horizontal_m=1.0, vertical_m=3.0):
    """Positions with uniform GNSS-like noise of +-horizontal_m and +-vertical_m."""
    return pos + rng.uniform(-1.0, 1.0, pos.shape) * [horizontal_m, horizontal_m, vertical_m]


def angle_error(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


TAXI = [("taxi", 20, 5, 15, 0, 0), ("taxi", 10, 15, 8, 9, 0), ("taxi", 30, 8, 12, 0, 0),
        ("taxi", 15, 12, 5, -6, 0), ("taxi", 20, 5, 10, 0, 0)]


@pytest.mark.parametrize("seed", range(10))
def test_taxiing_with_noisy_heights_is_ground_roll(seed):
    # The issue: from altitude noise over metres between fixes, neighbouring differences made
    # pitch swing by 50-60 degrees on the taxiway.
    t, clean, _ = path_of(TAXI, heading=30.0)
    est = attitude.estimate_with_report(t, noisy(np.random.default_rng(seed), clean))
    assert est.on_ground.all()
    assert np.abs(est.hpr[:, 1]).max() < 2.0 and np.abs(est.hpr[:, 2]).max() < 2.0
    # heading is still the track: compare with the clean track's direction
    d = np.gradient(clean, t, axis=0)
    assert angle_error(est.hpr[:, 0], np.degrees(np.arctan2(d[:, 0], d[:, 1])))[3:-3].max() < 10.0


@pytest.mark.parametrize("seed", range(10))
def test_take_off_and_a_three_degree_climb(seed):
    climb = 30.0 * math.tan(math.radians(3.0))
    t, clean, labels = path_of(TAXI + [("line up", 10, 0, 0, 0, 0), ("roll", 25, 0, 30, 0, 0),
                                       ("climb", 150, 30, 30, 0, climb)], heading=30.0)
    est = attitude.estimate_with_report(t, noisy(np.random.default_rng(seed), clean))
    assert est.on_ground[np.isin(labels, ["taxi", "line up"])].all()
    roll = np.flatnonzero(labels == "roll")
    assert est.on_ground[roll[:14]].all()  # up to 17 m/s: still below the take-off speed
    airborne = np.flatnonzero(labels == "climb")
    assert not est.on_ground[airborne].any()
    # once the pitch window (400 m, 13 s at 30 m/s) has left the runway, and before it is cut short at
    # the end of the log
    steady = airborne[(t[airborne] >= t[airborne[0]] + 15.0) & (t[airborne] <= t[-1] - 7.0)]
    np.testing.assert_allclose(est.hpr[steady, 1], 3.0, atol=1.0)
    assert np.abs(est.hpr[steady, 2]).max() < 2.0


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_a_coordinated_turn_at_30_degrees_of_bank(direction):
    v = 40.0
    turn_dps = direction * math.degrees(G * math.tan(math.radians(30.0)) / v)  # 8.1 deg/s
    t, clean, _ = path_of([("turn", 120, v, v, turn_dps, 0.0)], start=(0.0, 0.0, 1500.0))
    est = attitude.estimate_with_report(t, noisy(np.random.default_rng(7), clean))
    inside = slice(4, -4)  # the motion window is whole
    np.testing.assert_allclose(est.hpr[inside, 2], direction * 30.0, atol=3.0)
    assert np.abs(est.hpr[inside, 1]).max() < 1.0
    heading = (turn_dps * t) % 360.0  # the tangent at each record (path_of starts north)
    assert angle_error(est.hpr[inside, 0], heading[inside]).max() < 2.0
    assert not est.on_ground.any()


def test_parked_then_a_vertical_climb_and_a_hover():
    # A drone: moves north-east, lands and parks, climbs straight up to 50 m and hovers.
    t, clean, labels = path_of([("move", 20, 5, 5, 0, 0), ("parked", 40, 0, 0, 0, 0),
                                ("climb", 25, 0, 0, 0, 2.0), ("hover", 20, 0, 0, 0, 0)], heading=45.0)
    est = attitude.estimate_with_report(t, noisy(np.random.default_rng(3), clean))
    assert angle_error(est.hpr[:, 0], 45.0).max() < 5.0  # held while not moving
    still = labels != "move"
    assert (est.hpr[still, 1:] == 0.0).all()
    assert est.on_ground[labels == "parked"].all()
    assert not est.on_ground[labels == "hover"].any()  # 50 m above where it parked


def gaussian(rng, pos, sigma_m):
    """Positions with Gaussian horizontal noise of sigma_m in east and in north (heights clean)."""
    return pos + rng.normal(0.0, 1.0, pos.shape) * [sigma_m, sigma_m, 0.0]


def assert_heading_rate_limited(t, heading):
    limit = attitude.MAX_HEADING_RATE_DPS * np.diff(t) * (1 + 1e-9) + 1e-9
    assert (angle_error(heading[1:], heading[:-1]) <= limit).all()


@pytest.mark.parametrize("sigma_m", [1.0, 2.0, attitude.GNSS_NOISE_M])
@pytest.mark.parametrize("seed", range(5))
def test_a_parked_heading_holds_through_gnss_noise(sigma_m, seed):
    # The issue: at 1 Hz with sigma 1.5 m of noise, the window's speed from noise alone often
    # passed the 1 m/s hold threshold, and the parked heading spun through 265 degrees at up to
    # 176 deg/s. Taxi in heading 70, park for 120 s (pivoting 90 degrees in place, which the track
    # cannot show), taxi away heading 160.
    t, clean, labels = path_of([("in", 30, 8, 8, 0, 0), ("parked", 120, 0, 0, 0.75, 0),
                                ("out", 60, 10, 10, 0, 0)], heading=70.0)
    heading = attitude.estimate(t, gaussian(np.random.default_rng(seed), clean, sigma_m))[:, 0]
    assert_heading_rate_limited(t, heading)
    parked = np.flatnonzero(labels == "parked")
    # Records whose motion window is all parked and which the limited turn to the taxi-out
    # heading (90 degrees at MAX_HEADING_RATE_DPS, smoothed both ways) does not reach.
    turn_s = 90.0 / attitude.MAX_HEADING_RATE_DPS
    half = attitude.MOTION_WINDOW_S / 2.0
    still = parked[(t[parked] >= t[parked[0]] + half) & (t[parked] <= t[parked[-1]] - half - turn_s)]
    swing = np.degrees(np.unwrap(np.radians(heading[still])))
    assert swing.max() - swing.min() < 1.0
    # The taxi-in heading, held: that of the last window to pass MOVING_DISPLACEMENT_M, with an
    # error of 0.61 sigma / MOVING_DISPLACEMENT_M radians (3.5 deg at sigma 1 m).
    assert angle_error(heading[still], 70.0).max() < 4.0 * math.degrees(
        0.61 * sigma_m / attitude.MOVING_DISPLACEMENT_M) + 1.0
    out = np.flatnonzero(labels == "out")
    out = out[(t[out] >= t[out[0]] + half) & (t[out] <= t[-1] - half)]
    error = angle_error(heading[out], 160.0)
    # The direction between the halves' mean positions, 30 m apart at 10 m/s, has an error of
    # 0.61 sigma / 30 m radians (1.2 deg at sigma 1 m): follows the track, no more noisy than that.
    assert np.median(error) < 3.0
    assert error.max() < 4.0 * math.degrees(0.61 * sigma_m / 30.0) + 1.0


def test_heading_turns_no_faster_than_an_aircraft():
    # A 180-degree glitch in a taxi (one fix 40 m to the side) and a reversal on the spot.
    t, clean, _ = path_of([("taxi", 30, 10, 10, 0, 0), ("stop", 5, 10, 0, 0, 0), ("back", 30, 0, 0, 0, 0)])
    clean[40:, 1] = clean[39, 1] - 8.0 * (t[40:] - t[39])  # then taxi back south
    clean[20, 0] += 40.0
    est = attitude.estimate_with_report(t, clean)
    assert_heading_rate_limited(t, est.hpr[:, 0])
    assert angle_error(est.hpr[:10, 0], 0.0).max() < 1.0
    assert angle_error(est.hpr[-20:-4, 0], 180.0).max() < 1.0
    text = " ".join(est.assumptions)
    for value in (attitude.MAX_HEADING_RATE_DPS, attitude.MOVING_DISPLACEMENT_M, attitude.GNSS_NOISE_M):
        assert f"{value:g}" in text


def test_an_igc_like_track_with_quantised_fixes():
    # 1 Hz fixes as IGC stores them: thousandths of a minute of latitude and longitude, whole
    # metres of height; a tow to 600 m at 5.7 degrees, then level.
    origin = (46.5, 7.0, 500.0)
    climb = 30.0 * 0.1
    t, clean, labels = path_of([("tow", 200, 30, 30, 0, climb), ("level", 120, 30, 30, 0, 0.0)],
                               start=(0.0, 0.0, 500.0), heading=250.0)
    lat, lon, h = geodetic.geodetic_of_enu(clean[:, 0], clean[:, 1], clean[:, 2] - origin[2], origin)
    lat = np.round(lat * 60_000.0) / 60_000.0
    lon = np.round(lon * 60_000.0) / 60_000.0
    position = geodetic.enu(lat, lon, np.round(h), origin)
    est = attitude.estimate_with_report(t, position)
    tow = np.flatnonzero(labels == "tow")[10:-10]
    level = np.flatnonzero(labels == "level")[10:-10]
    np.testing.assert_allclose(est.hpr[tow, 1], math.degrees(math.atan(0.1)), atol=1.0)
    np.testing.assert_allclose(est.hpr[level, 1], 0.0, atol=1.0)
    assert angle_error(est.hpr[10:-10, 0], 250.0).max() < 2.0
    assert np.abs(est.hpr[10:-10, 2]).max() < 2.0


def test_estimate_is_the_reported_hpr_and_the_assumptions_name_the_constants():
    t, clean, _ = path_of(TAXI)
    est = attitude.estimate_with_report(t, clean)
    np.testing.assert_array_equal(attitude.estimate(t, clean), est.hpr)
    text = " ".join(est.assumptions)
    for value in (attitude.PITCH_WINDOW_M, attitude.TAKEOFF_SPEED_MPS, attitude.GROUND_HEIGHT_M,
                  attitude.MAX_PITCH_DEG, attitude.MAX_BANK_DEG, attitude.MOTION_WINDOW_S):
        assert f"{value:g}" in text
    assert "coordinated turn" in text and "Ground roll" in text


def test_short_and_bad_tracks():
    assert attitude.estimate(np.zeros(0), np.zeros((0, 3))).shape == (0, 3)
    one = attitude.estimate_with_report(np.array([3.0]), np.array([[1.0, 2.0, 3.0]]))
    assert one.hpr.shape == (1, 3) and one.on_ground.shape == (1,)
    two = attitude.estimate(np.array([0.0, 1.0]), np.array([[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]]))
    np.testing.assert_allclose(two[:, 0], 90.0)
    with pytest.raises(ValueError, match=r"t_s\[2\]: 1.0 does not come after t_s\[1\] = 1.0"):
        attitude.estimate(np.array([0.0, 1.0, 1.0]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"position\[1, 2\]: nan is not finite"):
        attitude.estimate(np.array([0.0, 1.0]), np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.nan]]))
    with pytest.raises(ValueError, match=r"position: shape \(2, 2\), need \(2, 3\)"):
        attitude.estimate(np.array([0.0, 1.0]), np.zeros((2, 2)))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 150), st.floats(0.05, 10.0), st.floats(0.0, 20.0),
       st.floats(0.0, 80.0))
def test_random_noisy_tracks_stay_finite_and_bounded(seed, n, dt_max, noise_m, speed):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, dt_max, n))
    velocity = speed * np.cumsum(rng.normal(0.0, 0.3, (n, 3)), axis=0)
    position = np.cumsum(velocity * np.gradient(t)[:, None], axis=0) + rng.uniform(-noise_m, noise_m, (n, 3))
    est = attitude.estimate_with_report(t, position)
    hpr = est.hpr
    assert hpr.shape == (n, 3) and est.on_ground.shape == (n,) and est.on_ground.dtype == bool
    assert np.isfinite(hpr).all()
    assert ((hpr[:, 0] >= 0.0) & (hpr[:, 0] < 360.0)).all()
    assert np.abs(hpr[:, 1]).max() <= attitude.MAX_PITCH_DEG
    assert np.abs(hpr[:, 2]).max() <= attitude.MAX_BANK_DEG
    assert (hpr[est.on_ground, 1:] == 0.0).all()
    dt = np.diff(t)
    assert (np.abs(np.diff(hpr[:, 1])) <= attitude.MAX_PITCH_RATE_DPS * dt * (1 + 1e-9) + 1e-9).all()
    assert (np.abs(np.diff(hpr[:, 2])) <= attitude.MAX_BANK_RATE_DPS * dt * (1 + 1e-9) + 1e-9).all()
    assert_heading_rate_limited(t, hpr[:, 0])


# Logged attitudes: the local frame at the aircraft -> the world frame at the origin.

def local_axes_ecef(lat_deg, lon_deg):
    """East, north and up unit vectors at a geodetic position, in ECEF, from first principles:
    up is the normal of the ellipsoid x^2/a^2 + y^2/a^2 + z^2/b^2 = 1 (its gradient), east is
    horizontal and perpendicular to the earth's axis, north completes the right-handed set."""
    a, b = 6378137.0, 6356752.314245
    x, y, z = geodetic.ecef(np.array(lat_deg), np.array(lon_deg), np.array(0.0))
    up = np.array([x / a**2, y / a**2, z / b**2])
    up /= np.linalg.norm(up)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    return east, np.cross(up, east), up


def body_axes(heading, pitch, roll):
    """(right, forward, up) of an attitude in its east-north-up frame, from the definitions of
    docs/conventions.md: the nose heading clockwise from north and pitched up, then the wings
    rolled right-wing-down about the nose."""
    h, p, r = np.radians([heading, pitch, roll])
    forward = np.array([math.sin(h) * math.cos(p), math.cos(h) * math.cos(p), math.sin(p)])
    right0 = np.array([math.cos(h), -math.sin(h), 0.0])  # level, to the right of the nose
    up0 = np.cross(right0, forward)
    return math.cos(r) * right0 - math.sin(r) * up0, forward, math.cos(r) * up0 + math.sin(r) * right0


ATTITUDES = [(0.0, 0.0, 0.0), (30.0, 10.0, 20.0), (200.0, -45.0, 170.0), (0.0, 0.0, 180.0), (270.0, 0.0, -180.0),
             (123.0, 89.99, 40.0), (300.0, -89.99, -120.0), (45.0, 90.0, 0.0), (10.0, -90.0, 0.0), (90.0, 5.0, -60.0)]


@pytest.mark.parametrize("origin", [(47.0, 8.0, 500.0), (-33.9, 151.2, 0.0), (78.0, 15.0, 0.0)])
@pytest.mark.parametrize("distance_m", [600e3, 1000e3])
@pytest.mark.parametrize("bearing", [0.0, 60.0, 135.0, 200.0, 290.0])
def test_local_to_world_against_an_independent_ecef_computation(origin, distance_m, bearing):
    b = math.radians(bearing)
    lat, lon, _ = geodetic.geodetic_of_enu(distance_m * math.sin(b), distance_m * math.cos(b), 0.0, origin)
    hpr = np.array(ATTITUDES)
    got = attitude.local_to_world(hpr, np.full(len(hpr), lat), np.full(len(hpr), lon), origin)
    e1, n1, u1 = local_axes_ecef(lat, lon)
    e0, n0, u0 = local_axes_ecef(origin[0], origin[1])
    for local, world in zip(hpr, got, strict=True):
        expected = []
        for v in body_axes(*local):
            v_ecef = v[0] * e1 + v[1] * n1 + v[2] * u1
            expected.append(np.array([v_ecef @ e0, v_ecef @ n0, v_ecef @ u0]))
        # the same rotation, whatever the angles (pitch +-90 has many names)
        for want, have in zip(expected, body_axes(*world), strict=True):
            np.testing.assert_allclose(have, want, atol=1e-9)
        right, forward, up = expected
        pitch = math.degrees(math.asin(forward[2]))
        assert world[1] == pytest.approx(pitch, abs=1e-7)
        if abs(pitch) < 85.0:
            assert angle_error(world[0], math.degrees(math.atan2(forward[0], forward[1]))) < 1e-7
            assert angle_error(world[2], math.degrees(math.atan2(-right[2], up[2]))) < 1e-7
    # the local vertical has turned by the angle between the two normals
    tilt = math.degrees(math.acos(np.clip(u1 @ u0, -1.0, 1.0)))
    assert tilt == pytest.approx(distance_m / 111_000.0, rel=0.02)


def test_at_the_origin_the_change_of_frame_is_the_identity():
    origin = (47.0, 8.0, 500.0)
    hpr = np.array([a for a in ATTITUDES if abs(a[1]) < 89.0 and abs(a[2]) < 180.0])
    got = attitude.local_to_world(hpr, np.full(len(hpr), origin[0]), np.full(len(hpr), origin[1]), origin)
    np.testing.assert_allclose(got, hpr, atol=1e-9)
    straight_up = attitude.local_to_world(np.array([[45.0, 90.0, 0.0]]), np.array([47.0]), np.array([8.0]), origin)
    np.testing.assert_allclose(straight_up, [[45.0, 90.0, 0.0]], atol=1e-6)


def test_level_flight_due_north_600_km_north_is_pitched_down_5_4_degrees():
    origin = (47.0, 8.0, 500.0)
    lat = origin[0] + math.degrees(600e3 / 6_371_000.0)  # 600 km further along the meridian
    (heading, pitch, roll), = attitude.local_to_world(np.zeros((1, 3)), np.array([lat]), np.array([8.0]), origin)
    # the normal's elevation is the geodetic latitude: along a meridian the tilt is the change of latitude
    assert pitch == pytest.approx(-(lat - origin[0]), abs=1e-9)
    assert pitch == pytest.approx(-5.4, abs=0.05)
    assert angle_error(heading, 0.0) < 1e-9 and abs(roll) < 1e-9


def test_local_to_world_names_bad_shapes():
    with pytest.raises(ValueError, match=r"hpr_deg: shape \(3,\), need \(n, 3\)"):
        attitude.local_to_world(np.zeros(3), np.zeros(1), np.zeros(1), (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=r"lon_deg: shape \(1,\), need \(2,\) like hpr_deg"):
        attitude.local_to_world(np.zeros((2, 3)), np.zeros(2), np.zeros(1), (0.0, 0.0, 0.0))
