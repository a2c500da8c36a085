"""The local east-north-up axes of a geodetic position and the tilt of its vertical seen from
another (geodetic.enu_rotation, geodetic.vertical_angle_deg)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.rig import geodetic

LATS = np.array([-89.0, -33.9, 0.0, 47.0, 78.0, 90.0])
LONS = np.array([-170.0, 151.2, 0.0, 8.0, 15.0, 45.0])


def test_the_rows_are_a_right_handed_orthonormal_basis():
    r = geodetic.enu_rotation(LATS, LONS)
    assert r.shape == (6, 3, 3)
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-15)
    assert geodetic.enu_rotation(np.zeros((2, 4)), np.array(5.0)).shape == (2, 4, 3, 3)


@pytest.mark.parametrize("lat,lon", list(zip(LATS[1:-1], LONS[1:-1], strict=True)))
def test_the_rows_point_east_north_and_up(lat, lon):
    # By finite differences of ECEF positions: a step east, north and up.
    east, north, up = geodetic.enu_rotation(np.array(lat), np.array(lon))
    p = geodetic.ecef(np.array(lat), np.array(lon), np.array(100.0))
    for row, (dlat, dlon, dh) in ((east, (0, 1e-6, 0)), (north, (1e-6, 0, 0)), (up, (0, 0, 1.0))):
        step = geodetic.ecef(np.array(lat + dlat), np.array(lon + dlon), np.array(100.0 + dh)) - p
        np.testing.assert_allclose(row, step / np.linalg.norm(step), atol=1e-7)


def test_it_agrees_with_enu_and_its_origin_rotation():
    origin = (47.0, 8.0, 500.0)
    r = geodetic.enu_rotation(np.array(origin[0]), np.array(origin[1]))
    lat, lon, h = np.array([47.5, 46.0]), np.array([9.0, 7.5]), np.array([1000.0, 20.0])
    d = geodetic.ecef(lat, lon, h) - geodetic.ecef(np.array(origin[0]), np.array(origin[1]), np.array(origin[2]))
    np.testing.assert_allclose(d @ r.T, geodetic.enu(lat, lon, h, origin), atol=1e-8)


def test_the_vertical_tilts_by_the_change_of_latitude_along_a_meridian():
    origin = (47.0, 8.0, 0.0)
    assert geodetic.vertical_angle_deg(np.array(47.0), np.array(8.0), origin) == pytest.approx(0.0, abs=1e-12)
    for d_lat in (-20.0, -1.0, 1e-6, 3.0, 5.4, 9.0):
        angle = geodetic.vertical_angle_deg(np.array(47.0 + d_lat), np.array(8.0), origin)
        assert angle == pytest.approx(abs(d_lat), rel=1e-9)


@pytest.mark.parametrize("distance_m,expected_deg", [(600e3, 5.4), (1000e3, 9.0)])
def test_the_vertical_600_and_1000_km_away(distance_m, expected_deg):
    origin = (47.0, 8.0, 500.0)
    for bearing in (0.0, 90.0, 225.0):
        b = math.radians(bearing)
        lat, lon, _ = geodetic.geodetic_of_enu(distance_m * math.sin(b), distance_m * math.cos(b), 0.0, origin)
        # about a degree per 111 km on an earth of mean radius 6371 km; the ellipsoid adds up to 1 %
        angle = float(geodetic.vertical_angle_deg(lat, lon, origin))
        assert angle == pytest.approx(expected_deg, rel=0.02)
