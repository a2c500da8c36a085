"""numba kernel of the cloud scan (clouds.py): the coarse cloud image (JP H07-76990's
cloud frame buffer), in the CLOUD_CHANNELS layout of _groups.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import F_ON, F_WORLD_AXIS
from channel_worker.pipeline.fog.fog import fog_blend

from ._cast_kernels import ground_ray_span
from .haze import haze_amount

#: A ray that has kept less than this of its light is opaque: its row stops integrating.
_OPAQUE_T = 0.004


@njit(cache=True, inline="always")
def _bilinear(a, iy, ix, u, v):
    """Node grid a interpolated at local point (u, v) of cell (iy, ix)."""
    return ((1.0 - v) * ((1.0 - u) * a[iy, ix] + u * a[iy, ix + 1])
            + v * ((1.0 - u) * a[iy + 1, ix] + u * a[iy + 1, ix + 1]))


@njit(cache=True, parallel=True)
def scan_clouds_kernel(slabs, columns, eye, r_far, air, out):
    """One radial scan across the cloud grid per coarse column (azimuth columns.phi_lo +
    (j + 1/2) columns.dphi), integrating every coarse row's ray (elevation tangent
    columns.row_tan[i]) through the clouds front to back.

    Inside a cell the slab (base, top) and the density are the bilinear interpolation of the
    cell's nodes, taken at the middle of the ray's ground segment across the cell (the data
    are coarse and smooth; JP H07-76990 wants blurry clouds with translucent edges).

    Args:
        slabs: the cloud database (CloudSlabs).
        columns: the coarse columns and rows (CloudColumns).
        eye: (3,) float64 the eye's x and y relative to node (0, 0) and its world z, metres.
        r_far: ground range beyond which nothing is scanned, metres.
        air: the frame's air array (haze, then fog; contract.py).
        out: (ncols, nrows, CLOUD_CHANNELS) float32 the cloud texels.
    """
    base = slabs.base
    top = slabs.top
    density = slabs.density
    cell = slabs.cell
    colour = slabs.colour
    base_shade = slabs.base_shade
    phi_lo = columns.phi_lo
    dphi = columns.dphi
    row_tan = columns.row_tan
    row_inv_cos = columns.row_inv_cos
    row_sin = columns.row_sin
    ny = base.shape[0] - 1
    nx = base.shape[1] - 1
    nrows = row_tan.shape[0]
    extent_x = nx * cell
    extent_y = ny * cell
    ex, ey, ez = eye[0], eye[1], eye[2]
    inv_cell = 1.0 / cell  # guard: the scene parser requires cell_m >= 1
    for j in prange(columns.ncols):
        phi = phi_lo + (j + 0.5) * dphi
        dx = math.sin(phi)
        dy = math.cos(phi)
        trans = np.ones(nrows)
        acc = np.zeros((nrows, 3))
        entry = np.full(nrows, np.inf)
        # The column's rays' fog-axis cosine is ax_h cos(elevation) + ax_z sin(elevation).
        ax_h = air[F_WORLD_AXIS] * dx + air[F_WORLD_AXIS + 1] * dy
        ax_z = air[F_WORLD_AXIS + 2]
        r_lo, r_hi = ground_ray_span(ex, ey, dx, dy, extent_x, extent_y, 0.0, r_far)
        inv_dx = 1.0 / dx if dx != 0.0 else 0.0  # guard: that family of lines is never crossed
        inv_dy = 1.0 / dy if dy != 0.0 else 0.0
        r = r_lo
        open_rows = nrows
        while r < r_hi and open_rows > 0:
            q = r + 1e-7 * cell + 1e-12 * r
            ix = min(max(int(math.floor((ex + q * dx) * inv_cell)), 0), nx - 1)
            iy = min(max(int(math.floor((ey + q * dy) * inv_cell)), 0), ny - 1)
            tx = math.inf
            ty = math.inf
            if dx > 0.0:
                tx = ((ix + 1) * cell - ex) * inv_dx
            elif dx < 0.0:
                tx = (ix * cell - ex) * inv_dx
            if dy > 0.0:
                ty = ((iy + 1) * cell - ey) * inv_dy
            elif dy < 0.0:
                ty = (iy * cell - ey) * inv_dy
            r_next = min(min(tx, ty), r_hi)
            if r_next <= r:
                break  # cannot happen (the cell holds a point past r); never loop on rounding
            if (density[iy, ix] > 0.0 or density[iy, ix + 1] > 0.0 or density[iy + 1, ix] > 0.0
                    or density[iy + 1, ix + 1] > 0.0):
                rm = 0.5 * (r + r_next)
                u = min(max((ex + rm * dx) * inv_cell - ix, 0.0), 1.0)
                v = min(max((ey + rm * dy) * inv_cell - iy, 0.0), 1.0)
                b = _bilinear(base, iy, ix, u, v) - ez
                t = _bilinear(top, iy, ix, u, v) - ez
                sigma = _bilinear(density, iy, ix, u, v)
                open_rows = 0
                if t > b and sigma > 0.0:
                    for i in range(nrows):
                        if trans[i] < _OPAQUE_T:
                            continue
                        open_rows += 1
                        tn = row_tan[i]
                        # Ground range over which the ray's height r * tn lies inside [b, t].
                        if tn > 1e-12:
                            ra = b / tn
                            rb = t / tn
                        elif tn < -1e-12:
                            ra = t / tn
                            rb = b / tn
                        elif b <= 0.0 <= t:
                            ra = -math.inf
                            rb = math.inf
                        else:
                            continue
                        lo = max(ra, r)
                        hi = min(rb, r_next)
                        if hi <= lo:
                            continue
                        # Guard: row_inv_cos is finite (texel centres stop short of +-90 deg).
                        a = -math.expm1(-sigma * (hi - lo) * row_inv_cos[i])
                        rng = lo * row_inv_cos[i]
                        if entry[i] == np.inf:
                            entry[i] = rng
                        # Lit from above: the base is darker than the top.
                        up = min(max((lo * tn - b) / (t - b), 0.0), 1.0)  # guard: t > b
                        shade = base_shade + (1.0 - base_shade) * up
                        cr = colour[0] * shade
                        cg = colour[1] * shade
                        cb = colour[2] * shade
                        if air[0] != 0.0:
                            hz = haze_amount(air, rng, row_sin[i])
                            cr = cr * (1.0 - hz) + air[3] * hz
                            cg = cg * (1.0 - hz) + air[4] * hz
                            cb = cb * (1.0 - hz) + air[5] * hz
                        if air[F_ON] != 0.0:
                            sn = row_sin[i]
                            cos_ax = ax_h * math.sqrt(max(1.0 - sn * sn, 0.0)) + ax_z * sn
                            cr, cg, cb = fog_blend(air, rng, cos_ax, cr, cg, cb)
                        w = trans[i] * a
                        acc[i, 0] += w * cr
                        acc[i, 1] += w * cg
                        acc[i, 2] += w * cb
                        trans[i] *= 1.0 - a
                else:
                    for i in range(nrows):
                        if trans[i] >= _OPAQUE_T:
                            open_rows += 1
            r = r_next
        for i in range(nrows):
            out[j, i, 0] = acc[i, 0]
            out[j, i, 1] = acc[i, 1]
            out[j, i, 2] = acc[i, 2]
            out[j, i, 3] = 1.0 - trans[i]
            out[j, i, 4] = entry[i]
