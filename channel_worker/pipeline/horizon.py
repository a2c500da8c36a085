"""Horizon geometry: where the flat earth plane meets the sky on the screen.

The earth is an infinite plane at database.earth_height behind every feature; its horizon is
where the world-z component of a sample's ray changes sign, a straight line on the screen at
any roll. The visibility stages give a sample no polygon covers to the earth where that
component is negative, to the sky elsewhere.
"""

from __future__ import annotations

import numpy as np

from .project import screen_mapping
from .types import Database, View

#: An eye at or below the earth plane is treated as this high above it (metres), so the picture
#: stays defined (earth below the horizon line) instead of flipping or dividing by zero.
MIN_HEIGHT_ABOVE_EARTH = 0.01


def earth_dz_row(view: View) -> np.ndarray:
    """(r0, r1, r2): world z of the eye ray (tx, ty, 1) is r0 tx + r1 ty + r2."""
    return np.ascontiguousarray(view.world_to_eye[:, 2])


def earth_dz_screen(view: View) -> tuple[float, float, float]:
    """(kx, ky, k0): world z of the eye ray through screen point (sx, sy) is kx sx + ky sy + k0.

    The ray is (tx, ty, 1) in eye coordinates, with tx, ty affine in sx, sy (project.py).
    """
    r0, r1, r2 = earth_dz_row(view)
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    return r0 / sx_scale, r1 / sy_scale, r2 - r0 * sx_off / sx_scale - r1 * sy_off / sy_scale


def height_above_earth(database: Database, view: View) -> float:
    """Eye height above the earth plane, metres, clamped to MIN_HEIGHT_ABOVE_EARTH."""
    return max(float(view.eye[2]) - database.earth_height, MIN_HEIGHT_ABOVE_EARTH)
