"""WGS-84 -> ECEF -> ENU in float64."""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.rig import geodetic


def test_ecef_of_known_points():
    np.testing.assert_allclose(geodetic.ecef(np.array(0.0), np.array(0.0), np.array(0.0)), [6378137.0, 0.0, 0.0])
    np.testing.assert_allclose(geodetic.ecef(np.array(90.0), np.array(0.0), np.array(0.0)),
                               [0.0, 0.0, 6356752.314245], atol=1e-6)  # the polar radius
    np.testing.assert_allclose(geodetic.ecef(np.array(0.0), np.array(90.0), np.array(100.0)),
                               [0.0, 6378237.0, 0.0], atol=1e-6)


def test_enu_axes_point_east_north_up():
    origin = (47.0, 8.0, 500.0)
    east = geodetic.enu(np.array([47.0]), np.array([8.001]), np.array([500.0]), origin)[0]
    north = geodetic.enu(np.array([47.001]), np.array([8.0]), np.array([500.0]), origin)[0]
    up = geodetic.enu(np.array([47.0]), np.array([8.0]), np.array([600.0]), origin)[0]
    assert east[0] == pytest.approx(76.0, rel=0.01) and abs(east[1]) < 0.01  # 0.001 deg * 111 km * cos 47
    assert north[1] == pytest.approx(111.2, rel=0.01) and abs(north[0]) < 1e-6
    np.testing.assert_allclose(up, [0.0, 0.0, 100.0], atol=1e-6)
    np.testing.assert_array_equal(geodetic.enu(np.array([47.0]), np.array([8.0]), np.array([500.0]), origin), 0.0)


def test_distances_are_preserved_and_the_earth_curves_away():
    origin = (-33.9, 151.2, 0.0)
    # 10 km due north along the ellipsoid: the chord is the distance, and the far point drops
    # below the local horizontal by about d^2 / (2 R).
    lat = -33.9 + 10_000.0 / 110_900.0
    p = geodetic.enu(np.array([lat]), np.array([151.2]), np.array([0.0]), origin)[0]
    assert math.hypot(p[1], p[2]) == pytest.approx(10_000.0, rel=2e-3)
    assert p[2] == pytest.approx(-10_000.0 ** 2 / (2 * 6_371_000.0), rel=0.02)


def test_float64_keeps_millimetres_far_from_the_origin():
    origin = (45.0, 7.0, 0.0)
    a = geodetic.enu(np.array([45.5]), np.array([7.5]), np.array([1000.0]), origin)[0]
    b = geodetic.enu(np.array([45.5]), np.array([7.5]), np.array([1000.001]), origin)[0]
    assert np.linalg.norm(b - a) == pytest.approx(0.001, abs=1e-6)
    assert a.dtype == np.float64


@pytest.mark.parametrize("origin", [(47.0, 8.0, 500.0), (89.9, 10.0, 0.0), (-89.5, -120.0, 2000.0),
                                    (0.0, 179.9, -50.0)])
def test_enu_to_geodetic_round_trip_to_1000_km(origin):
    rng = np.random.default_rng(11)
    east = np.concatenate([[0.0, 1e6, 0.0, -1e6], rng.uniform(-1e6, 1e6, 200)])
    north = np.concatenate([[0.0, 0.0, 1e6, -7e5], rng.uniform(-1e6, 1e6, 200)])
    up = np.concatenate([[0.0, -78e3, -78e3, 5.0], rng.uniform(-1e5, 1e4, 200)])
    lat, lon, h = geodetic.geodetic_of_enu(east, north, up, origin)
    assert np.all(np.abs(lat) <= 90.0)
    back = geodetic.enu(lat, lon, h, origin)
    np.testing.assert_allclose(back, np.stack([east, north, up], axis=-1), atol=1e-6)  # a micrometre
    assert lat[0] == pytest.approx(origin[0], abs=1e-12) and h[0] == pytest.approx(origin[2], abs=1e-6)


def test_geodetic_of_ecef_at_the_poles_and_the_equator():
    lat, lon, h = geodetic.geodetic_of_ecef(np.array([[0.0, 0.0, 6356752.314245 + 10.0],
                                                      [0.0, 0.0, -6356752.314245],
                                                      [6378137.0, 0.0, 0.0]]))
    np.testing.assert_allclose(lat, [90.0, -90.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(h, [10.0, 0.0, 0.0], atol=1e-6)
    assert lon[2] == 0.0
