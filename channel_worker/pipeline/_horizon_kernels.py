"""numba kernel for horizon synthesis (see horizon.py)."""

from __future__ import annotations

from numba import njit, prange

from .types import EARTH_ID, SKY_ID


@njit(cache=True, parallel=True)
def horizon_kernel(offsets, kx, ky, k0, sky, earth, out_colour, out_inv_z, out_feature):
    """Fill every sample with sky or earth, the background that polygons are drawn over.

    The world-z component of a sample's ray is affine on the screen, dz = kx sx + ky sy + k0;
    a sample sees the earth when its ray descends (dz < 0). The eye is always above the plane
    (horizon.MIN_HEIGHT_ABOVE_EARTH).
    """
    h, w, s_count = out_inv_z.shape
    for y in prange(h):
        for s in range(s_count):
            row = ky * (y + offsets[s, 1]) + k0
            ox = offsets[s, 0]
            for x in range(w):
                out_inv_z[y, x, s] = 0.0
                if kx * (x + ox) + row < 0.0:
                    out_feature[y, x, s] = EARTH_ID
                    out_colour[y, x, s, 0] = earth[0]
                    out_colour[y, x, s, 1] = earth[1]
                    out_colour[y, x, s, 2] = earth[2]
                else:
                    out_feature[y, x, s] = SKY_ID
                    out_colour[y, x, s, 0] = sky[0]
                    out_colour[y, x, s, 1] = sky[1]
                    out_colour[y, x, s, 2] = sky[2]
