"""numba kernel for the box resolve (see resolve.py)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .types import EARTH_ID, SKY_ID


@njit(cache=True, parallel=True)
def box_resolve_kernel(colour, inv_z, feature, tx, ty, dz_row, height_above, out_rgb, out_range):
    """Average the samples of each pixel; range is that of the nearest sample in the pixel.

    tx[x, s], ty[y, s]: the eye-space ray (tx, ty, 1) of sample s of pixel column x / row y.
    Range along a ray: a polygon at 1/z = iz is at |(tx, ty, 1)| / iz (iz > 0: polygons are
    clipped to z >= near); the earth is where the ray meets the plane height_above below the
    eye, |(tx, ty, 1)| * height_above / -dz (dz < 0 for every earth sample, as the horizon
    stage decided); the sky is at +inf.
    """
    h, w, s_count = inv_z.shape
    inv_s = np.float32(1.0 / s_count)
    for y in prange(h):
        for x in range(w):
            r = np.float32(0.0)
            g = np.float32(0.0)
            b = np.float32(0.0)
            nearest = np.inf
            for s in range(s_count):
                r += colour[y, x, s, 0]
                g += colour[y, x, s, 1]
                b += colour[y, x, s, 2]
                f = feature[y, x, s]
                if f == SKY_ID:
                    continue
                a = tx[x, s]
                c = ty[y, s]
                norm = math.sqrt(a * a + c * c + 1.0)
                if f == EARTH_ID:
                    dist = norm * height_above / -(dz_row[0] * a + dz_row[1] * c + dz_row[2])
                else:
                    dist = norm / inv_z[y, x, s]
                nearest = min(nearest, dist)
            out_rgb[y, x, 0] = r * inv_s
            out_rgb[y, x, 1] = g * inv_s
            out_rgb[y, x, 2] = b * inv_s
            out_range[y, x] = nearest
