"""numba kernels of the warp (background.py): every output pixel and sample from the zero-roll
pre-image, the sky and earth plane behind it, the coarse clouds over it.

The warp is JP H07-76990's rotation by the roll angle with anti-aliased resampling and its
vertical perspective correction, as one inverse mapping from screen points to pre-image
coordinates (azimuth, elevation): exact for wide and off-axis channels, so terrain seams
between channels line up like polygon seams.

The per-row and per-block functions are compiled without reference counting (jit.borrowing):
they hand the frame's groups to inlined per-pixel helpers, and numba would otherwise count
every array of a group in and out of every such call (the warp took a third longer).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange

from channel_worker.pipeline.jit import borrowing, lanes, prefetch

from ._groups import PRE_A, PRE_B, PRE_G, PRE_IR, PRE_R
from ._sky_kernels import earth_samples, sky_and_earth


class _Block(NamedTuple):
    """One block of the warp: its top-left pixel (x0, y0), its size in pixels (inv_size =
    1 / size), and how its points map to the pre-image: exactly, or bilinearly from the
    pre-image coordinates of its corners (cols: columns, rows: rows, each in the order
    top-left, top-right, bottom-left, bottom-right)."""

    x0: int
    y0: int
    size: int
    inv_size: float
    exact: bool
    cols: tuple
    rows: tuple


@borrowing
def _map_point(sx, sy, frame, pre):
    """Pre-image coordinates (column, row; texel centres at integers) of screen point (sx, sy)
    (pixels)."""
    m = frame.world_to_eye
    mapping = frame.mapping
    tx = (sx - mapping[1]) / mapping[0]
    ty = (sy - mapping[3]) / mapping[2]
    wx = m[0, 0] * tx + m[1, 0] * ty + m[2, 0]
    wy = m[0, 1] * tx + m[1, 1] * ty + m[2, 1]
    wz = m[0, 2] * tx + m[1, 2] * ty + m[2, 2]
    theta = math.atan2(wz, math.sqrt(wx * wx + wy * wy))
    rel = math.atan2(wx, wy) - pre.phi_lo
    rel -= 2.0 * math.pi * math.floor(rel / (2.0 * math.pi))  # into [0, 2 pi)
    if not pre.full and rel > 0.5 * (pre.span + 2.0 * math.pi):
        rel -= 2.0 * math.pi  # just left of the range, not far right of it
    return rel / pre.dphi - 0.5, (theta - pre.theta0) / pre.dtheta - 0.5


@njit(cache=True, parallel=True)
def warp_kernel(frame, pre, air, sky_haze, clouds, depth, block, out, threads):
    """Every output pixel and sample from the pre-image: roll, vertical perspective and the
    off-axis frustum in one inverse mapping, bilinear (anti-aliased) resampling.

    Pre-image coordinates come from the exact world direction (azimuth, elevation); they are
    computed exactly at the corners of block x block pixel blocks and interpolated inside,
    unless the interpolation misses the exact value at the block centre by more than 1/50
    texel (near the nadir or zenith, where azimuth turns fast): such a block is split in four,
    and a quarter that still misses maps every point exactly.

    Per pixel (out.rgb, at its centre): the terrain over the sky or earth plane (the share of
    the pixel's samples below the horizon sees the earth), with haze. Per sample (out.inv_z):
    1/z of the terrain pushed back by the polygon margin where the terrain covers the sample
    (coverage >= 1/2), else 0 (sky and earth never hide a polygon); so a hill's silhouette
    against a polygon behind it keeps the samples' resolution. out.range_m: the pixel's
    nearest range (the earth plane's where seen, +inf for sky). With clouds, out.cloud keeps
    the pixel's cloud (premultiplied RGB, opacity, entry range) for the polygons.

    Args:
        frame: the frame's constants (FrameConstants).
        pre: the pre-image (Preimage).
        air: the frame's air array (haze, then fog; contract.py).
        sky_haze: the sky's haze by elevation (SkyHaze).
        clouds: the coarse cloud image (CloudImage), interpolated bilinearly and laid over
            the background where the background lies beyond the cloud's entry range.
        depth: where per-sample depth is wanted, and the polygon margin (SampleDepth).
        block: pixels per side of the blocks mapped at their corners.
        out: the arrays filled (BackgroundArrays).
        threads: numba.get_num_threads() (jit.lanes).
    """
    blocks_y = (frame.height + block - 1) // block
    # A row of blocks per task, in a function of its own: numba's parallel array analysis
    # fails on the corner tuples of _block_corners inlined into the loop body.
    # Rows interleaved over the threads (jit.lanes): sky rows cost less than terrain rows.
    n_lanes = lanes(threads, blocks_y)
    for lane in prange(n_lanes):
        for by in range(lane, blocks_y, n_lanes):
            _warp_row(frame, pre, air, sky_haze, clouds, depth, block, out, by * block)


@borrowing
def _warp_row(frame, pre, air, sky_haze, clouds, depth, block, out, y0):
    """The blocks of warp_kernel whose top row is y0."""
    blocks_x = (frame.width + block - 1) // block
    # Each block's texels are asked for while the block before it is drawn (jit.prefetch).
    ok_next, cols_next, rows_next = _block_corners(0, y0, block, frame, pre)
    _prefetch_block(pre, cols_next, rows_next)
    for bx in range(blocks_x):
        x0 = bx * block
        ok, cols, rows = ok_next, cols_next, rows_next
        if bx + 1 < blocks_x:
            ok_next, cols_next, rows_next = _block_corners(x0 + block, y0, block, frame, pre)
            _prefetch_block(pre, cols_next, rows_next)
        if ok:
            _warp_block(frame, pre, air, sky_haze, clouds, depth, out,
                        _Block(x0, y0, block, 1.0 / block, False, cols, rows))
            continue
        # Mapping too curved for the block (near the nadir or zenith): its quarters, each
        # interpolated if it can be, else mapped point by point.
        half = block // 2
        for q in range(4):
            qx0 = x0 + (q % 2) * half
            qy0 = y0 + (q // 2) * half
            ok, cols, rows = _block_corners(qx0, qy0, half, frame, pre)
            _warp_block(frame, pre, air, sky_haze, clouds, depth, out,
                        _Block(qx0, qy0, half, 1.0 / half, not ok, cols, rows))


@borrowing
def _block_corners(x0, y0, size, frame, pre):
    """Pre-image coordinates of a block's corners (columns, rows), and whether interpolating
    them misses the exact value at the block's centre by at most 1/50 texel."""
    c00, r00 = _map_point(x0, y0, frame, pre)
    c10, r10 = _map_point(x0 + size, y0, frame, pre)
    c01, r01 = _map_point(x0, y0 + size, frame, pre)
    c11, r11 = _map_point(x0 + size, y0 + size, frame, pre)
    cm, rm = _map_point(x0 + 0.5 * size, y0 + 0.5 * size, frame, pre)
    if pre.full:
        # Unwrap the corners around the first one (the columns are periodic).
        ncols = pre.texels.shape[0]
        c10 -= ncols * round((c10 - c00) / ncols)
        c01 -= ncols * round((c01 - c00) / ncols)
        c11 -= ncols * round((c11 - c00) / ncols)
        cm -= ncols * round((cm - c00) / ncols)
    ok = (abs(0.25 * (c00 + c10 + c01 + c11) - cm) <= 0.02
          and abs(0.25 * (r00 + r10 + r01 + r11) - rm) <= 0.02)
    return ok, (c00, c10, c01, c11), (r00, r10, r01, r11)


@borrowing
def _prefetch_block(pre, cols, rows):
    """Ask for the pre-image texels a block reads (_texel_box of its corners, a texel more
    each way), a cache line at a time. Skipped for a block spanning more than 64 texels either
    way (near the nadir or zenith, where its corners say little)."""
    texels = pre.texels
    ncols = texels.shape[0]
    nrows = texels.shape[1]
    nch = texels.shape[2]
    c_lo, c_hi = _texel_box(cols, 1.0)
    r_lo, r_hi = _texel_box(rows, 1.0)
    c_lo -= 1
    r_lo -= 1
    c_hi += 2
    r_hi += 2
    if c_hi - c_lo > 64 or r_hi - r_lo > 64:
        return
    r_lo = _row(r_lo, nrows)
    r_hi = _row(r_hi, nrows)
    line = 16  # float32 texel values per 64-byte cache line
    for c in range(c_lo, c_hi + 1):
        cc = _column(c, ncols, pre.full)
        start = (cc * nrows + r_lo) * nch
        end = (cc * nrows + r_hi) * nch + nch - 1
        for i in range(start, end + line, line):
            prefetch(texels, min(i, end))


@borrowing
def _warp_block(frame, pre, air, sky_haze, clouds, depth, out, blk):
    """The pixels of one block of warp_kernel (blk: _Block), their pre-image coordinates
    interpolated from the block's corners, or each mapped exactly."""
    texels = pre.texels
    ncols = texels.shape[0]
    nrows = texels.shape[1]
    mapping = frame.mapping
    offsets = frame.offsets
    s_count = offsets.shape[0]
    tiles_x = (frame.width + depth.tile - 1) // depth.tile
    # Guard: screen_mapping's scales are nonzero (check_channel: left < right, bottom < top).
    inv_sxs = 1.0 / mapping[0]
    inv_sys = 1.0 / mapping[2]
    # Under clear air the cloud image is 0 over the whole block: its pixels skip the cloud's
    # interpolation (most blocks, even under a broken layer).
    clear = clouds.on and not blk.exact and _clear_air(clouds, pre.full, blk)
    for y in range(blk.y0, min(blk.y0 + blk.size, frame.height)):
        tile_row = (y // depth.tile) * tiles_x
        for x in range(blk.x0, min(blk.x0 + blk.size, frame.width)):
            # The pixel centre: colour and range of the terrain.
            sx = x + 0.5
            sy = y + 0.5
            c, rr = _block_point(sx, sy, blk, frame, pre)
            c0, c1, fc = _columns(c, ncols, pre.full)
            r0, r1, fr = _rows(rr, nrows)
            w00 = (1.0 - fc) * (1.0 - fr)
            w10 = fc * (1.0 - fr)
            w01 = (1.0 - fc) * fr
            w11 = fc * fr
            a00 = w00 * texels[c0, r0, PRE_A]
            a10 = w10 * texels[c1, r0, PRE_A]
            a01 = w01 * texels[c0, r1, PRE_A]
            a11 = w11 * texels[c1, r1, PRE_A]
            alpha = min(a00 + a10 + a01 + a11, 1.0)
            ir = 0.0
            if alpha > 0.0:
                ir = _inverse_range(texels, c0, c1, r0, r1, (w00, w10, w01, w11))
            keep = 1.0 - alpha
            cr = (w00 * texels[c0, r0, PRE_R] + w10 * texels[c1, r0, PRE_R]
                  + w01 * texels[c0, r1, PRE_R] + w11 * texels[c1, r1, PRE_R])
            cg = (w00 * texels[c0, r0, PRE_G] + w10 * texels[c1, r0, PRE_G]
                  + w01 * texels[c0, r1, PRE_G] + w11 * texels[c1, r1, PRE_G])
            cb = (w00 * texels[c0, r0, PRE_B] + w10 * texels[c1, r0, PRE_B]
                  + w01 * texels[c0, r1, PRE_B] + w11 * texels[c1, r1, PRE_B])
            earth_range = math.inf
            if alpha < 1.0:
                # Behind the terrain, for what it leaves uncovered: the sky and earth plane.
                # The sky's haze depends on elevation alone: from the per-row table.
                n_earth = earth_samples(frame, x, y)
                hs = 0.0
                if air[0] != 0.0 and n_earth < s_count:
                    table = sky_haze.table
                    q0, q1, fq = _rows((pre.theta0 + (rr + 0.5) * pre.dtheta - sky_haze.theta0)
                                       / sky_haze.dtheta - 0.5, table.shape[0])
                    hs = table[q0] + (table[q1] - table[q0]) * fq
                br, bg, bb, earth_range = sky_and_earth(
                    frame, air, n_earth, (sx - mapping[1]) * inv_sxs, (sy - mapping[3]) * inv_sys,
                    hs)
                cr += keep * br
                cg += keep * bg
                cb += keep * bb
            nearest = earth_range
            if ir > 0.0:
                nearest = min(nearest, 1.0 / ir)  # guard: ir > 0
            out.range_m[y, x] = nearest
            if clear:
                _clear_cloud(out.cloud, y, x)
            elif clouds.on:
                cr, cg, cb = _cloud_over(clouds, pre.full, c, rr, nearest, (cr, cg, cb),
                                         out.cloud, y, x)
            out.rgb[y, x, 0] = cr
            out.rgb[y, x, 1] = cg
            out.rgb[y, x, 2] = cb
            # Per sample: the terrain's coverage and depth there (only near terrain).
            near = (depth.need[tile_row + x // depth.tile]
                    and (texels[c0, r0, PRE_A] > 0.0 or texels[c1, r0, PRE_A] > 0.0
                         or texels[c0, r1, PRE_A] > 0.0 or texels[c1, r1, PRE_A] > 0.0))
            if not near:
                for s in range(s_count):
                    out.inv_z[y, x, s] = 0.0
                continue
            # Most samples fall in the same texel cell as the pixel centre: its coverage and
            # inverse ranges are read once for them all.
            cell_c = math.floor(c)
            cell_r = math.floor(rr)
            cell = (texels[c0, r0, PRE_A], texels[c1, r0, PRE_A], texels[c0, r1, PRE_A],
                    texels[c1, r1, PRE_A], texels[c0, r0, PRE_IR], texels[c1, r0, PRE_IR],
                    texels[c0, r1, PRE_IR], texels[c1, r1, PRE_IR])
            # The eye ray's length per pixel and to first order across it (the second-order
            # term is ~1e-7 relative at these pixel angles); its world z is linear in the
            # screen position, so exact.
            tx = (sx - mapping[1]) * inv_sxs
            ty = (sy - mapping[3]) * inv_sys
            ray = math.sqrt(tx * tx + ty * ty + 1.0)
            grad_x = tx / ray * inv_sxs  # d ray / d sx; guard: ray >= 1
            grad_y = ty / ray * inv_sys
            dz = frame.dz_row
            wz = dz[0] * tx + dz[1] * ty + dz[2]
            for s in range(s_count):
                qx = x + offsets[s, 0]
                qy = y + offsets[s, 1]
                cs, rs = _block_point(qx, qy, blk, frame, pre)
                if math.floor(cs) == cell_c and math.floor(rs) == cell_r:
                    ir_s = _cell_inverse_range(cell, cs - cell_c, rs - cell_r)
                else:
                    ir_s = _sample_inverse_range(pre, cs, rs)
                inv_z = 0.0
                if ir_s > 0.0:
                    ray_s = ray + (qx - sx) * grad_x + (qy - sy) * grad_y
                    wz_s = wz + (qx - sx) * dz[0] * inv_sxs + (qy - sy) * dz[1] * inv_sys
                    # The terrain pushed back by the margin of height: margin / sin(depression)
                    # of range, the sine floored at 1e-3 (at most 1000 margins), so a polygon
                    # lying on the terrain (a runway on its pad) wins against terrain rounded
                    # by interpolation. Guard: ray_s > 0.
                    push = (depth.margin_m * ray_s / max(-wz_s, 1e-3 * ray_s) if wz_s < 0.0
                            else depth.margin_m)
                    # 1/z = ray / (range + push), range = 1 / ir; guard: ir > 0, push >= 0.
                    inv_z = ray_s * ir_s / (1.0 + push * ir_s)
                out.inv_z[y, x, s] = inv_z


@borrowing
def _clear_air(clouds, full, blk):
    """Whether every cloud texel an interpolated block's pixel centres can read (_cloud_over:
    the two columns and rows around each point, over _texel_box of the block's corners, which
    bounds its bilinear interior) has opacity 0. False for a box wider than 8 texels."""
    cloud_pre = clouds.texels
    ncc = cloud_pre.shape[0]
    nrc = cloud_pre.shape[1]
    c_lo, c_hi = _texel_box(blk.cols, clouds.col_ratio)
    r_lo, r_hi = _texel_box(blk.rows, clouds.row_ratio)
    c_hi += 1
    r_hi += 1
    if c_hi - c_lo > 8 or r_hi - r_lo > 8:
        return False
    for c in range(c_lo, c_hi + 1):
        cc = _column(c, ncc, full)
        for r in range(_row(r_lo, nrc), _row(r_hi, nrc) + 1):
            if cloud_pre[cc, r, 3] != 0.0:
                return False
    return True


@njit(cache=True, inline="always")
def _texel_box(corners, ratio):
    """The lowest and highest texel index (floor) of the four corner coordinates, mapped to an
    image whose texels are ratio pre-image texels wide as _cloud_over maps them (ratio 1: the
    pre-image's own). Guard: ratio > 0 (a ratio of positive texel sizes)."""
    lo = min(min(corners[0], corners[1]), min(corners[2], corners[3]))
    hi = max(max(corners[0], corners[1]), max(corners[2], corners[3]))
    return (int(math.floor((lo + 0.5) / ratio - 0.5)), int(math.floor((hi + 0.5) / ratio - 0.5)))


@njit(cache=True, inline="always")
def _clear_cloud(out_cloud, y, x):
    """Pixel (x, y) sees no cloud: premultiplied colour and opacity 0, no entry range."""
    for ch in range(4):
        out_cloud[y, x, ch] = 0.0
    out_cloud[y, x, 4] = math.inf


@njit(cache=True, inline="always")
def _inverse_range(texels, c0, c1, r0, r1, weights):
    """Inverse range (1/metres) interpolated bilinearly, with weights (w00, w10, w01, w11),
    over the four texels (c0 | c1, r0 | r1) that hold one (1 / range is nearly linear across a
    plane, so grazing ground interpolates well; a partly covered texel, and the first
    uncovered one above a column's last surface, hold that surface continued, so edges
    interpolate too; texels never reached hold 0 and are left out)."""
    w00, w10, w01, w11 = weights
    num = 0.0
    den = 0.0
    if texels[c0, r0, PRE_IR] != 0.0:
        num += w00 * texels[c0, r0, PRE_IR]
        den += w00
    if texels[c1, r0, PRE_IR] != 0.0:
        num += w10 * texels[c1, r0, PRE_IR]
        den += w10
    if texels[c0, r1, PRE_IR] != 0.0:
        num += w01 * texels[c0, r1, PRE_IR]
        den += w01
    if texels[c1, r1, PRE_IR] != 0.0:
        num += w11 * texels[c1, r1, PRE_IR]
        den += w11
    return num / den if den > 0.0 else 0.0  # guard: den > 0


@njit(cache=True, inline="always")
def _sample_inverse_range(pre, c, rr):
    """The terrain's inverse range (1/metres) at pre-image coordinates (c, rr), or 0 where it
    covers less than half of that point."""
    texels = pre.texels
    c0, c1, fc = _columns(c, texels.shape[0], pre.full)
    r0, r1, fr = _rows(rr, texels.shape[1])
    return _cell_inverse_range((texels[c0, r0, PRE_A], texels[c1, r0, PRE_A],
                                texels[c0, r1, PRE_A], texels[c1, r1, PRE_A],
                                texels[c0, r0, PRE_IR], texels[c1, r0, PRE_IR],
                                texels[c0, r1, PRE_IR], texels[c1, r1, PRE_IR]), fc, fr)


@njit(cache=True, inline="always")
def _cell_inverse_range(cell, fc, fr):
    """_inverse_range over one texel cell whose four coverages and inverse ranges are cell
    (a00, a10, a01, a11, i00, i10, i01, i11), at fractions (fc, fr) across it; 0 where the
    terrain covers less than half of the point."""
    a00, a10, a01, a11, i00, i10, i01, i11 = cell
    w00 = (1.0 - fc) * (1.0 - fr)
    w10 = fc * (1.0 - fr)
    w01 = (1.0 - fc) * fr
    w11 = fc * fr
    if w00 * a00 + w10 * a10 + w01 * a01 + w11 * a11 < 0.5:
        return 0.0
    num = 0.0
    den = 0.0
    if i00 != 0.0:
        num += w00 * i00
        den += w00
    if i10 != 0.0:
        num += w10 * i10
        den += w10
    if i01 != 0.0:
        num += w01 * i01
        den += w01
    if i11 != 0.0:
        num += w11 * i11
        den += w11
    return num / den if den > 0.0 else 0.0  # guard: den > 0


@njit(cache=True, inline="always")
def _block_point(sx, sy, blk, frame, pre):
    """Pre-image coordinates of screen point (sx, sy) in block blk: exact, or interpolated
    from the block's corners."""
    if blk.exact:
        return _map_point(sx, sy, frame, pre)
    c00, c10, c01, c11 = blk.cols
    r00, r10, r01, r11 = blk.rows
    fx = (sx - blk.x0) * blk.inv_size
    fy = (sy - blk.y0) * blk.inv_size
    c = (1.0 - fy) * ((1.0 - fx) * c00 + fx * c10) + fy * ((1.0 - fx) * c01 + fx * c11)
    rr = (1.0 - fy) * ((1.0 - fx) * r00 + fx * r10) + fy * ((1.0 - fx) * r01 + fx * r11)
    return c, rr


@njit(cache=True, inline="always")
def _cloud_over(clouds, full, c, rr, behind, rgb, out_cloud, y, x):
    """Interpolate the coarse cloud image at pre-image coordinates (c, rr), keep it for pixel
    (x, y) in out_cloud, and lay it over colour rgb if what that colour shows lies beyond the
    cloud's entry range (behind, metres)."""
    cloud_pre = clouds.texels
    ncc = cloud_pre.shape[0]
    nrc = cloud_pre.shape[1]
    # Guard: the ratios are > 0 (ratios of positive texel sizes).
    c0, c1, fc = _columns((c + 0.5) / clouds.col_ratio - 0.5, ncc, full)
    r0, r1, fr = _rows((rr + 0.5) / clouds.row_ratio - 0.5, nrc)
    w00 = (1.0 - fc) * (1.0 - fr)
    w10 = fc * (1.0 - fr)
    w01 = (1.0 - fc) * fr
    w11 = fc * fr
    a00 = w00 * cloud_pre[c0, r0, 3]
    a10 = w10 * cloud_pre[c1, r0, 3]
    a01 = w01 * cloud_pre[c0, r1, 3]
    a11 = w11 * cloud_pre[c1, r1, 3]
    alpha = a00 + a10 + a01 + a11
    if alpha == 0.0:
        # Clear air (most pixels, even under a broken layer): premultiplied colour 0 too.
        _clear_cloud(out_cloud, y, x)
        return rgb
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
    for ch in range(3):
        out_cloud[y, x, ch] = (w00 * cloud_pre[c0, r0, ch] + w10 * cloud_pre[c1, r0, ch]
                               + w01 * cloud_pre[c0, r1, ch] + w11 * cloud_pre[c1, r1, ch])
    out_cloud[y, x, 3] = alpha
    out_cloud[y, x, 4] = entry
    r, g, b = rgb
    if alpha > 0.0 and behind > entry:
        keep = 1.0 - alpha
        return (out_cloud[y, x, 0] + keep * r, out_cloud[y, x, 1] + keep * g,
                out_cloud[y, x, 2] + keep * b)
    return r, g, b


@njit(cache=True, inline="always")
def _columns(c, ncols, full):
    """Neighbouring columns of pre-image coordinate c and the weight of the second."""
    ci = int(math.floor(c))
    return _column(ci, ncols, full), _column(ci + 1, ncols, full), c - ci


@njit(cache=True, inline="always")
def _rows(r, nrows):
    """Neighbouring rows of pre-image coordinate r (clamped) and the weight of the second."""
    ri = int(math.floor(r))
    return _row(ri, nrows), _row(ri + 1, nrows), r - ri


@njit(cache=True, inline="always")
def _column(ci, ncols, full):
    """Column index ci of an image of ncols columns: round the circle if full, else clamped."""
    return ci % ncols if full else min(max(ci, 0), ncols - 1)


@njit(cache=True, inline="always")
def _row(ri, nrows):
    """Row index ri of an image of nrows rows, clamped."""
    return min(max(ri, 0), nrows - 1)
