"""numba kernels of the terrain stage (see terrain.py): the radial column scan and the warp.

Pre-image texel channels (PRE_*): premultiplied linear RGB after haze and fog, coverage, and the
inverse range of the surface seen at the texel's centre elevation (0 where none is).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import F_ON, F_RGB, F_WORLD_AXIS
from channel_worker.pipeline.fog.fog import fog_blend, fog_cos, fog_depth

from .haze import haze_amount

PRE_R, PRE_G, PRE_B, PRE_A, PRE_IR = 0, 1, 2, 3, 4
PRE_CHANNELS = 5

# Column state (one small array per column, so the helpers can update it in place).
_ROW, _AR, _AG, _AB, _AW, _IR, _TMAX, _IRF = 0, 1, 2, 3, 4, 5, 6, 7
_R1, _Z1, _R2, _Z2 = 8, 9, 10, 11  # the last segment emitted
_TANMAX = 12  # tan of _TMAX, from the point that set it
_AXH = 13  # fog: the column's rays' axis cosine is _AXH cos(elevation) + axis z sin(elevation)
_STATE = 14

#: Depth of the skirt down the database's edge (metres): deep enough to reach below any
#: horizon the scan starts from.
_SKIRT_M = 1e7

#: A wall is emitted where two neighbouring voxels' corners disagree by more than this (metres):
#: below it the step is float32 rounding of copies of one value.
_WALL_DZ = 1e-3


@njit(cache=True, inline="always")
def _finish_row(pre, j, st, theta0, dtheta, air):
    """Write the current row of column j from the accumulators and start the next one."""
    row = int(st[_ROW])
    w = st[_AW]
    r = st[_AR]
    g = st[_AG]
    b = st[_AB]
    ir = st[_IR]
    if (air[0] != 0.0 or air[F_ON] != 0.0) and w > 0.0:
        centre = theta0 + (row + 0.5) * dtheta
        # The surface's range at the row's centre, or (a row its surface leaves below the
        # centre) that of the surface's far end. Guard: _IRF > 0 once anything was emitted.
        rng = 1.0 / (ir if ir > 0.0 else st[_IRF])
        sn = math.sin(centre)
        if air[0] != 0.0:
            hz = haze_amount(air, rng, sn)
            # Premultiplied: the haze covers the share w of the texel the terrain covers.
            r = r * (1.0 - hz) + air[3] * hz * w
            g = g * (1.0 - hz) + air[4] * hz * w
            b = b * (1.0 - hz) + air[5] * hz * w
        if air[F_ON] != 0.0:
            t = math.exp(-fog_depth(air, rng, st[_AXH] * math.cos(centre)
                                    + air[F_WORLD_AXIS + 2] * sn))
            r = t * r + (1.0 - t) * air[F_RGB] * w
            g = t * g + (1.0 - t) * air[F_RGB + 1] * w
            b = t * b + (1.0 - t) * air[F_RGB + 2] * w
    pre[j, row, PRE_R] = r
    pre[j, row, PRE_G] = g
    pre[j, row, PRE_B] = b
    pre[j, row, PRE_A] = min(w, 1.0)
    pre[j, row, PRE_IR] = ir
    st[_ROW] = row + 1
    st[_AR] = 0.0
    st[_AG] = 0.0
    st[_AB] = 0.0
    st[_AW] = 0.0
    st[_IR] = 0.0
    st[_IRF] = 0.0


@njit(cache=True, inline="always")
def _param_at(ct, st, r1, z1, r2, z2):
    """Where (0..1) along the segment (r1, z1) -> (r2, z2) (ground range, height relative to
    the eye, metres) the ray at elevation theta (its cosine and sine) meets it."""
    dr = r2 - r1
    dz = z2 - z1
    den = dr * st - dz * ct
    # Guard: a ray parallel to the segment (den ~ 0) meets it along its length; its middle
    # stands for it.
    t = (z1 * ct - r1 * st) / den if abs(den) > 1e-12 * (abs(dr) + abs(dz)) else 0.5
    return min(max(t, 0.0), 1.0)


@njit(cache=True, inline="always")
def _inverse_range_at(ct, st, r1, z1, r2, z2):
    """1 / distance from the eye to where the ray at elevation theta (its cosine and sine)
    meets the segment (r1, z1) -> (r2, z2)."""
    t = _param_at(ct, st, r1, z1, r2, z2)
    rr = r1 + t * (r2 - r1)
    zz = z1 + t * (z2 - z1)
    # Guard: the eye is kept above the surface (terrain.py), so the distance is > 0.
    return 1.0 / max(math.sqrt(rr * rr + zz * zz), 1e-6)


@njit(cache=True, inline="always")
def _inverse_range_on_line(ct, st, r1, z1, r2, z2):
    """Signed 1 / distance along the ray at elevation theta (cosine, sine) to the line through
    the segment (r1, z1) -> (r2, z2): (n . u) / (n . p1) with n normal to the line and u the
    ray's direction; negative if the ray meets the line behind the eye. The far end's inverse
    range where the line passes through the eye (n . p1 ~ 0)."""
    nr = -(z2 - z1)
    nz = r2 - r1
    c = nr * r1 + nz * z1
    if abs(c) <= 1e-9 * (abs(nr) + abs(nz)) * (abs(r1) + abs(z1) + 1.0):
        return 1.0 / max(math.sqrt(r2 * r2 + z2 * z2), 1e-6)
    return (nr * ct + nz * st) / c  # guard: |c| is not ~0


@njit(cache=True, inline="always")
def _colour_at(rgb_pages, lut, page, vy, vx, u0, v0, u1, v1, t, cr, cg, cb):
    """Colour at parameter t of a segment: the voxel's bilinear corner colours at the local
    point (u0, v0) + t ((u1, v1) - (u0, v0)), or the constant (cr, cg, cb) if page < 0."""
    if page < 0:
        return cr, cg, cb
    u = u0 + t * (u1 - u0)
    v = v0 + t * (v1 - v0)
    return (_corner_rgb(rgb_pages, lut, page, vy, vx, u, v, 0),
            _corner_rgb(rgb_pages, lut, page, vy, vx, u, v, 1),
            _corner_rgb(rgb_pages, lut, page, vy, vx, u, v, 2))


@njit(cache=True)
def _emit(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, a, b, ta, tb, r1, z1, r2, z2,
          rgb_pages, lut, page, vy, vx, u0, v0, u1, v1, cr, cg, cb, ca_r, ca_g, ca_b, cb_r, cb_g,
          cb_b):
    """Integrate the visible angular interval [a, b] of one surface segment into the rows.

    Each row receives the share of its height the interval covers (seed 002's colour
    integration by the fraction of the pixel a voxel covers: no jagged silhouettes), with the
    mean of the surface colour at the ends of its part: the colour is the voxel's bilinear
    colour where the row's boundary ray meets the segment (ta, tb: the segment parameters at
    a and b; top_cs: cosine and sine of each row's top boundary), so a voxel spanning many
    rows is coloured like the surface, not stretched. The segment's end points (r, z relative
    to the eye) give the exact range at a row's centre (row_cs: cosine and sine of each row's
    centre elevation). page < 0: a wall or pattern of constant colour (cr, cg, cb). ca, cb:
    the colours at a and at b, already known to the caller.
    """
    row = int(st[_ROW])
    st[_R1] = r1
    st[_Z1] = z1
    st[_R2] = r2
    st[_Z2] = z2
    while a < b and row < nrows:
        top = theta0 + (row + 1) * dtheta
        if b <= top:
            e = b
            ce_r, ce_g, ce_b = cb_r, cb_g, cb_b
        else:
            e = top
            te = _param_at(top_cs[row, 0], top_cs[row, 1], r1, z1, r2, z2)
            ce_r, ce_g, ce_b = _colour_at(rgb_pages, lut, page, vy, vx, u0, v0, u1, v1, te, cr,
                                          cg, cb)
        w = (e - a) / dtheta
        st[_AR] += w * 0.5 * (ca_r + ce_r)
        st[_AG] += w * 0.5 * (ca_g + ce_g)
        st[_AB] += w * 0.5 * (ca_b + ce_b)
        st[_AW] += w
        centre = top - 0.5 * dtheta
        st[_IRF] = 1.0 / max(math.sqrt(r2 * r2 + z2 * z2), 1e-6)
        if a <= centre < e:
            st[_IR] = _inverse_range_at(row_cs[row, 0], row_cs[row, 1], r1, z1, r2, z2)
        elif st[_IR] == 0.0 or centre >= e:
            # The centre ray is not (yet) on the surface: the signed inverse range along it
            # to the segment's line continued stands for the row (negative where it would
            # meet the line behind the eye). For planar ground that is linear in the
            # elevation's sine, so the warp interpolates a partly covered row at an edge or
            # crest as well as whole ones.
            st[_IR] = _inverse_range_on_line(row_cs[row, 0], row_cs[row, 1], r1, z1, r2, z2)
        if e >= top:
            _finish_row(pre, j, st, theta0, dtheta, air)
            row += 1
        # The rest of the interval starts at e with the colour there.
        a = e
        ca_r = ce_r
        ca_g = ce_g
        ca_b = ce_b
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
    rectangle [0, extent_x] x [0, extent_y] (slab method); r_lo >= r_hi when it misses."""
    r_lo, r_hi = _slab(ex, dx, extent_x, max(r_lo, 0.0), r_hi)
    return _slab(ey, dy, extent_y, r_lo, r_hi)


@njit(cache=True, inline="always")
def _corner_z(z_pages, page, vy, vx, u, v):
    z0 = z_pages[page, vy, vx, 0]
    z1 = z_pages[page, vy, vx, 1]
    z2 = z_pages[page, vy, vx, 2]
    z3 = z_pages[page, vy, vx, 3]
    return (1.0 - v) * ((1.0 - u) * z0 + u * z1) + v * ((1.0 - u) * z2 + u * z3)


@njit(cache=True, inline="always")
def _corner_rgb(rgb_pages, lut, page, vy, vx, u, v, ch):
    c0 = lut[rgb_pages[page, vy, vx, 0, ch]]
    c1 = lut[rgb_pages[page, vy, vx, 1, ch]]
    c2 = lut[rgb_pages[page, vy, vx, 2, ch]]
    c3 = lut[rgb_pages[page, vy, vx, 3, ch]]
    return (1.0 - v) * ((1.0 - u) * c0 + u * c1) + v * ((1.0 - u) * c2 + u * c3)


@njit(cache=True, inline="always")
def _page_key(qx, qy, d, log2_page, pages_x):
    """Identity of the page of a level (voxel width d, pages_x pages per row) holding ground
    point (qx, qy) (database-relative metres; points off the grid give off-grid keys)."""
    return (int(math.floor(qy / d)) >> log2_page) * pages_x + (int(math.floor(qx / d)) >> log2_page)


@njit(cache=True, inline="always")
def _page_of(page_table, table_offset, pages_x, pages_y, log2_page, level, ix, iy):
    px = ix >> log2_page
    py = iy >> log2_page
    if px < 0 or py < 0 or px >= pages_x[level] or py >= pages_y[level]:
        return -1
    return page_table[table_offset[level] + py * pages_x[level] + px]


@njit(cache=True, parallel=True)
def scan_kernel(z_pages, rgb_pages, pat_pages, page_table, table_offset, pages_x, pages_y,
                log2_page, level_nx, level_ny, spacing, extent_x, extent_y, z_max, pat_top,
                pat_rgb, pat_bands, lut, eye, phi_lo, dphi, ncols, theta0, dtheta, nrows,
                r_switch, r_far, air, row_cs, top_cs, first_row, out_pre, out_visits):
    """One radial scan across the ground grid per pre-image column (seed 002).

    Column j is the vertical half-plane through the eye at azimuth phi_lo + (j + 1/2) dphi
    (clockwise from north). Its ground line is walked outward from the start point, one grid
    line at a time (an exact 2-D DDA on the current level's grid, so no voxel is missed).
    Inside a voxel the surface is the bilinear interpolation of its corners. A point's
    elevation angle atan2(z - z_eye, r) against the highest angle seen so far decides
    occlusion; what rises above it covers the rows (bottom-up, elevation theta0 + i dtheta)
    it spans (_emit).

    Level: the coarsest whose voxel is at most 2**bias projected pixels wide at the slant
    range, i.e. one level coarser each time the range doubles (r_switch[L]: ground range
    where level L + 1 takes over); a missing page falls back to the next coarser level.

    eye: (3,) eye position relative to the database origin, metres (float64).
    r_far: ground range beyond which nothing is scanned (far plane or opaque haze).
    first_row[k]: the lowest row a column whose index has k trailing zero bits scans (k
    capped at first_row.size - 1). Towards the nadir output pixels span more azimuth, so
    there only every 2^k-th column is needed (fill_skipped interpolates the others); such a
    column starts where its first row's ray descends to the highest terrain (exact).
    out_visits[j]: voxels visited by column j.
    """
    levels = level_nx.shape[0]
    ex = eye[0]
    ey = eye[1]
    ez = eye[2]
    kmax = first_row.shape[0] - 1
    for j in prange(ncols):
        st = np.zeros(_STATE)
        k = kmax
        if j != 0 and j != ncols - 1:  # the first and last columns scan every row
            k = 0
            while k < kmax and (j >> k) & 1 == 0:
                k += 1
        start = first_row[k]
        st[_ROW] = start
        phi = phi_lo + (j + 0.5) * dphi
        st[_AXH] = air[F_WORLD_AXIS] * math.sin(phi) + air[F_WORLD_AXIS + 1] * math.cos(phi)
        theta_lo = theta0 + start * dtheta
        st[_TMAX] = theta_lo
        out_visits[j] = _scan_column(
            j, st, z_pages, rgb_pages, pat_pages, page_table, table_offset, pages_x, pages_y,
            log2_page, level_nx, level_ny, levels, spacing, extent_x, extent_y, z_max, pat_top,
            pat_rgb, pat_bands, lut, ex, ey, ez, phi_lo, dphi, theta0, theta_lo, dtheta, nrows,
            r_switch, r_far, air, row_cs, top_cs, out_pre)
        # The row the scan stopped in holds what covered it so far (a silhouette).
        if int(st[_ROW]) < nrows and st[_AW] > 0.0:
            _finish_row(out_pre, j, st, theta0, dtheta, air)
        # Rows the scan never finished see nothing (texels below the column's first row are
        # fill_skipped's). The first of them keeps the last surface's inverse range continued
        # (with no coverage): the warp interpolates between it and the last covered row,
        # which is exact for planar ground right up to the edge.
        row = int(st[_ROW])
        for i in range(row, nrows):
            for c in range(PRE_CHANNELS):
                out_pre[j, i, c] = 0.0
        if row < nrows and (st[_R1] != 0.0 or st[_R2] != 0.0):
            out_pre[j, row, PRE_IR] = _inverse_range_on_line(
                row_cs[row, 0], row_cs[row, 1], st[_R1], st[_Z1], st[_R2], st[_Z2])


@njit(cache=True, parallel=True)
def fill_skipped(pre, first_row, full):
    """Texels a column did not scan (below its first row, see scan_kernel): interpolated in
    azimuth between the nearest scanning columns of that row (every 2^k-th)."""
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


@njit(cache=True)
def _scan_column(j, st, z_pages, rgb_pages, pat_pages, page_table, table_offset, pages_x,
                 pages_y, log2_page, level_nx, level_ny, levels, spacing, extent_x, extent_y,
                 z_max, pat_top, pat_rgb, pat_bands, lut, ex, ey, ez, phi_lo, dphi, theta0,
                 theta_lo, dtheta, nrows, r_switch, r_far, air, row_cs, top_cs, pre):
    phi = phi_lo + (j + 0.5) * dphi
    dx = math.sin(phi)
    dy = math.cos(phi)
    zrel_max = z_max - ez  # highest surface point relative to the eye
    # Start: nothing nearer than where the lowest row's ray descends to the highest surface
    # point can reach above that row (seed 002's column start point, made exact for relief).
    r_lo = 0.0
    if zrel_max < 0.0:
        if theta_lo >= 0.0:
            return 0  # everything lies below the eye and the column looks level or up
        if theta_lo > -0.5 * math.pi + 1e-9:
            r_lo = zrel_max / math.tan(theta_lo)  # guard: tan(theta_lo) < 0 here
    r_lo, r_hi = ground_ray_span(ex, ey, dx, dy, extent_x, extent_y, r_lo, r_far)
    if r_lo >= r_hi:
        return 0

    visits = 0
    want = 0
    level = 0
    # The last voxel's exit elevation angle and colour, valid while `cached`.
    cached = False
    t_out = 0.0
    x_r = x_g = x_b = 0.0
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
                page = _page_of(page_table, table_offset, pages_x, pages_y, log2_page, level,
                                ix, iy)
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
                page = _page_of(page_table, table_offset, pages_x, pages_y, log2_page, level,
                                ix, iy)
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
        z_in = _corner_z(z_pages, page, vy, vx, u0, v0) - ez
        if not have_prev:
            # First point of the column. Entering the database from outside, the terrain is a
            # solid: its edge shows as a wall (skirt) down from the surface, not as a gap.
            have_prev = True
            z_prev = z_in
            if z_in > r * tan_max:
                _wall(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, rgb_pages, lut,
                      r, z_in - _SKIRT_M, z_in,
                      _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 0),
                      _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 1),
                      _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 2))
                tan_max = st[_TANMAX]
        elif abs(z_in - z_prev) > _WALL_DZ:
            cached = False  # the surface jumps here: nothing of the last voxel carries over
            if z_in > z_prev and z_in > r * tan_max:
                # A step up between voxels (a cliff, a building edge): a vertical wall at r.
                _wall(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, rgb_pages, lut,
                      r, z_prev, z_in,
                      _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 0),
                      _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 1),
                      _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 2))
                tan_max = st[_TANMAX]
        k = pat_pages[page, vy, vx] if level == 0 else 0
        if k > 0:
            # A vertical pattern (seed 002 pattern insertion): its bands stacked as a wall at
            # the voxel's near side, then its top across the voxel.
            cached = False
            k -= 1
            top = z_in
            for q in range(4):
                top = max(top, z_pages[page, vy, vx, q] - ez)
            lo = z_in
            for band in range(pat_bands[k]):
                hi = top + pat_top[k, band]
                if hi > r * tan_max:
                    _wall(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, rgb_pages,
                          lut, r, lo, hi,
                          pat_rgb[k, band, 0], pat_rgb[k, band, 1], pat_rgb[k, band, 2])
                    tan_max = st[_TANMAX]
                lo = hi
            cr = pat_rgb[k, pat_bands[k] - 1, 0]
            cg = pat_rgb[k, pat_bands[k] - 1, 1]
            cb = pat_rgb[k, pat_bands[k] - 1, 2]
            if lo > r_next * tan_max:
                _surface(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, r, lo, r_next,
                         lo, math.nan, rgb_pages, lut, -1, 0, 0, 0.0, 0.0, 0.0, 0.0, cr, cg, cb,
                         cr, cg, cb)
                tan_max = st[_TANMAX]
            z_prev = lo  # the drop back to the ground beyond is never seen from outside
        else:
            z_out = _corner_z(z_pages, page, vy, vx, u1, v1) - ez
            if z_out > r_next * tan_max or z_in > r * tan_max:
                # Visible. The entry's elevation angle and colour are the last voxel's exit
                # ones where the surface runs on continuously, as it nearly always does.
                if cached:
                    t_in = t_out
                    e_r, e_g, e_b = x_r, x_g, x_b
                else:
                    t_in = math.nan
                    e_r = _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 0)
                    e_g = _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 1)
                    e_b = _corner_rgb(rgb_pages, lut, page, vy, vx, u0, v0, 2)
                x_r = _corner_rgb(rgb_pages, lut, page, vy, vx, u1, v1, 0)
                x_g = _corner_rgb(rgb_pages, lut, page, vy, vx, u1, v1, 1)
                x_b = _corner_rgb(rgb_pages, lut, page, vy, vx, u1, v1, 2)
                t_out = _surface(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, r,
                                 z_in, r_next, z_out, t_in, rgb_pages, lut, page, vy, vx, u0, v0,
                                 u1, v1, e_r, e_g, e_b, x_r, x_g, x_b)
                tan_max = st[_TANMAX]
                cached = True
            else:
                cached = False
            z_prev = z_out
        if int(st[_ROW]) >= nrows:
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


@njit(cache=True)
def _wall(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, rgb_pages, lut, r, z_lo,
          z_hi, cr, cg, cb):
    """A vertical face of constant colour at ground range r from height z_lo to z_hi
    (relative to the eye)."""
    a = math.atan2(z_lo, r)
    b = math.atan2(z_hi, r)
    a = max(a, st[_TMAX])
    if b > a:
        _emit(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, a, b, 0.0, 1.0,
              r, z_lo, r, z_hi, rgb_pages, lut, -1, 0, 0, 0.0, 0.0, 0.0, 0.0, cr, cg, cb,
              cr, cg, cb, cr, cg, cb)


@njit(cache=True)
def _surface(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, r1, z1, r2, z2, t1,
             rgb_pages, lut, page, vy, vx, u0, v0, u1, v1, c1r, c1g, c1b, c2r, c2g, c2b):
    """The surface from (r1, z1) to (r2, z2): the part rising above the current horizon.

    t1: elevation angle of (r1, z1) if known (NaN: computed here). Returns that of (r2, z2).
    Colour: the voxel's bilinear colours from local point (u0, v0) (colour c1) to (u1, v1)
    (colour c2), or constant c1 if page < 0.
    """
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
        ca_r, ca_g, ca_b, cb_r, cb_g, cb_b = c1r, c1g, c1b, c2r, c2g, c2b
    else:
        ca_r, ca_g, ca_b, cb_r, cb_g, cb_b = c2r, c2g, c2b, c1r, c1g, c1b
    if a < tmax:
        # Only the part above the horizon, from where it emerges (its colour there).
        a = tmax
        ta = _param_at(math.cos(tmax), math.sin(tmax), r1, z1, r2, z2)
        ca_r, ca_g, ca_b = _colour_at(rgb_pages, lut, page, vy, vx, u0, v0, u1, v1, ta, c1r, c1g,
                                      c1b)
    _emit(pre, j, st, nrows, theta0, dtheta, row_cs, top_cs, air, a, hi, 0.0, t_hi,
          r1, z1, r2, z2, rgb_pages, lut, page, vy, vx, u0, v0, u1, v1, c1r, c1g, c1b,
          ca_r, ca_g, ca_b, cb_r, cb_g, cb_b)
    return t_far


@njit(cache=True, inline="always")
def _map_point(sx, sy, m, mapping, phi_lo, dphi, span, full, theta0, dtheta):
    """Pre-image coordinates (column, row; texel centres at integers) of screen point (sx, sy)."""
    tx = (sx - mapping[1]) / mapping[0]
    ty = (sy - mapping[3]) / mapping[2]
    wx = m[0, 0] * tx + m[1, 0] * ty + m[2, 0]
    wy = m[0, 1] * tx + m[1, 1] * ty + m[2, 1]
    wz = m[0, 2] * tx + m[1, 2] * ty + m[2, 2]
    theta = math.atan2(wz, math.sqrt(wx * wx + wy * wy))
    rel = math.atan2(wx, wy) - phi_lo
    rel -= 2.0 * math.pi * math.floor(rel / (2.0 * math.pi))  # into [0, 2 pi)
    if not full and rel > 0.5 * (span + 2.0 * math.pi):
        rel -= 2.0 * math.pi  # just left of the range, not far right of it
    return rel / dphi - 0.5, (theta - theta0) / dtheta - 0.5


@njit(cache=True, parallel=True)
def warp_kernel(pre, full, phi_lo, dphi, theta0, dtheta, m, mapping, offsets, width, height,
                horizon, dz_row, height_above, sky, earth, air, sky_haze, sky_haze_t0,
                sky_haze_dt, margin_m, block,
                cloud_on, cloud_pre, cloud_col_ratio, cloud_row_ratio, depth_tile, depth_need,
                out_rgb, out_iz, out_range, out_cloud):
    """Every output pixel and sample from the pre-image: roll, vertical perspective and the
    off-axis frustum in one inverse mapping, bilinear (anti-aliased) resampling.

    Pre-image coordinates come from the exact world direction (azimuth, elevation); they are
    computed exactly at the corners of block x block pixel blocks and interpolated inside,
    unless the interpolation misses the exact value at the block centre by more than 1/50
    texel (near the nadir or zenith, where azimuth turns fast): such a block is split in four,
    and a quarter that still misses maps every point exactly.

    Per pixel (out_rgb, at its centre): the terrain over the sky or earth plane (the share of
    the pixel's samples below the horizon sees the earth), with haze (sky_haze: the sky's
    haze at elevations sky_haze_t0 + (i + 1/2) sky_haze_dt). Per sample (out_iz):
    1/z of the terrain pushed back by the polygon margin where the terrain covers the sample
    (coverage >= 1/2), else 0 (sky and earth never hide a polygon); so a hill's silhouette
    against a polygon behind it keeps the samples' resolution. out_range: the pixel's nearest
    range (the earth plane's where seen, +inf for sky).

    Clouds (cloud_on): the coarse cloud pre-image (clouds.py; cloud_col_ratio and
    cloud_row_ratio: pre-image texels per cloud texel) is interpolated bilinearly and laid over
    the background where the background lies beyond the cloud's entry range; out_cloud keeps
    the pixel's cloud (premultiplied RGB, opacity, entry range) for the polygons.

    depth_need: per depth_tile x depth_tile sub-area (row-major), whether out_iz is wanted
    there (sub-areas without polygons have nothing to test against the terrain: left 0).
    """
    tiles_x = (width + depth_tile - 1) // depth_tile
    ncols = pre.shape[0]
    nrows = pre.shape[1]
    span = ncols * dphi
    s_count = offsets.shape[0]
    blocks_x = (width + block - 1) // block
    blocks_y = (height + block - 1) // block
    kx, ky, k0 = horizon[0], horizon[1], horizon[2]
    # Guard: screen_mapping's scales are nonzero (check_channel: left < right, bottom < top).
    inv_sxs = 1.0 / mapping[0]
    inv_sys = 1.0 / mapping[2]
    for by in prange(blocks_y):
        for bx in range(blocks_x):
            x0 = bx * block
            y0 = by * block
            ok, c00, c10, c01, c11, r00, r10, r01, r11 = _block_corners(
                x0, y0, block, m, mapping, phi_lo, dphi, span, full, theta0, dtheta, ncols)
            if ok:
                _warp_block(x0, y0, block, False, c00, c10, c01, c11, r00, r10, r01, r11,
                            pre, full, phi_lo, dphi, theta0, dtheta, m, mapping, offsets, width, height, kx, ky,
                            k0, dz_row, height_above, sky, earth, air, sky_haze, sky_haze_t0, sky_haze_dt,
                            margin_m, cloud_on, cloud_pre, cloud_col_ratio, cloud_row_ratio, depth_tile,
                            tiles_x, depth_need, ncols, nrows, span, s_count, inv_sxs, inv_sys,
                            out_rgb, out_iz, out_range, out_cloud)
                continue
            # Mapping too curved for the block (near the nadir or zenith): its quarters, each
            # interpolated if it can be, else mapped point by point.
            half = block // 2
            for q in range(4):
                qx0 = x0 + (q % 2) * half
                qy0 = y0 + (q // 2) * half
                ok, c00, c10, c01, c11, r00, r10, r01, r11 = _block_corners(
                    qx0, qy0, half, m, mapping, phi_lo, dphi, span, full, theta0, dtheta, ncols)
                _warp_block(qx0, qy0, half, not ok, c00, c10, c01, c11, r00, r10, r01, r11,
                            pre, full, phi_lo, dphi, theta0, dtheta, m, mapping, offsets, width, height, kx, ky,
                            k0, dz_row, height_above, sky, earth, air, sky_haze, sky_haze_t0, sky_haze_dt,
                            margin_m, cloud_on, cloud_pre, cloud_col_ratio, cloud_row_ratio, depth_tile,
                            tiles_x, depth_need, ncols, nrows, span, s_count, inv_sxs, inv_sys,
                            out_rgb, out_iz, out_range, out_cloud)


@njit(cache=True, parallel=True)
def sky_earth_kernel(mapping, offsets, width, height, horizon, dz_row, height_above, sky, earth,
                     air, out_rgb, out_range):
    """The background of a scene with haze or fog but neither terrain nor clouds: per pixel
    (at its centre) the sky over the earth plane (the share of the pixel's samples below the
    horizon sees the earth), through the air; out_range: the earth plane's range where seen,
    +inf for sky. What warp_kernel paints there, without its pre-image."""
    kx, ky, k0 = horizon[0], horizon[1], horizon[2]
    s_count = offsets.shape[0]
    # Guard: screen_mapping's scales are nonzero (check_channel: left < right, bottom < top).
    inv_sxs = 1.0 / mapping[0]
    inv_sys = 1.0 / mapping[2]
    for y in prange(height):
        ty = (y + 0.5 - mapping[3]) * inv_sys
        for x in range(width):
            tx = (x + 0.5 - mapping[1]) * inv_sxs
            n_earth = _earth_samples(x, y, offsets, kx, ky, k0)
            hs = 0.0
            if air[0] != 0.0 and n_earth < s_count:
                # Guard: the ray (tx, ty, 1) is at least 1 long.
                sin_el = (dz_row[0] * tx + dz_row[1] * ty + dz_row[2]) / math.sqrt(
                    tx * tx + ty * ty + 1.0)
                hs = haze_amount(air, math.inf, max(sin_el, 0.0))
            r, g, b, out_range[y, x] = _sky_and_earth(n_earth, s_count, tx, ty, dz_row,
                                                      height_above, sky, earth, air, hs)
            out_rgb[y, x, 0] = r
            out_rgb[y, x, 1] = g
            out_rgb[y, x, 2] = b


@njit(cache=True, inline="always")
def _earth_samples(x, y, offsets, kx, ky, k0):
    """How many of pixel (x, y)'s samples lie below the horizon line kx sx + ky sy + k0 = 0."""
    n = 0
    for s in range(offsets.shape[0]):
        if kx * (x + offsets[s, 0]) + ky * (y + offsets[s, 1]) + k0 < 0.0:
            n += 1
    return n


@njit(cache=True, inline="always")
def _sky_and_earth(n_earth, s_count, tx, ty, dz_row, height_above, sky, earth, air, sky_haze):
    """(r, g, b, earth range) of what lies behind everything along eye ray (tx, ty, 1): the
    earth plane for n_earth of the pixel's s_count samples, the sky for the rest, each through
    the haze and the fog (sky_haze: the sky's haze share, the caller's). The earth's range is
    +inf where no sample sees it."""
    ez = dz_row[0] * tx + dz_row[1] * ty + dz_row[2]  # world z of the ray
    ray = math.sqrt(tx * tx + ty * ty + 1.0)
    fogged = air[F_ON] != 0.0
    cos_ax = fog_cos(air, tx, ty, ray) if fogged else 0.0
    er, eg, eb = earth[0], earth[1], earth[2]
    earth_range = math.inf
    if n_earth > 0:
        # Guard: ez < 0 below the horizon; at it rounding may give 0 or a tiny positive: the
        # range becomes huge, never negative.
        earth_range = ray * height_above / max(-ez, 1e-300)
        if air[0] != 0.0:
            he = haze_amount(air, earth_range, min(ez / ray, -1e-9))  # guard: ray >= 1
            er = er * (1.0 - he) + air[3] * he
            eg = eg * (1.0 - he) + air[4] * he
            eb = eb * (1.0 - he) + air[5] * he
        if fogged:
            er, eg, eb = fog_blend(air, earth_range, cos_ax, er, eg, eb)
    sr = sky[0] * (1.0 - sky_haze) + air[3] * sky_haze
    sg = sky[1] * (1.0 - sky_haze) + air[4] * sky_haze
    sb = sky[2] * (1.0 - sky_haze) + air[5] * sky_haze
    if fogged and n_earth < s_count:
        sr, sg, sb = fog_blend(air, math.inf, cos_ax, sr, sg, sb)
    fe = n_earth / s_count  # guard: a pattern has at least one sample
    return (fe * er + (1.0 - fe) * sr, fe * eg + (1.0 - fe) * sg, fe * eb + (1.0 - fe) * sb,
            earth_range)


@njit(cache=True, inline="always")
def _block_corners(x0, y0, size, m, mapping, phi_lo, dphi, span, full, theta0, dtheta, ncols):
    """Pre-image coordinates of a block's corners, and whether interpolating them misses the
    exact value at the block's centre by at most 1/50 texel."""
    c00, r00 = _map_point(x0, y0, m, mapping, phi_lo, dphi, span, full, theta0, dtheta)
    c10, r10 = _map_point(x0 + size, y0, m, mapping, phi_lo, dphi, span, full, theta0, dtheta)
    c01, r01 = _map_point(x0, y0 + size, m, mapping, phi_lo, dphi, span, full, theta0, dtheta)
    c11, r11 = _map_point(x0 + size, y0 + size, m, mapping, phi_lo, dphi, span, full, theta0,
                          dtheta)
    cm, rm = _map_point(x0 + 0.5 * size, y0 + 0.5 * size, m, mapping, phi_lo, dphi, span, full,
                        theta0, dtheta)
    if full:
        # Unwrap the corners around the first one (the columns are periodic).
        c10 -= ncols * round((c10 - c00) / ncols)
        c01 -= ncols * round((c01 - c00) / ncols)
        c11 -= ncols * round((c11 - c00) / ncols)
        cm -= ncols * round((cm - c00) / ncols)
    ok = (abs(0.25 * (c00 + c10 + c01 + c11) - cm) <= 0.02
          and abs(0.25 * (r00 + r10 + r01 + r11) - rm) <= 0.02)
    return ok, c00, c10, c01, c11, r00, r10, r01, r11


@njit(cache=True)
def _warp_block(x0, y0, size, exact, c00, c10, c01, c11, r00, r10, r01, r11, pre, full, phi_lo, dphi, theta0, dtheta, m, mapping, offsets, width, height, kx, ky,
                k0, dz_row, height_above, sky, earth, air, sky_haze, sky_haze_t0, sky_haze_dt,
                margin_m, cloud_on, cloud_pre, cloud_col_ratio, cloud_row_ratio, depth_tile,
                tiles_x, depth_need, ncols, nrows, span, s_count, inv_sxs, inv_sys,
                out_rgb, out_iz, out_range, out_cloud):
    """The pixels of one size x size block of warp_kernel, their pre-image coordinates
    interpolated from the block's corners, or each mapped exactly."""
    inv_b = 1.0 / size
    for y in range(y0, min(y0 + size, height)):
        for x in range(x0, min(x0 + size, width)):
            # The pixel centre: colour and range of the terrain.
            sx = x + 0.5
            sy = y + 0.5
            c, rr = _block_point(sx, sy, exact, x0, y0, inv_b, c00, c10, c01, c11, r00,
                                 r10, r01, r11, m, mapping, phi_lo, dphi, span, full,
                                 theta0, dtheta)
            c0, c1, fc = _columns(c, ncols, full)
            r0, r1, fr = _rows(rr, nrows)
            w00 = (1.0 - fc) * (1.0 - fr)
            w10 = fc * (1.0 - fr)
            w01 = (1.0 - fc) * fr
            w11 = fc * fr
            a00 = w00 * pre[c0, r0, PRE_A]
            a10 = w10 * pre[c1, r0, PRE_A]
            a01 = w01 * pre[c0, r1, PRE_A]
            a11 = w11 * pre[c1, r1, PRE_A]
            alpha = min(a00 + a10 + a01 + a11, 1.0)
            ir = 0.0
            if alpha > 0.0:
                ir = _inverse_range(pre, c0, c1, r0, r1, w00, w10, w01, w11)
            keep = 1.0 - alpha
            pr = w00 * pre[c0, r0, PRE_R] + w10 * pre[c1, r0, PRE_R] + w01 * pre[c0, r1, PRE_R] + w11 * pre[c1, r1, PRE_R]
            pg = w00 * pre[c0, r0, PRE_G] + w10 * pre[c1, r0, PRE_G] + w01 * pre[c0, r1, PRE_G] + w11 * pre[c1, r1, PRE_G]
            pb = w00 * pre[c0, r0, PRE_B] + w10 * pre[c1, r0, PRE_B] + w01 * pre[c0, r1, PRE_B] + w11 * pre[c1, r1, PRE_B]
            cr, cg, cb = pr, pg, pb
            earth_range = math.inf
            if alpha < 1.0:
                # Behind the terrain, for what it leaves uncovered: the sky and earth plane.
                # The sky's haze depends on elevation alone: from the per-row table.
                n_earth = _earth_samples(x, y, offsets, kx, ky, k0)
                hs = 0.0
                if air[0] != 0.0 and n_earth < s_count:
                    q0, q1, fq = _rows((theta0 + (rr + 0.5) * dtheta - sky_haze_t0)
                                       / sky_haze_dt - 0.5, sky_haze.shape[0])
                    hs = sky_haze[q0] + (sky_haze[q1] - sky_haze[q0]) * fq
                br, bg, bb, earth_range = _sky_and_earth(
                    n_earth, s_count, (sx - mapping[1]) * inv_sxs, (sy - mapping[3]) * inv_sys,
                    dz_row, height_above, sky, earth, air, hs)
                cr += keep * br
                cg += keep * bg
                cb += keep * bb
            nearest = earth_range
            if ir > 0.0:
                nearest = min(nearest, 1.0 / ir)  # guard: ir > 0
            out_range[y, x] = nearest
            if cloud_on:
                cr, cg, cb = _cloud_over(cloud_pre, full, c, rr, cloud_col_ratio,
                                         cloud_row_ratio, nearest, cr, cg, cb, out_cloud,
                                         y, x)
            out_rgb[y, x, 0] = cr
            out_rgb[y, x, 1] = cg
            out_rgb[y, x, 2] = cb
            # Per sample: the terrain's coverage and depth there (only near terrain).
            t = (y // depth_tile) * tiles_x + x // depth_tile
            near = (depth_need[t]
                    and (pre[c0, r0, PRE_A] > 0.0 or pre[c1, r0, PRE_A] > 0.0
                         or pre[c0, r1, PRE_A] > 0.0 or pre[c1, r1, PRE_A] > 0.0))
            for s in range(s_count):
                out_iz[y, x, s] = 0.0
                if not near:
                    continue
                qx = x + offsets[s, 0]
                qy = y + offsets[s, 1]
                c, rr = _block_point(qx, qy, exact, x0, y0, inv_b, c00, c10, c01, c11,
                                     r00, r10, r01, r11, m, mapping, phi_lo, dphi, span,
                                     full, theta0, dtheta)
                out_iz[y, x, s] = _sample_inverse_depth(
                    pre, ncols, nrows, full, c, rr, (qx - mapping[1]) * inv_sxs,
                    (qy - mapping[3]) * inv_sys, dz_row, margin_m)


@njit(cache=True, inline="always")
def _inverse_range(pre, c0, c1, r0, r1, w00, w10, w01, w11):
    """Inverse range interpolated bilinearly over the four texels that hold one (1 / range
    is nearly linear across a plane, so grazing ground interpolates well; a partly covered
    texel, and the first uncovered one above a column's last surface, hold that surface
    continued, so edges interpolate too; texels never reached hold 0 and are left out)."""
    num = 0.0
    den = 0.0
    if pre[c0, r0, PRE_IR] != 0.0:
        num += w00 * pre[c0, r0, PRE_IR]
        den += w00
    if pre[c1, r0, PRE_IR] != 0.0:
        num += w10 * pre[c1, r0, PRE_IR]
        den += w10
    if pre[c0, r1, PRE_IR] != 0.0:
        num += w01 * pre[c0, r1, PRE_IR]
        den += w01
    if pre[c1, r1, PRE_IR] != 0.0:
        num += w11 * pre[c1, r1, PRE_IR]
        den += w11
    return num / den if den > 0.0 else 0.0  # guard: den > 0


@njit(cache=True, inline="always")
def _sample_inverse_depth(pre, ncols, nrows, full, c, rr, tx, ty, dz_row, margin_m):
    """1/z a polygon must exceed to be seen in front of the terrain at one sample (pre-image
    coordinates c, rr; eye ray (tx, ty, 1)), or 0 where the terrain covers less than half of
    it. The terrain is pushed back by margin_m of height, i.e. margin_m / sin(depression) of
    range (the sine floored at 1e-3, at most 1000 margins), so a polygon lying on the terrain
    (a runway on its pad) wins against terrain rounded by interpolation."""
    c0, c1, fc = _columns(c, ncols, full)
    r0, r1, fr = _rows(rr, nrows)
    a00 = (1.0 - fc) * (1.0 - fr) * pre[c0, r0, PRE_A]
    a10 = fc * (1.0 - fr) * pre[c1, r0, PRE_A]
    a01 = (1.0 - fc) * fr * pre[c0, r1, PRE_A]
    a11 = fc * fr * pre[c1, r1, PRE_A]
    cover = a00 + a10 + a01 + a11
    if cover < 0.5:
        return 0.0
    ir = _inverse_range(pre, c0, c1, r0, r1, (1.0 - fc) * (1.0 - fr), fc * (1.0 - fr),
                        (1.0 - fc) * fr, fc * fr)
    if ir <= 0.0:
        return 0.0
    ray = math.sqrt(tx * tx + ty * ty + 1.0)
    sin_el = (dz_row[0] * tx + dz_row[1] * ty + dz_row[2]) / ray  # guard: ray >= 1
    push = margin_m / max(-sin_el, 1e-3) if sin_el < 0.0 else margin_m
    return ray / (1.0 / ir + push)  # guard: ir > 0


@njit(cache=True, inline="always")
def _block_point(sx, sy, exact, x0, y0, inv_b, c00, c10, c01, c11, r00, r10, r01, r11, m, mapping,
                 phi_lo, dphi, span, full, theta0, dtheta):
    """Pre-image coordinates of screen point (sx, sy) in the block with top-left (x0, y0):
    exact, or interpolated from the block's corners."""
    if exact:
        return _map_point(sx, sy, m, mapping, phi_lo, dphi, span, full, theta0, dtheta)
    fx = (sx - x0) * inv_b
    fy = (sy - y0) * inv_b
    c = (1.0 - fy) * ((1.0 - fx) * c00 + fx * c10) + fy * ((1.0 - fx) * c01 + fx * c11)
    rr = (1.0 - fy) * ((1.0 - fx) * r00 + fx * r10) + fy * ((1.0 - fx) * r01 + fx * r11)
    return c, rr


@njit(cache=True, inline="always")
def _cloud_over(cloud_pre, full, c, rr, col_ratio, row_ratio, behind, r, g, b, out_cloud, y, x):
    """Interpolate the coarse cloud image at pre-image coordinates (c, rr), keep it for the
    pixel, and lay it over colour (r, g, b) if what that colour shows lies beyond the cloud's
    entry range (behind, metres)."""
    ncc = cloud_pre.shape[0]
    nrc = cloud_pre.shape[1]
    c0, c1, fc = _columns((c + 0.5) / col_ratio - 0.5, ncc, full)  # guard: ratios > 0
    r0, r1, fr = _rows((rr + 0.5) / row_ratio - 0.5, nrc)
    w00 = (1.0 - fc) * (1.0 - fr)
    w10 = fc * (1.0 - fr)
    w01 = (1.0 - fc) * fr
    w11 = fc * fr
    a00 = w00 * cloud_pre[c0, r0, 3]
    a10 = w10 * cloud_pre[c1, r0, 3]
    a01 = w01 * cloud_pre[c0, r1, 3]
    a11 = w11 * cloud_pre[c1, r1, 3]
    alpha = a00 + a10 + a01 + a11
    entry = math.inf
    if alpha > 0.0:
        # Entry range weighted by opacity, over the texels that have cloud (finite entry).
        num = 0.0
        den = 0.0
        if a00 > 0.0:
            num += a00 * cloud_pre[c0, r0, 4]
            den += a00
        if a10 > 0.0:
            num += a10 * cloud_pre[c1, r0, 4]
            den += a10
        if a01 > 0.0:
            num += a01 * cloud_pre[c0, r1, 4]
            den += a01
        if a11 > 0.0:
            num += a11 * cloud_pre[c1, r1, 4]
            den += a11
        entry = num / den  # guard: den = alpha > 0
    out_cloud[y, x, 0] = w00 * cloud_pre[c0, r0, 0] + w10 * cloud_pre[c1, r0, 0] + w01 * cloud_pre[c0, r1, 0] + w11 * cloud_pre[c1, r1, 0]
    out_cloud[y, x, 1] = w00 * cloud_pre[c0, r0, 1] + w10 * cloud_pre[c1, r0, 1] + w01 * cloud_pre[c0, r1, 1] + w11 * cloud_pre[c1, r1, 1]
    out_cloud[y, x, 2] = w00 * cloud_pre[c0, r0, 2] + w10 * cloud_pre[c1, r0, 2] + w01 * cloud_pre[c0, r1, 2] + w11 * cloud_pre[c1, r1, 2]
    out_cloud[y, x, 3] = alpha
    out_cloud[y, x, 4] = entry
    if alpha > 0.0 and behind > entry:
        keep = 1.0 - alpha
        return (out_cloud[y, x, 0] + keep * r, out_cloud[y, x, 1] + keep * g,
                out_cloud[y, x, 2] + keep * b)
    return r, g, b


@njit(cache=True, inline="always")
def _columns(c, ncols, full):
    """Neighbouring columns of pre-image coordinate c and the weight of the second."""
    ci = int(math.floor(c))
    if full:
        return ci % ncols, (ci + 1) % ncols, c - ci
    return min(max(ci, 0), ncols - 1), min(max(ci + 1, 0), ncols - 1), c - ci


@njit(cache=True, inline="always")
def _rows(r, nrows):
    """Neighbouring rows of pre-image coordinate r (clamped) and the weight of the second."""
    ri = int(math.floor(r))
    return min(max(ri, 0), nrows - 1), min(max(ri + 1, 0), nrows - 1), r - ri
