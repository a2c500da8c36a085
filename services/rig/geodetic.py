"""WGS-84 geodetic positions to the world's local east-north-up frame, in float64.

geodetic (latitude, longitude, height above the ellipsoid) -> ECEF (earth-centred,
earth-fixed) -> ENU: east, north, up metres from a reference point, the world frame of
docs/conventions.md (x east, y north, z up). Up is the ellipsoid normal at the reference,
so a flight 50 km away sits lower than its height says (the earth curves away by about
200 m there), as it would be seen from the reference.
"""

from __future__ import annotations

import math

import numpy as np

#: WGS-84 semi-major axis, metres, and flattening.
A_M = 6378137.0
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)  # first eccentricity squared


def ecef(lat_deg: np.ndarray, lon_deg: np.ndarray, h_m: np.ndarray) -> np.ndarray:
    """(n, 3) earth-centred, earth-fixed positions, metres, of geodetic WGS-84 positions."""
    lat, lon = np.radians(np.asarray(lat_deg, np.float64)), np.radians(np.asarray(lon_deg, np.float64))
    h = np.asarray(h_m, np.float64)
    n = A_M / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)  # prime vertical radius of curvature
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon),
                     (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - E2) + h) * np.sin(lat)], axis=-1)


def enu(lat_deg: np.ndarray, lon_deg: np.ndarray, h_m: np.ndarray,
        origin: tuple[float, float, float]) -> np.ndarray:
    """(n, 3) float64 east, north, up metres of geodetic positions from origin (lat, lon, h).

    Args:
        lat_deg, lon_deg: WGS-84 latitude and longitude, degrees.
        h_m: height above the ellipsoid, metres (a height above mean sea level gives the same
            positions relative to an origin given in it, within the geoid's slope).
        origin: the reference point (latitude deg, longitude deg, height m): (0, 0, 0) in ENU.
    """
    lat0, lon0 = np.radians(origin[0]), np.radians(origin[1])
    d = ecef(lat_deg, lon_deg, h_m) - ecef(np.array(origin[0]), np.array(origin[1]), np.array(origin[2]))
    sl, cl, sp, cp = np.sin(lon0), np.cos(lon0), np.sin(lat0), np.cos(lat0)
    rot = np.array([[-sl, cl, 0.0],
                    [-sp * cl, -sp * sl, cp],
                    [cp * cl, cp * sl, sp]])
    return d @ rot.T


def _enu_rotation(origin: tuple[float, float, float]) -> np.ndarray:
    """Rows: the east, north and up unit vectors of origin, in ECEF."""
    lat0, lon0 = np.radians(origin[0]), np.radians(origin[1])
    sl, cl, sp, cp = np.sin(lon0), np.cos(lon0), np.sin(lat0), np.cos(lat0)
    return np.array([[-sl, cl, 0.0],
                     [-sp * cl, -sp * sl, cp],
                     [cp * cl, cp * sl, sp]])


def geodetic_of_ecef(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WGS-84 (latitude deg, longitude deg, height m) of (..., 3) ECEF positions, metres.

    Fixed-point iteration on the latitude, lat = atan2(z + e^2 N(lat) sin(lat), p), which
    contracts by about e^2 (0.0067) per step: six steps reach 1e-13 rad (under a micrometre) from
    the geocentric start anywhere above a few km of the earth's centre. The height uses
    h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2 lat), which, unlike p / cos(lat) - N,
    stays exact at the poles (p = 0).
    """
    xyz = np.asarray(xyz, np.float64)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - E2))
    for _ in range(6):
        n = A_M / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
        lat = np.arctan2(z + E2 * n * np.sin(lat), p)
    h = p * np.cos(lat) + z * np.sin(lat) - A_M * np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return np.degrees(lat), np.degrees(np.arctan2(y, x)), h


def geodetic_of_enu(east_m: np.ndarray, north_m: np.ndarray, up_m: np.ndarray,
                    origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of enu(): WGS-84 (latitude deg, longitude deg, height m) of ENU positions.

    Args:
        east_m, north_m, up_m: metres from origin along its east, north and up (ellipsoid normal).
        origin: the reference point (latitude deg, longitude deg, height m).
    """
    local = np.stack(np.broadcast_arrays(np.asarray(east_m, np.float64), np.asarray(north_m, np.float64),
                                         np.asarray(up_m, np.float64)), axis=-1)
    o = ecef(np.array(origin[0]), np.array(origin[1]), np.array(origin[2]))
    return geodetic_of_ecef(local @ _enu_rotation(origin) + o)


def enu_rotation(lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations from ECEF to the east-north-up frame at each geodetic position.

    The rows are the east, north and up unit vectors at (lat, lon) in ECEF, so `R @ v` gives
    the east, north, up components of an ECEF vector v and `R.T @ w` takes local ENU back to
    ECEF. Up is the ellipsoid normal, whose elevation is the geodetic latitude; the height
    does not change the directions.

    Args:
        lat_deg, lon_deg: WGS-84 latitude and longitude, degrees (any broadcastable shapes).
    """
    lat, lon = np.broadcast_arrays(np.radians(np.asarray(lat_deg, np.float64)),
                                   np.radians(np.asarray(lon_deg, np.float64)))
    sl, cl, sp, cp = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    return np.stack([np.stack([-sl, cl, np.zeros_like(sl)], axis=-1),
                     np.stack([-sp * cl, -sp * sl, cp], axis=-1),
                     np.stack([cp * cl, cp * sl, sp], axis=-1)], axis=-2)


def vertical_angle_deg(lat_deg: np.ndarray, lon_deg: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """Angle, degrees, between the local vertical (ellipsoid normal) at each position and at origin.

    This is how far an attitude measured against the local horizontal at the position is tilted
    in the world frame of origin: about 1 degree per 111 km (5.4 degrees at 600 km).
    atan2(|a x b|, a . b) rather than acos(a . b), which loses all precision near 0.

    Args:
        lat_deg, lon_deg: WGS-84 latitude and longitude of the positions, degrees.
        origin: the reference point (latitude deg, longitude deg, height m).
    """
    up = enu_rotation(lat_deg, lon_deg)[..., 2, :]
    up0 = enu_rotation(np.array(origin[0]), np.array(origin[1]))[2]
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(up, up0), axis=-1), up @ up0))


# One point at a time, in scalars: the same formulas as ecef / enu_rotation / geodetic_of_ecef
# above (tests/host_sim/cigi/test_geometry.py holds them equal), for callers converting a point
# or two per message (a CIGI host's ownship and requests), where numpy's per-call overhead was
# most of the cost.

def ecef_point(lat_deg: float, lon_deg: float, h_m: float) -> tuple[np.ndarray, np.ndarray]:
    """ECEF position (3,) of one geodetic point and its ECEF -> local east-north-up rotation (3, 3)."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    sp, cp, sl, cl = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    n = A_M / math.sqrt(1.0 - E2 * sp * sp)  # prime vertical radius of curvature
    here = np.array([(n + h_m) * cp * cl, (n + h_m) * cp * sl, (n * (1.0 - E2) + h_m) * sp])
    return here, np.array([[-sl, cl, 0.0], [-sp * cl, -sp * sl, cp], [cp * cl, cp * sl, sp]])


def height_of_ecef_point(x: float, y: float, z: float) -> float:
    """WGS-84 height, metres, of one ECEF point (geodetic_of_ecef's iteration)."""
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1.0 - E2))
    for _ in range(6):
        n = A_M / math.sqrt(1.0 - E2 * math.sin(lat) ** 2)
        lat = math.atan2(z + E2 * n * math.sin(lat), p)
    return p * math.cos(lat) + z * math.sin(lat) - A_M * math.sqrt(1.0 - E2 * math.sin(lat) ** 2)

