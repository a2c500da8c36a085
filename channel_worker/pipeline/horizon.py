"""Horizon synthesis: the sky and the flat earth plane behind every feature."""

from __future__ import annotations

import numpy as np

from ._horizon_kernels import horizon_kernel
from .project import screen_mapping
from .types import Database, SampleBuffer, View

#: An eye at or below the earth plane is treated as this high above it (metres), so the picture
#: stays defined (earth below the horizon line) instead of flipping or dividing by zero.
MIN_HEIGHT_ABOVE_EARTH = 0.01


def synthesize_horizon(database: Database, view: View, offsets: np.ndarray) -> SampleBuffer:
    """A new sample buffer with every sample set to sky or earth.

    The earth is an infinite plane at database.earth_height; its horizon is where the ray's world
    z component changes sign, which is a straight line on the screen at any roll. Samples keep
    1/z = 0 so that any polygon in front passes the depth test.
    """
    h, w, s = view.height, view.width, offsets.shape[0]
    colour = np.empty((h, w, s, 3), np.float32)
    inv_z = np.empty((h, w, s), np.float32)
    feature = np.empty((h, w, s), np.int32)
    kx, ky, k0 = earth_dz_screen(view)
    horizon_kernel(offsets, kx, ky, k0, database.sky_colour, database.earth_colour, colour,
                   inv_z, feature)
    return SampleBuffer(colour=colour, inv_z=inv_z, feature=feature, offsets=offsets)


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
