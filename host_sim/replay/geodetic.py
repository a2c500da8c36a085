"""WGS-84 geodetic positions to the world's local east-north-up frame, in float64.

geodetic (latitude, longitude, height above the ellipsoid) -> ECEF (earth-centred,
earth-fixed) -> ENU: east, north, up metres from a reference point, the world frame of
docs/conventions.md (x east, y north, z up). Up is the ellipsoid normal at the reference,
so a flight 50 km away sits lower than its height says (the earth curves away by about
200 m there), as it would be seen from the reference.
"""

from __future__ import annotations

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
