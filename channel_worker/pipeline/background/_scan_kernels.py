"""numba kernels of the radial column scan (terrain.py): one scan across the ground grid per
pre-image column, integrating what it sees into the column's rows (JP H07-76990).

A column is walked by an exact 2-D DDA over the voxel grid of the wanted level (_scan_column).
Each surface piece rising above the horizon of what was seen so far is a segment in the
column's vertical half-plane, (ground range, height relative to the eye) from its near to its
far end, and is coloured by a _Paint: the voxel's bilinear corner colours between two local
points, or one colour (walls and patterns). _surface and _wall find the part of a segment that
shows; _emit spreads it over the rows it spans.

The per-column and per-segment functions are compiled without reference counting
(jit.borrowing): they take the groups whole, and numba would otherwise count every array of a
group in and out of every call (the scan took half as long again), and they take the voxel
colours alone (_Colours), not the database, because every array passed is a dozen words
copied per call.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import F_ON, F_RGB, F_WORLD_AXIS
from channel_worker.pipeline.fog.fog import fog_depth
from channel_worker.pipeline.jit import borrowing, lanes

from ._groups import PRE_A, PRE_B, PRE_CHANNELS, PRE_G, PRE_IR, PRE_R
from .haze import haze_amount

# Column state (one small array per column, so the helpers can update it in place).
_ROW, _AR, _AG, _AB, _AW, _IR, _TMAX, _IRF = 0, 1, 2, 3, 4, 5, 6, 7
_R1, _Z1, _R2, _Z2 = 8, 9, 10, 11  # the last segment emitted
_TANMAX = 12  # tan of _TMAX, from the point that set it
_AXH = 13  # fog: the column's rays' axis cosine is _AXH cos(elevation) + axis z sin(elevation)
_STATE = 14
#: Columns per parallel task of scan_kernel.
_COLUMN_BLOCK = 16

#: Depth of the skirt down the database's edge (metres): deep enough to reach below any
#: horizon the scan starts from.
_SKIRT_M = 1e7

#: A wall is emitted where two neighbouring voxels' corners disagree by more than this (metres):
#: below it the step is float32 rounding of copies of one value.
_WALL_DZ = 1e-3


class _Colours(NamedTuple):
    """The voxels' colours (VoxelPages.rgb and .lut): all that painting a segment reads of the
    database, so the per-segment functions take two arrays, not the whole database."""

    rgb: np.ndarray
    lut: np.ndarray


class _Paint(NamedTuple):
    """How a segment is coloured: the bilinear corner colours of voxel (vy, vx) of page at the
    local point (u0, v0) + t ((u1, v1) - (u0, v0)) for segment parameter t; or, page < 0,
    the one colour rgb (a wall, a pattern band or top)."""

    page: int
    vy: int
    vx: int
    u0: float
    v0: float
    u1: float
    v1: float
    rgb: tuple


@njit(cache=True, inline="always")
def _finish_row(out, st, grid, air):
    """Write the current row of the column's texels out (nrows, PRE_CHANNELS) from the
    accumulators in st, through the haze and fog, and start the next row."""
    row = int(st[_ROW])
    w = st[_AW]
    r = st[_AR]
    g = st[_AG]
    b = st[_AB]
    ir = st[_IR]
    if (air[0] != 0.0 or air[F_ON] != 0.0) and w > 0.0:
        # The surface's range at the row's centre, or (a row its surface leaves below the
        # centre) that of the surface's far end. Guard: _IRF > 0 once anything was emitted.
        rng = 1.0 / (ir if ir > 0.0 else st[_IRF])
        # The centre's cosine and sine from the grid's table: sin and cos per texel took
        # about 6 % of the scan (perf, demo frame).
        cs = grid.row_cs[row, 0]
        sn = grid.row_cs[row, 1]
        if air[0] != 0.0:
            hz = haze_amount(air, rng, sn)
            # Premultiplied: the haze covers the share w of the texel the terrain covers.
            r = r * (1.0 - hz) + air[3] * hz * w
            g = g * (1.0 - hz) + air[4] * hz * w
            b = b * (1.0 - hz) + air[5] * hz * w
        if air[F_ON] != 0.0:
            t = math.exp(-fog_depth(air, rng, st[_AXH] * cs + air[F_WORLD_AXIS + 2] * sn))
            r = t * r + (1.0 - t) * air[F_RGB] * w
            g = t * g + (1.0 - t) * air[F_RGB + 1] * w
            b = t * b + (1.0 - t) * air[F_RGB + 2] * w
    out[row, PRE_R] = r
    out[row, PRE_G] = g
    out[row, PRE_B] = b
    out[row, PRE_A] = min(w, 1.0)
    out[row, PRE_IR] = ir
    st[_ROW] = row + 1
    st[_AR] = 0.0
    st[_AG] = 0.0
    st[_AB] = 0.0
    st[_AW] = 0.0
    st[_IR] = 0.0
    st[_IRF] = 0.0


@njit(cache=True, inline="always")
def _param_at(ct, sn, seg):
    """Where (0..1) along the segment (r1, z1, r2, z2) the ray at elevation theta (its cosine
    and sine) meets it."""
    r1, z1, r2, z2 = seg
    dr = r2 - r1
    dz = z2 - z1
    den = dr * sn - dz * ct
    # Guard: a ray parallel to the segment (den ~ 0) meets it along its length; its middle
    # stands for it.
    t = (z1 * ct - r1 * sn) / den if abs(den) > 1e-12 * (abs(dr) + abs(dz)) else 0.5
    return min(max(t, 0.0), 1.0)


@njit(cache=True, inline="always")
def _inverse_range_at(ct, sn, seg):
    """1 / distance (1/metres) from the eye to where the ray at elevation theta (its cosine and
    sine) meets the segment (r1, z1, r2, z2)."""
    r1, z1, r2, z2 = seg
    t = _param_at(ct, sn, seg)
    rr = r1 + t * (r2 - r1)
    zz = z1 + t * (z2 - z1)
    # Guard: the eye is kept above the surface (terrain.py), so the distance is > 0.
    return 1.0 / max(math.sqrt(rr * rr + zz * zz), 1e-6)


@njit(cache=True, inline="always")
def _inverse_range_on_line(ct, sn, seg):
    """Signed 1 / distance along the ray at elevation theta (cosine, sine) to the line through
    the segment (r1, z1, r2, z2): (n . u) / (n . p1) with n normal to the line and u the ray's
    direction; negative if the ray meets the line behind the eye. The far end's inverse range
    where the line passes through the eye (n . p1 ~ 0)."""
    r1, z1, r2, z2 = seg
    nr = -(z2 - z1)
    nz = r2 - r1
    c = nr * r1 + nz * z1
    if abs(c) <= 1e-9 * (abs(nr) + abs(nz)) * (abs(r1) + abs(z1) + 1.0):
        return 1.0 / max(math.sqrt(r2 * r2 + z2 * z2), 1e-6)
    return (nr * ct + nz * sn) / c  # guard: |c| is not ~0


@njit(cache=True, inline="always")
def _colour_at(colours, paint, t):
    """Linear colour at parameter t of a segment painted by paint."""
    if paint.page < 0:
        return paint.rgb
    u = paint.u0 + t * (paint.u1 - paint.u0)
    v = paint.v0 + t * (paint.v1 - paint.v0)
    return _voxel_rgb(colours, paint.page, paint.vy, paint.vx, u, v)


@borrowing
def _emit(out, st, grid, air, colours, a, b, tb, seg, paint, c_a, c_b):
    """Integrate the visible angular interval [a, b] (elevations) of one surface segment into
    the column's rows.

    Each row receives the share of its height the interval covers (JP H07-76990's colour
    integration by the fraction of the pixel a voxel covers: no jagged silhouettes), with the
    mean of the surface colour at the ends of its part: the colour is paint's where the row's
    boundary ray meets the segment, so a voxel spanning many rows is coloured like the
    surface, not stretched. The segment's end points seg = (r1, z1, r2, z2) (ground range and
    height relative to the eye, metres) give the exact range at a row's centre. tb: the
    segment parameter at b (0 or 1). c_a, c_b: the colours at a and at b, already known to
    the caller.
    """
    r1, z1, r2, z2 = seg
    nrows = grid.nrows
    dtheta = grid.dtheta
    row_cs = grid.row_cs
    top_cs = grid.top_cs
    row = int(st[_ROW])
    st[_R1] = r1
    st[_Z1] = z1
    st[_R2] = r2
    st[_Z2] = z2
    inv_dtheta = 1.0 / dtheta  # guard: the grid's rows have a height > 0
    # The segment's far end, for the rows whose centre the surface leaves below it.
    inv_far = 1.0 / max(math.sqrt(r2 * r2 + z2 * z2), 1e-6)
    while a < b and row < nrows:
        top = grid.theta0 + (row + 1) * dtheta
        if b <= top:
            e = b
            c_e = c_b
        else:
            e = top
            te = _param_at(top_cs[row, 0], top_cs[row, 1], seg)
            c_e = _colour_at(colours, paint, te)
        w = (e - a) * inv_dtheta
        st[_AR] += w * 0.5 * (c_a[0] + c_e[0])
        st[_AG] += w * 0.5 * (c_a[1] + c_e[1])
        st[_AB] += w * 0.5 * (c_a[2] + c_e[2])
        st[_AW] += w
        centre = top - 0.5 * dtheta
        st[_IRF] = inv_far
        if a <= centre < e:
            st[_IR] = _inverse_range_at(row_cs[row, 0], row_cs[row, 1], seg)
        elif st[_IR] == 0.0 or centre >= e:
            # The centre ray is not (yet) on the surface: the signed inverse range along it
            # to the segment's line continued stands for the row (negative where it would
            # meet the line behind the eye). For planar ground that is linear in the
            # elevation's sine, so the warp interpolates a partly covered row at an edge or
            # crest as well as whole ones.
            st[_IR] = _inverse_range_on_line(row_cs[row, 0], row_cs[row, 1], seg)
        if e >= top:
            _finish_row(out, st, grid, air)
            row += 1
        # The rest of the interval starts at e with the colour there.
        a = e
        c_a = c_e
    if b > st[_TMAX]:
        st[_TMAX] = b
        # Its tangent from the segment end it came from (z / r), no trigonometry.
        rb, zb = (r2, z2) if tb == 1.0 else (r1, z1)
        st[_TANMAX] = zb / rb if rb > 0.0 else math.tan(min(b, 1.5707963))


@njit(cache=True, inline="always")
def _dda_axis(i, d, e, direction, inv):
    """One axis of the grid walk from cell i (width d) along e + r * direction: the step, the
    ground range between crossings and the range of the next crossing (inf if parallel)."""
    if direction > 0.0:
        return 1, d * inv, ((i + 1) * d - e) * inv
    if direction < 0.0:
        return -1, -d * inv, (i * d - e) * inv
    return 0, math.inf, math.inf


@njit(cache=True, inline="always")
def _slab(e, d, extent, r_lo, r_hi):
    """Clip [r_lo, r_hi] of the line e + r d to the slab [0, extent] (r_lo >= r_hi: missed)."""
    if abs(d) > 1e-15:
        t1 = (0.0 - e) / d  # guard: |d| > 1e-15
        t2 = (extent - e) / d
        return max(r_lo, min(t1, t2)), min(r_hi, max(t1, t2))
    if 0.0 <= e <= extent:
        return r_lo, r_hi
    return 0.0, -1.0  # parallel to the slab and outside it


@njit(cache=True, inline="always")
def ground_ray_span(ex, ey, dx, dy, extent_x, extent_y, r_lo, r_hi):
    """The part [r_lo, r_hi] of the ground ray (ex, ey) + r (dx, dy), r >= 0, inside the
    rectangle [0, extent_x] x [0, extent_y] (slab method; metres); r_lo >= r_hi when it
    misses. Shared with the cloud scan (_cloud_kernels)."""
    r_lo, r_hi = _slab(ex, dx, extent_x, max(r_lo, 0.0), r_hi)
    return _slab(ey, dy, extent_y, r_lo, r_hi)


@njit(cache=True, inline="always")
def _corner_z(pages, page, vy, vx, u, v):
    """Height of voxel (vy, vx) of page at local point (u, v), metres above the origin."""
    z0 = pages.z[page, vy, vx, 0]
    z1 = pages.z[page, vy, vx, 1]
    z2 = pages.z[page, vy, vx, 2]
    z3 = pages.z[page, vy, vx, 3]
    return (1.0 - v) * ((1.0 - u) * z0 + u * z1) + v * ((1.0 - u) * z2 + u * z3)


@njit(cache=True, inline="always")
def _corner_rgb(colours, page, vy, vx, u, v, ch):
    """Linear colour channel ch of voxel (vy, vx) of page at local point (u, v)."""
    lut = colours.lut
    c0 = lut[colours.rgb[page, vy, vx, 0, ch]]
    c1 = lut[colours.rgb[page, vy, vx, 1, ch]]
    c2 = lut[colours.rgb[page, vy, vx, 2, ch]]
    c3 = lut[colours.rgb[page, vy, vx, 3, ch]]
    return (1.0 - v) * ((1.0 - u) * c0 + u * c1) + v * ((1.0 - u) * c2 + u * c3)


@njit(cache=True, inline="always")
def _voxel_rgb(colours, page, vy, vx, u, v):
    """Linear (r, g, b) of voxel (vy, vx) of page at local point (u, v)."""
    return (_corner_rgb(colours, page, vy, vx, u, v, 0),
            _corner_rgb(colours, page, vy, vx, u, v, 1),
            _corner_rgb(colours, page, vy, vx, u, v, 2))


@njit(cache=True, inline="always")
def _page_key(qx, qy, d, log2_page, pages_x):
    """Identity of the page of a level (voxel width d, pages_x pages per row) holding ground
    point (qx, qy) (database-relative metres; points off the grid give off-grid keys)."""
    return (int(math.floor(qy / d)) >> log2_page) * pages_x + (int(math.floor(qx / d)) >> log2_page)


@njit(cache=True, inline="always")
def _page_of(pages, level, ix, iy):
    """The page holding voxel (ix, iy) of a level, or -1 (off the level, or missing)."""
    px = ix >> pages.log2_page
    py = iy >> pages.log2_page
    if px < 0 or py < 0 or px >= pages.pages_x[level] or py >= pages.pages_y[level]:
        return -1
    return pages.page_table[pages.table_offset[level] + py * pages.pages_x[level] + px]


@njit(cache=True, parallel=True)
def scan_kernel(pages, grid, limits, air, out_pre, out_visits, threads):
    """One radial scan across the ground grid per pre-image column (JP H07-76990).

    Column j is the vertical half-plane through the eye at azimuth grid.phi_lo + (j + 1/2)
    grid.dphi. Its ground line is walked outward from the start point, one grid line at a
    time (an exact 2-D DDA on the current level's grid, so no voxel is missed). Inside a voxel
    the surface is the bilinear interpolation of its corners. A point's elevation angle
    atan2(z - z_eye, r) against the highest angle seen so far decides occlusion; what rises
    above it covers the rows (bottom-up) it spans (_emit).

    Level: the coarsest whose voxel is at most 2**bias projected pixels wide at the slant
    range, i.e. one level coarser each time the range doubles (limits.r_switch); a missing
    page falls back to the next coarser level.

    limits.first_row[k]: the lowest row a column whose index has k trailing zero bits scans (k
    capped at first_row.size - 1). Towards the nadir output pixels span more azimuth, so
    there only every 2^k-th column is needed (fill_skipped interpolates the others); such a
    column starts where its first row's ray descends to the highest terrain (exact).

    Args:
        pages: the terrain database (VoxelPages).
        grid: the pre-image's columns and rows (ColumnGrid).
        limits: the columns' first rows, the eye (database-relative) and the scan's ranges
            (ScanLimits).
        air: the frame's air array (haze, then fog; contract.py).
        out_pre: (ncols, nrows, PRE_CHANNELS) float32 the pre-image texels.
        out_visits: (ncols,) int64 voxels visited by each column.
        threads: numba.get_num_threads() (jit.lanes).
    """
    ncols = grid.ncols
    # Blocks of columns interleaved over the threads (jit.lanes): the terrain, and with it a
    # column's cost, differs from one side of the view to the other.
    n_blocks = (ncols + _COLUMN_BLOCK - 1) // _COLUMN_BLOCK
    n_lanes = lanes(threads, n_blocks)
    for lane in prange(n_lanes):
        st = np.empty(_STATE)
        for blk in range(lane, n_blocks, n_lanes):
            for j in range(blk * _COLUMN_BLOCK, min(ncols, (blk + 1) * _COLUMN_BLOCK)):
                _column(j, st, pages, grid, limits, air, out_pre, out_visits)


@borrowing
def _column(j, st, pages, grid, limits, air, out_pre, out_visits):
    """Column j of scan_kernel, with st as its scan state."""
    kmax = limits.first_row.shape[0] - 1
    ncols = grid.ncols
    nrows = grid.nrows
    for q in range(_STATE):
        st[q] = 0.0
    k = kmax
    if j != 0 and j != ncols - 1:  # the first and last columns scan every row
        k = 0
        while k < kmax and (j >> k) & 1 == 0:
            k += 1
    start = limits.first_row[k]
    st[_ROW] = start
    phi = grid.phi_lo + (j + 0.5) * grid.dphi
    st[_AXH] = air[F_WORLD_AXIS] * math.sin(phi) + air[F_WORLD_AXIS + 1] * math.cos(phi)
    theta_lo = grid.theta0 + start * grid.dtheta
    st[_TMAX] = theta_lo
    out = out_pre[j]
    out_visits[j] = _scan_column(j, st, pages, grid, limits, theta_lo, air, out)
    # The row the scan stopped in holds what covered it so far (a silhouette).
    if int(st[_ROW]) < nrows and st[_AW] > 0.0:
        _finish_row(out, st, grid, air)
    # Rows the scan never finished see nothing (texels below the column's first row are
    # fill_skipped's). The first of them keeps the last surface's inverse range continued
    # (with no coverage): the warp interpolates between it and the last covered row, which
    # is exact for planar ground right up to the edge.
    row = int(st[_ROW])
    for i in range(row, nrows):
        for c in range(PRE_CHANNELS):
            out[i, c] = 0.0
    if row < nrows and (st[_R1] != 0.0 or st[_R2] != 0.0):
        out[row, PRE_IR] = _inverse_range_on_line(
            grid.row_cs[row, 0], grid.row_cs[row, 1], (st[_R1], st[_Z1], st[_R2], st[_Z2]))

@njit(cache=True, parallel=True)
def fill_skipped(pre, first_row, full):
    """Texels a column did not scan (below its first row, see scan_kernel): interpolated in
    azimuth between the nearest scanning columns of that row (every 2^k-th).

    Args:
        pre: (ncols, nrows, PRE_CHANNELS) float32 the pre-image texels, filled in place.
        first_row: ScanLimits.first_row.
        full: the columns wrap around a full circle.
    """
    ncols = pre.shape[0]
    kmax = first_row.shape[0] - 1
    for i in prange(pre.shape[1]):
        # The stride of row i: the smallest 2^k whose columns all scan it.
        k = 0
        while k < kmax and first_row[k] > i:
            k += 1
        stride = 1 << k
        if stride == 1:
            continue
        for j in range(ncols):
            if j % stride == 0 or j == ncols - 1:
                continue
            a = j - j % stride
            b = a + stride
            f = (j - a) / stride
            if b >= ncols:
                # Full circle: the grid is a multiple of every stride (column 0 follows);
                # otherwise the last column, which scans every row.
                b = 0 if full else ncols - 1
                if not full:
                    f = (j - a) / (ncols - 1 - a)  # guard: ncols - 1 > j > a
            for c in range(PRE_CHANNELS):
                pre[j, i, c] = (1.0 - f) * pre[a, i, c] + f * pre[b, i, c]


@borrowing
def _scan_column(j, st, pages, grid, limits, theta_lo, air, out):
    """Walk column j's ground line (scan_kernel) from elevation theta_lo up, into its texels
    out (nrows, PRE_CHANNELS) and state st; returns the voxels visited."""
    phi = grid.phi_lo + (j + 0.5) * grid.dphi
    dx = math.sin(phi)
    dy = math.cos(phi)
    ex = limits.eye[0]
    ey = limits.eye[1]
    ez = limits.eye[2]
    r_switch = limits.r_switch
    colours = _Colours(pages.rgb, pages.lut)
    spacing = pages.spacing
    log2_page = pages.log2_page
    pages_x = pages.pages_x
    level_nx = pages.level_nx
    level_ny = pages.level_ny
    levels = level_nx.shape[0]
    zrel_max = pages.z_max - ez  # highest surface point relative to the eye
    # Start: nothing nearer than where the lowest row's ray descends to the highest surface
    # point can reach above that row (JP H07-76990's column start point, made exact for
    # relief).
    r_lo = 0.0
    if zrel_max < 0.0:
        if theta_lo >= 0.0:
            return 0  # everything lies below the eye and the column looks level or up
        if theta_lo > -0.5 * math.pi + 1e-9:
            r_lo = zrel_max / math.tan(theta_lo)  # guard: tan(theta_lo) < 0 here
    r_lo, r_hi = ground_ray_span(ex, ey, dx, dy, pages.extent_x, pages.extent_y, r_lo,
                                 limits.r_far)
    if r_lo >= r_hi:
        return 0

    visits = 0
    want = 0
    level = 0
    # The last voxel's exit elevation angle and colour, valid while `cached`.
    cached = False
    t_out = 0.0
    c_out = (0.0, 0.0, 0.0)
    d_l = spacing
    r = r_lo
    z_prev = 0.0
    have_prev = False
    tan_max = math.tan(theta_lo) if theta_lo > -0.5 * math.pi + 1e-9 else -math.inf
    st[_TANMAX] = tan_max
    # Guard: a zero direction component never crosses that family of grid lines.
    inv_dx = 1.0 / dx if dx != 0.0 else 0.0
    inv_dy = 1.0 / dy if dy != 0.0 else 0.0
    mask = (1 << log2_page) - 1
    ix = 0
    iy = 0
    step_x = 0
    step_y = 0
    t_max_x = math.inf
    t_max_y = math.inf
    t_dx = math.inf
    t_dy = math.inf
    page = -1
    page_key = -1
    miss_key = -1  # in fallback: the wanted level's page that was missing
    inv_d = 1.0 / spacing
    restart = True
    while r < r_hi:
        if want < levels - 1 and r >= r_switch[want]:
            while want < levels - 1 and r >= r_switch[want]:
                want += 1
            restart = True
        if restart:
            # (Re)start the DDA at r: the wanted level, or the next coarser one that has this
            # area; the voxel is the one holding the point just past r.
            restart = False
            nudge = r + 1e-7 * spacing + 1e-12 * r
            qx = ex + nudge * dx
            qy = ey + nudge * dy
            level = want
            while True:
                d_l = spacing * (1 << level)
                ix = min(max(int(math.floor(qx / d_l)), 0), level_nx[level] - 1)
                iy = min(max(int(math.floor(qy / d_l)), 0), level_ny[level] - 1)
                page = _page_of(pages, level, ix, iy)
                if page >= 0 or level == levels - 1:
                    break
                level += 1
            if page < 0:
                break  # malformed table (the loader rejects it): stop rather than read garbage
            if level > want:
                miss_key = _page_key(qx, qy, spacing * (1 << want), log2_page, pages_x[want])
            inv_d = 1.0 / d_l  # guard: d_l >= spacing > 0
            page_key = (iy >> log2_page) * pages_x[level] + (ix >> log2_page)
            step_x, t_dx, t_max_x = _dda_axis(ix, d_l, ex, dx, inv_dx)
            step_y, t_dy, t_max_y = _dda_axis(iy, d_l, ey, dy, inv_dy)
        else:
            key = (iy >> log2_page) * pages_x[level] + (ix >> log2_page)
            if key != page_key:
                # A new page: look it up; if this level lacks it, or a finer wanted level may
                # have it again, restart the DDA on the right level.
                page_key = key
                page = _page_of(pages, level, ix, iy)
                if page < 0:
                    restart = True
                    continue
            if level > want:
                # Falling back: back to the wanted level as soon as the line leaves the page
                # it lacked (that level's page, not this coarser one's).
                nudge = r + 1e-7 * spacing + 1e-12 * r
                if _page_key(ex + nudge * dx, ey + nudge * dy, spacing * (1 << want), log2_page,
                             pages_x[want]) != miss_key:
                    restart = True
                    continue
        vx = ix & mask
        vy = iy & mask
        visits += 1
        r_next = min(min(t_max_x, t_max_y), r_hi)
        if r_next <= r:
            # Rounding at a restart can leave the first exit a hair behind r: step past it.
            r_next = r
        # Entry and exit points of this voxel, local coordinates clamped against rounding.
        u0 = min(max((ex + r * dx) * inv_d - ix, 0.0), 1.0)
        v0 = min(max((ey + r * dy) * inv_d - iy, 0.0), 1.0)
        u1 = min(max((ex + r_next * dx) * inv_d - ix, 0.0), 1.0)
        v1 = min(max((ey + r_next * dy) * inv_d - iy, 0.0), 1.0)
        z_in = _corner_z(pages, page, vy, vx, u0, v0) - ez
        if not have_prev:
            # First point of the column. Entering the database from outside, the terrain is a
            # solid: its edge shows as a wall (skirt) down from the surface, not as a gap.
            have_prev = True
            z_prev = z_in
            if z_in > r * tan_max:
                _wall(out, st, grid, air, colours, r, z_in - _SKIRT_M, z_in,
                      _voxel_rgb(colours, page, vy, vx, u0, v0))
                tan_max = st[_TANMAX]
        elif abs(z_in - z_prev) > _WALL_DZ:
            cached = False  # the surface jumps here: nothing of the last voxel carries over
            if z_in > z_prev and z_in > r * tan_max:
                # A step up between voxels (a cliff, a building edge): a vertical wall at r.
                _wall(out, st, grid, air, colours, r, z_prev, z_in,
                      _voxel_rgb(colours, page, vy, vx, u0, v0))
                tan_max = st[_TANMAX]
        k = pages.pattern[page, vy, vx] if level == 0 else 0
        if k > 0:
            # A vertical pattern (JP H07-76990's pattern insertion): its bands stacked as a
            # wall at the voxel's near side, then its top across the voxel.
            cached = False
            k -= 1
            top = z_in
            for q in range(4):
                top = max(top, pages.z[page, vy, vx, q] - ez)
            lo = z_in
            for band in range(pages.pat_bands[k]):
                hi = top + pages.pat_top[k, band]
                if hi > r * tan_max:
                    _wall(out, st, grid, air, colours, r, lo, hi,
                          _rgb64(pages.pat_rgb[k, band]))
                    tan_max = st[_TANMAX]
                lo = hi
            last = pages.pat_bands[k] - 1
            c_top = _rgb64(pages.pat_rgb[k, last])
            if lo > r_next * tan_max:
                _surface(out, st, grid, air, colours, (r, lo, r_next, lo), math.nan,
                         _Paint(-1, 0, 0, 0.0, 0.0, 0.0, 0.0, c_top), c_top, c_top)
                tan_max = st[_TANMAX]
            z_prev = lo  # the drop back to the ground beyond is never seen from outside
        else:
            z_out = _corner_z(pages, page, vy, vx, u1, v1) - ez
            if z_out > r_next * tan_max or z_in > r * tan_max:
                # Visible. The entry's elevation angle and colour are the last voxel's exit
                # ones where the surface runs on continuously, as it nearly always does.
                if cached:
                    t_in = t_out
                    c_in = c_out
                else:
                    t_in = math.nan
                    c_in = _voxel_rgb(colours, page, vy, vx, u0, v0)
                c_out = _voxel_rgb(colours, page, vy, vx, u1, v1)
                t_out = _surface(out, st, grid, air, colours, (r, z_in, r_next, z_out), t_in,
                                 _Paint(page, vy, vx, u0, v0, u1, v1, c_in), c_in, c_out)
                tan_max = st[_TANMAX]
                cached = True
            else:
                cached = False
            z_prev = z_out
        if int(st[_ROW]) >= grid.nrows:
            break  # every row of the column is covered
        r = r_next
        # Nothing farther can rise above what is seen: the highest point of the database
        # beyond r is below the current horizon (guard: r > 0 once a step was taken).
        if r > 0.0 and zrel_max <= min(r * tan_max, r_hi * tan_max):  # r_hi binds if tan_max < 0
            break
        if t_max_x < t_max_y:
            ix += step_x
            t_max_x += t_dx
            if ix < 0 or ix >= level_nx[level]:
                break
        else:
            iy += step_y
            t_max_y += t_dy
            if iy < 0 or iy >= level_ny[level]:
                break
    return visits


@njit(cache=True, inline="always")
def _rgb64(rgb):
    """A float32 colour as the float64 tuple every other colour of the scan is: one
    compiled version of the functions it reaches, not one per float width."""
    return (np.float64(rgb[0]), np.float64(rgb[1]), np.float64(rgb[2]))


@borrowing
def _wall(out, st, grid, air, colours, r, z_lo, z_hi, rgb):
    """A vertical face of one linear colour rgb at ground range r from height z_lo to z_hi
    (relative to the eye, metres)."""
    a = math.atan2(z_lo, r)
    b = math.atan2(z_hi, r)
    a = max(a, st[_TMAX])
    if b > a:
        _emit(out, st, grid, air, colours, a, b, 1.0, (r, z_lo, r, z_hi),
              _Paint(-1, 0, 0, 0.0, 0.0, 0.0, 0.0, rgb), rgb, rgb)


@borrowing
def _surface(out, st, grid, air, colours, seg, t1, paint, c1, c2):
    """The surface segment seg = (r1, z1, r2, z2): the part rising above the current horizon.

    t1: elevation angle of (r1, z1) if known (NaN: computed here). Returns that of (r2, z2).
    Colour: paint, whose colour at the near end is c1 and at the far end c2.
    """
    r1, z1, r2, z2 = seg
    if math.isnan(t1):
        t1 = math.atan2(z1, r1)
    t2 = math.atan2(z2, r2)
    t_far = t2
    lo = t1
    hi = t2
    t_lo = 0.0
    t_hi = 1.0
    if t2 < t1:
        # Seen from the eye the segment runs downwards in angle: only its near end can show
        # (a crest).
        lo = t2
        hi = t1
        t_lo = 1.0
        t_hi = 0.0
    tmax = st[_TMAX]
    if hi <= tmax:
        return t_far
    a = lo
    if t_lo == 0.0:
        c_a, c_b = c1, c2
    else:
        c_a, c_b = c2, c1
    if a < tmax:
        # Only the part above the horizon, from where it emerges (its colour there).
        a = tmax
        ta = _param_at(math.cos(tmax), math.sin(tmax), seg)
        c_a = _colour_at(colours, paint, ta)
    _emit(out, st, grid, air, colours, a, hi, t_hi, seg, paint, c_a, c_b)
    return t_far
