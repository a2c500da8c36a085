"""The CIGI conversions: the scalar ownship pose equals the array conversions the replay uses,
body offsets go both ways, and a local vertical leans as the earth curves."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.cigi.geometry import (
    azimuth_elevation,
    body_of_world,
    direction_of,
    geodetic_of_world,
    local_rotation,
    pose_of_geodetic,
    world_of_body,
)
from host_sim.replay.attitude import local_to_world
from services.rig import geodetic

ORIGIN = (36.6089, -84.1708, 349.2)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-500.0, 12000.0), st.floats(0.0, 360.0),
       st.floats(-90.0, 90.0), st.floats(-180.0, 180.0))
def test_the_ownship_pose_is_the_replays_conversion(dlat, dlon, alt, yaw, pitch, roll):
    lat, lon = ORIGIN[0] + dlat, ORIGIN[1] + dlon
    pose = pose_of_geodetic(lat, lon, alt, yaw, pitch, roll, ORIGIN)
    np.testing.assert_allclose(pose.position, geodetic.enu(np.array([lat]), np.array([lon]), np.array([alt]),
                                                           ORIGIN)[0], atol=1e-6)
    expected = local_to_world(np.array([[yaw, pitch, roll]]), np.array([lat]), np.array([lon]), ORIGIN)[0]
    from services.rig.frame import hpr_matrix
    # Compare rotations, not angles: at pitch +-90 heading and roll trade places.
    np.testing.assert_allclose(pose.rotation, hpr_matrix(*expected), atol=1e-9)
    np.testing.assert_allclose(hpr_matrix(pose.heading_deg, pose.pitch_deg, pose.roll_deg), pose.rotation, atol=1e-9)


def test_a_thousand_kilometres_away_the_pose_keeps_its_millimetres():
    lat = ORIGIN[0] + 9.0  # about 1000 km north
    pose = pose_of_geodetic(lat, ORIGIN[1], 10000.0, 0.0, 0.0, 0.0, ORIGIN)
    back = geodetic_of_world(pose.position[None], ORIGIN)
    assert (back[0][0], back[1][0], back[2][0]) == pytest.approx((lat, ORIGIN[1], 10000.0), abs=1e-9)
    # Level flight there pitches down in the origin's world by the arc between the verticals.
    assert pose.pitch_deg == pytest.approx(-9.0, abs=0.1)


def test_body_offsets_go_both_ways_and_point_where_cigi_says():
    pose = pose_of_geodetic(*ORIGIN[:2], ORIGIN[2] + 100.0, 90.0, 0.0, 0.0, ORIGIN)  # facing east
    ahead = world_of_body(pose, np.array([10.0, 0.0, 0.0]))[0]  # x forward
    right = world_of_body(pose, np.array([0.0, 10.0, 0.0]))[0]  # y right: south when facing east
    down = world_of_body(pose, np.array([0.0, 0.0, 10.0]))[0]  # z down
    np.testing.assert_allclose(ahead - pose.position, [10.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(right - pose.position, [0.0, -10.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(down - pose.position, [0.0, 0.0, -10.0], atol=1e-9)
    offsets = np.array([[1.0, 2.0, 3.0], [-4.0, 5.5, -6.0]])
    np.testing.assert_allclose(body_of_world(pose, world_of_body(pose, offsets)), offsets, atol=1e-9)


def test_directions_and_their_angles_agree():
    for az, el in ((0.0, 0.0), (90.0, 10.0), (-135.0, -45.0), (179.0, 89.0)):
        a, e = azimuth_elevation(direction_of(az, el)[None], np.eye(3))
        assert (a[0], e[0]) == pytest.approx((az, el), abs=1e-9)
    assert azimuth_elevation(np.zeros((1, 3)), np.eye(3)) == (pytest.approx([0.0]), pytest.approx([0.0]))


def test_the_local_vertical_leans_a_degree_per_111_km():
    up = local_rotation(ORIGIN[0] + 1.0, ORIGIN[1], ORIGIN) @ np.array([0.0, 0.0, 1.0])
    assert np.degrees(np.arccos(up[2])) == pytest.approx(1.0, abs=0.01)
    assert up[1] > 0  # north of the origin, up leans north


def test_the_scalar_point_conversions_equal_the_array_ones():
    from host_sim.cigi.geometry import height_of_world, point_and_up, world_of_geodetic

    for lat, lon, h in ((ORIGIN[0], ORIGIN[1], 0.0), (ORIGIN[0] + 0.5, ORIGIN[1] - 0.7, 3000.0), (80.0, 10.0, -50.0)):
        point, up = point_and_up(lat, lon, h, ORIGIN)
        np.testing.assert_allclose(point, world_of_geodetic(np.array([lat]), np.array([lon]), np.array([h]),
                                                            ORIGIN)[0], atol=1e-6)
        np.testing.assert_allclose(up, local_rotation(lat, lon, ORIGIN)[:, 2], atol=1e-12)
        assert height_of_world(point, ORIGIN) == pytest.approx(h, abs=1e-6)
