"""numba kernels of the cloud scan (clouds.py): the coarse cloud image (JP H07-76990's
cloud frame buffer) and the finer samples of its quads where a cloud's edge crosses them, both
in the CLOUD_CHANNELS layout of _groups.py and both radial scans of the cloud grid, one per
column of rays (_walk); and the marking of the quads to sample finer (edge_quads_kernel,
seam_quads_kernel).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import F_ON, F_WORLD_AXIS
from channel_worker.pipeline.fog.fog import fog_blend
from channel_worker.pipeline.jit import claim, lanes, new_queue

from ._cast_kernels import ground_ray_span
from ._groups import CLOUD_CHANNELS
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
    columns.row_tan[i]) through the clouds front to back (_walk).

    Args:
        slabs: the cloud database (CloudSlabs).
        columns: the coarse columns and rows (CloudColumns).
        eye: (3,) float64 the eye's x and y relative to node (0, 0) and its world z, metres.
        r_far: ground range beyond which nothing is scanned, metres.
        air: the frame's air array (haze, then fog; contract.py).
        out: (ncols, nrows, CLOUD_CHANNELS) float32 the cloud texels.
    """
    nrows = columns.row_tan.shape[0]
    shaded = np.ones(nrows, np.bool_)
    for j in prange(columns.ncols):
        phi = columns.phi_lo + (j + 0.5) * columns.dphi
        texels = np.empty((nrows, CLOUD_CHANNELS), np.float32)
        _walk(slabs, phi, columns.row_tan, columns.row_inv_cos, columns.row_sin, shaded, eye,
              r_far, air, texels)
        out[j, :, :] = texels


#: Fewer fine columns than this in a round of refine_clouds_kernel run on the calling thread:
#: waking the pool costs more than they do. Measured (one fine column about 14 us on one
#: core): on a loaded 2-core machine each parallel launch took 15 ms, even for the 18 fine
#: columns of a seam round of 2 quads (0.06 ms on one thread); the seam rounds are that small.
_PARALLEL_WALKS = 128


@njit(cache=True, parallel=True)
def refine_clouds_kernel(slabs, quads, eye, r_far, air, threads, out):
    """The fine samples of the quads clouds.edge_quads chose: (factor + 1)^2 rays over each
    quad, its corners the coarse texel centres. The quads sharing a column are scanned
    together, one radial scan (_walk) per fine column carrying the fine rows of all of them.

    Args:
        slabs: the cloud database (CloudSlabs).
        quads: the quads to refine (CloudQuads).
        eye: (3,) float64 the eye's x and y relative to node (0, 0) and its world z, metres.
        r_far: ground range beyond which nothing is scanned, metres.
        air: the frame's air array (haze, then fog; contract.py).
        threads: numba.get_num_threads() (jit.lanes).
        out: (quads, factor + 1, factor + 1, CLOUD_CHANNELS) float32: out[t, a, b] is quad
            t's sample a / factor of a texel right of and b / factor above its corner texel.
    """
    n_walks = quads.col.shape[0] * (quads.factor + 1)
    if n_walks < _PARALLEL_WALKS:
        for w in range(n_walks):
            _fine_column(slabs, quads, eye, r_far, air, w, out)
        return
    # Fine columns from a queue (jit.lanes): a column holding more edge quads costs more.
    n_lanes = lanes(threads, n_walks)
    queue = new_queue()
    for _lane in prange(n_lanes):
        while True:
            w = claim(queue)
            if w >= n_walks:
                break
            _fine_column(slabs, quads, eye, r_far, air, w, out)


@njit(cache=True)
def _fine_column(slabs, quads, eye, r_far, air, w, out):
    """Fine column w of refine_clouds_kernel: fine column a = w mod (factor + 1) of the quads
    of group g = w div (factor + 1), all their fine rows in one radial scan."""
    f = quads.factor
    g = w // (f + 1)
    a = w % (f + 1)
    t0 = quads.start[g]
    n = (quads.start[g + 1] - t0) * (f + 1)
    # The group's fine rows, bottom to top (its quads' rows ascend): ascending tangents.
    tan = np.empty(n)
    inv_cos = np.empty(n)
    sin = np.empty(n)
    shaded = np.empty(n, np.bool_)
    for k in range(n):
        t = t0 + k // (f + 1)
        b = k % (f + 1)
        tan[k] = quads.row_tan[quads.row[t], b]
        inv_cos[k] = quads.row_inv_cos[quads.row[t], b]
        sin[k] = quads.row_sin[quads.row[t], b]
        shaded[k] = quads.shaded[t]
    phi = quads.phi_lo + (quads.col[g] + a / f + 0.5) * quads.dphi  # guard: clouds.REFINE >= 1
    texels = np.empty((n, CLOUD_CHANNELS), np.float32)
    _walk(slabs, phi, tan, inv_cos, sin, shaded, eye, r_far, air, texels)
    for k in range(n):
        out[t0 + k // (f + 1), a, k % (f + 1), :] = texels[k]


@njit(cache=True)
def edge_quads_kernel(texels, full, contrast, out):
    """Mark in out (ncols, nrows bool) the quads (CloudImage) whose four corner texels'
    opacities differ by more than contrast. Quads past the last row, or past the last column
    unless the columns wrap (full), are left unmarked."""
    ncols = texels.shape[0]
    nrows = texels.shape[1]
    out[:, :] = False
    for c in range(ncols if full else ncols - 1):
        c1 = (c + 1) % ncols
        for r in range(nrows - 1):
            v00 = texels[c, r, 3]
            v10 = texels[c1, r, 3]
            v01 = texels[c, r + 1, 3]
            v11 = texels[c1, r + 1, 3]
            out[c, r] = (max(max(v00, v10), max(v01, v11)) - min(min(v00, v10), min(v01, v11))
                         > contrast)


@njit(cache=True)
def seam_quads_kernel(texels, full, quad, cols, rows, fine, contrast, out):
    """Mark in out (ncols, nrows bool) the quads not refined yet (quad -1) beside the refined
    quads (cols, rows; samples fine, CloudImage.fine) whose shared side the fine samples show
    differs in opacity by more than contrast from what the neighbour reads there: the linear
    blend of the side's two corner texels."""
    ncols = texels.shape[0]
    nrows = texels.shape[1]
    f = fine.shape[1] - 1
    inv_f = 1.0 / f  # guard: clouds.REFINE >= 1
    out[:, :] = False
    for t in range(cols.shape[0]):
        c = cols[t]
        r = rows[t]
        c1 = (c + 1) % ncols  # a refined quad has its right column (wrapping if full)
        # Sides left, right, below, above: the neighbour (nc, nr), the side's corner texels
        # (ca, ra) and (cb, rb), and its fine samples fine[t, a0 + k da, b0 + k db].
        for side in range(4):
            if side == 0:
                nc, nr, ca, ra, cb, rb, a0, b0, da, db = c - 1, r, c, r, c, r + 1, 0, 0, 0, 1
            elif side == 1:
                nc, nr, ca, ra, cb, rb, a0, b0, da, db = c + 1, r, c1, r, c1, r + 1, f, 0, 0, 1
            elif side == 2:
                nc, nr, ca, ra, cb, rb, a0, b0, da, db = c, r - 1, c, r, c1, r, 0, 0, 1, 0
            else:
                nc, nr, ca, ra, cb, rb, a0, b0, da, db = c, r + 1, c, r + 1, c1, r + 1, 0, f, 1, 0
            if full:
                nc = nc % ncols
            elif nc < 0 or nc >= ncols - 1:
                continue
            if nr < 0 or nr >= nrows - 1 or quad[nc, nr] >= 0 or out[nc, nr]:
                continue
            for k in range(f + 1):
                w = k * inv_f
                coarse = (1.0 - w) * texels[ca, ra, 3] + w * texels[cb, rb, 3]
                if abs(fine[t, a0 + k * da, b0 + k * db, 3] - coarse) > contrast:
                    out[nc, nr] = True
                    break


@njit(cache=True)
def _walk(slabs, phi, row_tan, row_inv_cos, row_sin, shaded, eye, r_far, air, out):
    """One radial scan across the cloud grid at azimuth phi, integrating the ray of every row
    (elevation tangent row_tan[i], ascending) through the clouds front to back into out[i]
    (the CLOUD_CHANNELS layout; the colour left 0 where shaded[i] is False: the haze and fog
    on every cloud a ray crosses are most of a walk's cost).

    The slab (base, top) and the density are the bilinear interpolation of the cell's nodes
    (scene/atmosphere.Clouds), taken at both ends of the ray's ground segment across a cell
    and linear between them, so they are continuous along the ray and a cloud's outline has
    no step where its rays cross from one cell into the next (one flat slab per crossing,
    sampled at its middle, puts walls at the cells' edges: 1.2-pixel steps on the 400 m cells
    of test_cloud_edges' bank). In each cell only the rows whose rays can pass through the
    slab are visited (_rows_in_slab), and the scan ends where every ray is opaque or has left
    the heights any cloud reaches (_band_end).
    """
    base = slabs.base
    top = slabs.top
    density = slabs.density
    cell = slabs.cell
    ny = base.shape[0] - 1
    nx = base.shape[1] - 1
    nrows = row_tan.shape[0]
    extent_x = nx * cell
    extent_y = ny * cell
    ex, ey, ez = eye[0], eye[1], eye[2]
    inv_cell = 1.0 / cell  # guard: the scene parser requires cell_m >= 1
    dx = math.sin(phi)
    dy = math.cos(phi)
    trans = np.ones(nrows)
    acc = np.zeros((nrows, 3))
    entry = np.full(nrows, np.inf)
    # The column's rays' fog-axis cosine is ax_h cos(elevation) + ax_z sin(elevation).
    ax_h = air[F_WORLD_AXIS] * dx + air[F_WORLD_AXIS + 1] * dy
    ax_z = air[F_WORLD_AXIS + 2]
    r_lo, r_hi = ground_ray_span(ex, ey, dx, dy, extent_x, extent_y, 0.0, r_far)
    # Past r_end no ray meets cloud (the cell that holds it is still taken whole).
    r_end = _band_end(row_tan, ez - slabs.z_min, ez - slabs.z_max)
    inv_dx = 1.0 / dx if dx != 0.0 else 0.0  # guard: that family of lines is never crossed
    inv_dy = 1.0 / dy if dy != 0.0 else 0.0
    r = r_lo
    open_rows = nrows
    while r < min(r_hi, r_end) and open_rows > 0:
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
            # The slab at the segment's two ends (bilinear in the cell, so the same where two
            # cells meet), linear between them.
            u0 = min(max((ex + r * dx) * inv_cell - ix, 0.0), 1.0)
            v0 = min(max((ey + r * dy) * inv_cell - iy, 0.0), 1.0)
            u1 = min(max((ex + r_next * dx) * inv_cell - ix, 0.0), 1.0)
            v1 = min(max((ey + r_next * dy) * inv_cell - iy, 0.0), 1.0)
            b0 = _bilinear(base, iy, ix, u0, v0) - ez
            b1 = _bilinear(base, iy, ix, u1, v1) - ez
            t0 = _bilinear(top, iy, ix, u0, v0) - ez
            t1 = _bilinear(top, iy, ix, u1, v1) - ez
            s0 = _bilinear(density, iy, ix, u0, v0)
            s1 = _bilinear(density, iy, ix, u1, v1)
            if max(t0, t1) > min(b0, b1) and max(s0, s1) > 0.0:
                inv_len = 1.0 / (r_next - r)  # guard: r_next > r
                kb = (b1 - b0) * inv_len  # slopes per metre of ground range
                kt = (t1 - t0) * inv_len
                ks = (s1 - s0) * inv_len
                i0, i1 = _rows_in_slab(row_tan, min(b0, b1), max(t0, t1), r, r_next)
                for i in range(i0, i1):
                    if trans[i] < _OPAQUE_T:
                        continue
                    tn = row_tan[i]
                    # Ground range over which the ray's height s tn lies above the base
                    # (tn - kb) s >= b0 - kb r and below the top (kt - tn) s >= kt r - t0.
                    lo, hi = _at_least(tn - kb, b0 - kb * r, r, r_next)
                    lo, hi = _at_least(kt - tn, kt * r - t0, lo, hi)
                    if hi <= lo:
                        continue
                    depth = 0.5 * ((s0 + ks * (lo - r)) + (s0 + ks * (hi - r))) * (hi - lo)
                    if depth <= 0.0:
                        continue
                    # Guard: row_inv_cos is finite (texel centres stop short of +-90 deg).
                    a = -math.expm1(-depth * row_inv_cos[i])
                    rng = lo * row_inv_cos[i]
                    if entry[i] == np.inf:
                        entry[i] = rng
                    if shaded[i]:
                        cr, cg, cb = _cloud_colour(slabs, air, ax_h, ax_z, row_sin[i], rng,
                                                   lo * tn, b0 + kb * (lo - r), t0 + kt * (lo - r))
                        w = trans[i] * a
                        acc[i, 0] += w * cr
                        acc[i, 1] += w * cg
                        acc[i, 2] += w * cb
                    trans[i] *= 1.0 - a
                    if trans[i] < _OPAQUE_T:
                        open_rows -= 1
        r = r_next
    for i in range(nrows):
        out[i, 0] = acc[i, 0]
        out[i, 1] = acc[i, 1]
        out[i, 2] = acc[i, 2]
        out[i, 3] = 1.0 - trans[i]
        out[i, 4] = entry[i]


@njit(cache=True, inline="always")
def _cloud_colour(slabs, air, ax_h, ax_z, sn, rng, z, b, t):
    """Linear RGB of the cloud a ray (elevation sine sn) enters at range rng (metres) and
    height z, between the slab's base b and top t there (metres relative to the eye), seen
    through the haze and the fog (air; ax_h, ax_z: _walk's fog-axis terms)."""
    colour = slabs.colour
    base_shade = slabs.base_shade
    # Lit from above: the base is darker than the top.
    up = min(max((z - b) / (t - b), 0.0), 1.0) if t > b else 1.0  # guard: t > b
    shade = base_shade + (1.0 - base_shade) * up
    cr = colour[0] * shade
    cg = colour[1] * shade
    cb = colour[2] * shade
    if air[0] != 0.0:
        hz = haze_amount(air, rng, sn)
        cr = cr * (1.0 - hz) + air[3] * hz
        cg = cg * (1.0 - hz) + air[4] * hz
        cb = cb * (1.0 - hz) + air[5] * hz
    if air[F_ON] != 0.0:
        cos_ax = ax_h * math.sqrt(max(1.0 - sn * sn, 0.0)) + ax_z * sn
        cr, cg, cb = fog_blend(air, rng, cos_ax, cr, cg, cb)
    return cr, cg, cb


@njit(cache=True, inline="always")
def _at_least(slope, bound, lo, hi):
    """The part of ground ranges lo .. hi where slope s >= bound (empty: hi <= lo)."""
    if slope > 0.0:
        return max(lo, bound / slope), hi  # guard: slope > 0
    if slope < 0.0:
        return lo, min(hi, bound / slope)  # guard: slope < 0
    return (lo, hi) if bound <= 0.0 else (lo, lo)


#: Relative widening of _rows_in_slab's interval: far above the rounding of the exact test
#: each row still gets (_at_least), so no row that test keeps is left out.
_SLAB_MARGIN = 1e-9


@njit(cache=True, inline="always")
def _rows_in_slab(row_tan, b, t, r, r_next):
    """The rows i0 .. i1 - 1 (row_tan ascending) whose rays can lie between heights b and t
    (metres relative to the eye, b < t) somewhere over ground ranges r .. r_next (0 <= r <
    r_next): a ray of tangent tn is at height s tn at range s, so over the segment it spans
    [r tn, r_next tn] (tn >= 0) or [r_next tn, r tn], and the tangents that meet [b, t] form
    one interval."""
    # Lowest tangent: reaches b at the segment's far end (b >= 0), or at its near end.
    if b >= 0.0:
        lo = b / r_next  # guard: r_next > r >= 0
    elif r > 0.0:
        lo = b / r
    else:
        lo = -math.inf  # the eye's cell: every downward ray starts at height 0 > b
    # Highest tangent: still at or below t at the near end (t >= 0), or at the far end.
    if t < 0.0:
        hi = t / r_next
    elif r > 0.0:
        hi = t / r
    else:
        hi = math.inf
    lo -= _SLAB_MARGIN * abs(lo) + 1e-300
    hi += _SLAB_MARGIN * abs(hi) + 1e-300
    return np.searchsorted(row_tan, lo), np.searchsorted(row_tan, hi, side="right")


@njit(cache=True, inline="always")
def _band_end(row_tan, above_low, above_high):
    """Ground range past which no row's ray lies between the lowest cloud base and the
    highest cloud top (the eye above them by above_low and above_high metres): a rising ray
    leaves through the highest top, a sinking one through the lowest base, a level one never
    if the eye is between them."""
    end = 0.0
    for i in range(row_tan.shape[0]):
        tn = row_tan[i]
        if tn > 0.0:
            leave = -above_high / tn  # guard: tn > 0
        elif tn < 0.0:
            leave = -above_low / tn  # guard: tn < 0
        else:
            leave = math.inf if above_high <= 0.0 <= above_low else 0.0
        end = max(end, leave)
    return end
