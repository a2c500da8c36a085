"""numba kernel for horizon synthesis (see horizon.py)."""

from __future__ import annotations

from numba import njit, prange

from .types import EARTH_ID, SKY_ID


@njit(cache=True, parallel=True)
def horizon_kernel(offsets, sx_scale, sx_off, sy_scale, sy_off, dz_row,
                   sky, earth, out_colour, out_inv_z, out_feature):
    """Fill every sample with sky or earth, the background that polygons are drawn over.

    dz_row: world-z component of the eye-space ray (tx, ty, 1) as dz = r0 tx + r1 ty + r2.
    A sample sees the earth when its ray descends (dz < 0); the eye is always above the plane
    (horizon.MIN_HEIGHT_ABOVE_EARTH).
    """
    h, w, s_count = out_inv_z.shape
    for y in prange(h):
        for x in range(w):
            for s in range(s_count):
                tx = (x + offsets[s, 0] - sx_off) / sx_scale
                ty = (y + offsets[s, 1] - sy_off) / sy_scale
                dz = dz_row[0] * tx + dz_row[1] * ty + dz_row[2]
                out_inv_z[y, x, s] = 0.0
                if dz < 0.0:
                    out_feature[y, x, s] = EARTH_ID
                    for c in range(3):
                        out_colour[y, x, s, c] = earth[c]
                else:
                    out_feature[y, x, s] = SKY_ID
                    for c in range(3):
                        out_colour[y, x, s, c] = sky[c]
