"""numba kernel that lays the coarse cloud image over the background (background.py): the one
resample left in the background stage, run only for a scene with clouds.

JP H07-76990's cloud frame buffer is one eighth of the ground's linear resolution and "an
interpolation stage smooths the cloud scene between coarse pixels": every pixel looks the
cloud image up at its exact azimuth and elevation, bilinearly, and where a cloud's edge
crosses the image takes the opacity from the finer samples there (clouds.py). The mapping is
computed exactly at the corners of blocks of pixels and interpolated inside (near the nadir or
zenith, where azimuth turns fast, a block's quarters, or each point exactly), and a block whose
cloud texels are all clear costs one test: under clear air the pass does nothing per pixel.

The per-row and per-block functions are compiled without reference counting (jit.borrowing).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange

from channel_worker.pipeline.jit import borrowing, claim, lanes, new_queue


class _Block(NamedTuple):
    """One block: its top-left pixel (x0, y0), its size in pixels (inv_size = 1 / size), and
    how its points map to the cloud image: exactly, or bilinearly from the cloud coordinates
    of its corners (cols, rows: top-left, top-right, bottom-left, bottom-right)."""

    x0: int
    y0: int
    size: int
    inv_size: float
    exact: bool
    cols: tuple
    rows: tuple


@borrowing
def _map_point(sx, sy, frame, clouds):
    """Cloud image coordinates (column, row; texel centres at integers) of screen point
    (sx, sy) (pixels)."""
    m = frame.world_to_eye
    mapping = frame.mapping
    tx = (sx - mapping[1]) / mapping[0]  # guard: screen_mapping's scales are nonzero
    ty = (sy - mapping[3]) / mapping[2]
    wx = m[0, 0] * tx + m[1, 0] * ty + m[2, 0]
    wy = m[0, 1] * tx + m[1, 1] * ty + m[2, 1]
    wz = m[0, 2] * tx + m[1, 2] * ty + m[2, 2]
    theta = math.atan2(wz, math.sqrt(wx * wx + wy * wy))
    rel = math.atan2(wx, wy) - clouds.phi_lo
    rel -= 2.0 * math.pi * math.floor(rel / (2.0 * math.pi))  # into [0, 2 pi)
    if not clouds.full and rel > 0.5 * (clouds.span + 2.0 * math.pi):
        rel -= 2.0 * math.pi  # just left of the range, not far right of it
    # Guard: the grid's steps are > 0 (cloud_grid).
    return rel / clouds.dphi - 0.5, (theta - clouds.theta0) / clouds.dtheta - 0.5


@njit(cache=True, parallel=True)
def cloud_over_kernel(frame, clouds, block, range_m, rgb, out_cloud, threads):
    """Lay the cloud image (CloudImage) over every pixel whose background lies beyond the
    cloud's entry range (range_m), and keep each pixel's cloud (premultiplied RGB, opacity,
    entry range) in out_cloud for the polygons.

    Args:
        frame: the frame's constants.
        clouds: the coarse cloud image (CloudImage).
        block: pixels per side of the blocks mapped at their corners.
        range_m: (H, W) float32 the background's range (the cast's or the earth plane's).
        rgb: (H, W, 3) float32 the background's colour, clouds laid over it in place.
        out_cloud: (H, W, 5) float32.
        threads: numba.get_num_threads() (jit.lanes).
    """
    blocks_y = (frame.height + block - 1) // block
    # Rows of blocks from a queue (jit.lanes): rows where the cloud lies over the background
    # cost more than clear ones.
    n_lanes = lanes(threads, blocks_y)
    queue = new_queue()
    for _lane in prange(n_lanes):
        while True:
            by = claim(queue)
            if by >= blocks_y:
                break
            _row_of_blocks(frame, clouds, block, range_m, rgb, out_cloud, by * block)


@borrowing
def _row_of_blocks(frame, clouds, block, range_m, rgb, out_cloud, y0):
    """The blocks of cloud_over_kernel whose top row is y0."""
    blocks_x = (frame.width + block - 1) // block
    for bx in range(blocks_x):
        x0 = bx * block
        ok, cols, rows = _block_corners(x0, y0, block, frame, clouds)
        if ok:
            _over_block(frame, clouds, range_m, rgb, out_cloud,
                        _Block(x0, y0, block, 1.0 / block, False, cols, rows))
            continue
        # Mapping too curved for the block (near the nadir or zenith): its quarters, each
        # interpolated if it can be, else mapped point by point.
        half = block // 2
        for q in range(4):
            qx0 = x0 + (q % 2) * half
            qy0 = y0 + (q // 2) * half
            ok, cols, rows = _block_corners(qx0, qy0, half, frame, clouds)
            _over_block(frame, clouds, range_m, rgb, out_cloud,
                        _Block(qx0, qy0, half, 1.0 / half, not ok, cols, rows))


@borrowing
def _block_corners(x0, y0, size, frame, clouds):
    """Cloud coordinates of a block's corners (columns, rows), and whether interpolating
    them misses the exact value at the block's centre by at most 1/50 texel."""
    c00, r00 = _map_point(x0, y0, frame, clouds)
    c10, r10 = _map_point(x0 + size, y0, frame, clouds)
    c01, r01 = _map_point(x0, y0 + size, frame, clouds)
    c11, r11 = _map_point(x0 + size, y0 + size, frame, clouds)
    cm, rm = _map_point(x0 + 0.5 * size, y0 + 0.5 * size, frame, clouds)
    if clouds.full:
        # Unwrap the corners around the first one (the columns are periodic).
        ncols = clouds.texels.shape[0]
        c10 -= ncols * round((c10 - c00) / ncols)
        c01 -= ncols * round((c01 - c00) / ncols)
        c11 -= ncols * round((c11 - c00) / ncols)
        cm -= ncols * round((cm - c00) / ncols)
    ok = (abs(0.25 * (c00 + c10 + c01 + c11) - cm) <= 0.02
          and abs(0.25 * (r00 + r10 + r01 + r11) - rm) <= 0.02)
    return ok, (c00, c10, c01, c11), (r00, r10, r01, r11)


@borrowing
def _over_block(frame, clouds, range_m, rgb, out_cloud, blk):
    """The pixels of one block (blk: _Block)."""
    if not blk.exact and clear_air(clouds, blk.cols, blk.rows):
        # Clear air over the whole block (most blocks, even under a broken layer).
        for y in range(blk.y0, min(blk.y0 + blk.size, frame.height)):
            for x in range(blk.x0, min(blk.x0 + blk.size, frame.width)):
                _clear_cloud(out_cloud, y, x)
        return
    for y in range(blk.y0, min(blk.y0 + blk.size, frame.height)):
        for x in range(blk.x0, min(blk.x0 + blk.size, frame.width)):
            c, rr = _block_point(x + 0.5, y + 0.5, blk, frame, clouds)
            r, g, b = _cloud_over(clouds, c, rr, range_m[y, x],
                                  (rgb[y, x, 0], rgb[y, x, 1], rgb[y, x, 2]), out_cloud, y, x)
            rgb[y, x, 0] = r
            rgb[y, x, 1] = g
            rgb[y, x, 2] = b


@borrowing
def clear_air(clouds, cols, rows):
    """Whether every cloud texel an interpolated block's pixel centres can read (_cloud_over:
    the two columns and rows around each point, over the texel box of the block's corners,
    which bounds its bilinear interior) has opacity 0 and no quad there is sampled finer (a
    quad the edge reached can hold cloud between clear corners, clouds.seam_quads). False for
    a box wider than 8 texels."""
    texels = clouds.texels
    ncc = texels.shape[0]
    nrc = texels.shape[1]
    c_lo, c_hi = _texel_box(cols)
    r_lo, r_hi = _texel_box(rows)
    c_hi += 1
    r_hi += 1
    if c_hi - c_lo > 8 or r_hi - r_lo > 8:
        return False
    for c in range(c_lo, c_hi + 1):
        cc = _column(c, ncc, clouds.full)
        for r in range(_row(r_lo, nrc), _row(r_hi, nrc) + 1):
            # The quad at the clamped (column, row): that quad itself, or, past the image's
            # border, one the pixels cannot read (a needless False at worst).
            if texels[cc, r, 3] != 0.0 or clouds.quad[cc, r] >= 0:
                return False
    return True


#: Margin of _texel_box, relative to the coordinates' size: a pixel's coordinate interpolated
#: between the corners can round past them by a few ulps (corners -1 and -5e-324 interpolate
#: to -0.0, whose floor is a row above the corners'), and the box must still hold it.
_BOX_MARGIN = 1e-9


@njit(cache=True, inline="always")
def _texel_box(corners):
    """The lowest and highest texel index (floor) the four corner coordinates and any point
    interpolated between them (rounding included) can have."""
    lo = min(min(corners[0], corners[1]), min(corners[2], corners[3]))
    hi = max(max(corners[0], corners[1]), max(corners[2], corners[3]))
    margin = _BOX_MARGIN * (1.0 + max(abs(lo), abs(hi)))
    return int(math.floor(lo - margin)), int(math.floor(hi + margin))


@njit(cache=True, inline="always")
def _clear_cloud(out_cloud, y, x):
    """Pixel (x, y) sees no cloud: premultiplied colour and opacity 0, no entry range."""
    for ch in range(4):
        out_cloud[y, x, ch] = 0.0
    out_cloud[y, x, 4] = math.inf


@njit(cache=True, inline="always")
def _block_point(sx, sy, blk, frame, clouds):
    """Cloud coordinates of screen point (sx, sy) in block blk: exact, or interpolated from
    the block's corners."""
    if blk.exact:
        return _map_point(sx, sy, frame, clouds)
    c00, c10, c01, c11 = blk.cols
    r00, r10, r01, r11 = blk.rows
    fx = (sx - blk.x0) * blk.inv_size
    fy = (sy - blk.y0) * blk.inv_size
    c = (1.0 - fy) * ((1.0 - fx) * c00 + fx * c10) + fy * ((1.0 - fx) * c01 + fx * c11)
    rr = (1.0 - fy) * ((1.0 - fx) * r00 + fx * r10) + fy * ((1.0 - fx) * r01 + fx * r11)
    return c, rr


@njit(cache=True, inline="always")
def _cloud_over(clouds, c, rr, behind, rgb, out_cloud, y, x):
    """Interpolate the cloud image at (c, rr), keep it for pixel (x, y) in out_cloud, and lay
    it over colour rgb if what that colour shows lies beyond the cloud's entry range (behind,
    metres).

    Bilinear between the four texels around (c, rr). In a quad a cloud's edge crosses
    (CloudImage.quad) the opacity and the entry range are bilinear between the four of its
    fine samples around (c, rr) instead, so the edge is as sharp as the pixels; the colour
    keeps the coarse texels' (their premultiplied colour over their opacity, scaled to the
    fine opacity): inside the cloud it stays as blurry as JP H07-76990's coarse image, and it
    meets the coarse quads beside without a seam. Where none of the four texels has cloud
    (a quad the edge reached, clouds.seam_quads) the fine samples' own colour is taken."""
    texels = clouds.texels
    ncc = texels.shape[0]
    nrc = texels.shape[1]
    ci = int(math.floor(c))
    ri = int(math.floor(rr))
    c0 = _column(ci, ncc, clouds.full)
    c1 = _column(ci + 1, ncc, clouds.full)
    r0 = _row(ri, nrc)
    r1 = _row(ri + 1, nrc)
    s00 = texels[c0, r0]
    s10 = texels[c1, r0]
    s01 = texels[c0, r1]
    s11 = texels[c1, r1]
    cr, cg, cb, alpha, entry = _bilinear5(s00, s10, s01, s11, c - ci, rr - ri)
    t = _quad(clouds, ci, ri)
    if t >= 0:
        fine = clouds.fine
        f = fine.shape[1] - 1
        fx = (c - ci) * f
        fy = (rr - ri) * f
        fa = min(int(fx), f - 1)  # c - ci < 1, but (c - ci) * f can round up to f
        fb = min(int(fy), f - 1)
        fr, fg, fbl, fine_alpha, entry = _bilinear5(fine[t, fa, fb], fine[t, fa + 1, fb],
                                                    fine[t, fa, fb + 1],
                                                    fine[t, fa + 1, fb + 1], fx - fa, fy - fb)
        corners = s00[3] + s10[3] + s01[3] + s11[3]
        if corners <= 0.0:
            cr, cg, cb = fr, fg, fbl  # the fine samples carry colour (CloudQuads.shaded)
        else:
            if alpha <= 0.0:
                # On the quad's side away from its cloudy corners: their colour, unweighted.
                cr = s00[0] + s10[0] + s01[0] + s11[0]
                cg = s00[1] + s10[1] + s01[1] + s11[1]
                cb = s00[2] + s10[2] + s01[2] + s11[2]
                alpha = corners
            scale = fine_alpha / alpha  # guard: alpha > 0
            cr *= scale
            cg *= scale
            cb *= scale
        alpha = fine_alpha
    if alpha <= 0.0:
        _clear_cloud(out_cloud, y, x)
        return rgb
    out_cloud[y, x, 0] = cr
    out_cloud[y, x, 1] = cg
    out_cloud[y, x, 2] = cb
    out_cloud[y, x, 3] = alpha
    out_cloud[y, x, 4] = entry
    r, g, b = rgb
    if behind > entry:
        keep = 1.0 - alpha
        return (out_cloud[y, x, 0] + keep * r, out_cloud[y, x, 1] + keep * g,
                out_cloud[y, x, 2] + keep * b)
    return r, g, b


@njit(cache=True, inline="always")
def _bilinear5(s00, s10, s01, s11, fc, fr):
    """Four cloud samples (CLOUD_CHANNELS each: left and right below, left and right above)
    interpolated at (fc, fr) in 0..1: premultiplied red, green, blue, opacity, and the entry
    range weighted by opacity over the samples that have cloud (finite entry; +inf where the
    opacity is 0)."""
    w00 = (1.0 - fc) * (1.0 - fr)
    w10 = fc * (1.0 - fr)
    w01 = (1.0 - fc) * fr
    w11 = fc * fr
    a00 = w00 * s00[3]
    a10 = w10 * s10[3]
    a01 = w01 * s01[3]
    a11 = w11 * s11[3]
    alpha = a00 + a10 + a01 + a11
    num = 0.0
    if a00 > 0.0:
        num += a00 * s00[4]
    if a10 > 0.0:
        num += a10 * s10[4]
    if a01 > 0.0:
        num += a01 * s01[4]
    if a11 > 0.0:
        num += a11 * s11[4]
    entry = num / alpha if alpha > 0.0 else math.inf  # guard: alpha > 0
    return (w00 * s00[0] + w10 * s10[0] + w01 * s01[0] + w11 * s11[0],
            w00 * s00[1] + w10 * s10[1] + w01 * s01[1] + w11 * s11[1],
            w00 * s00[2] + w10 * s10[2] + w01 * s01[2] + w11 * s11[2], alpha, entry)


@njit(cache=True, inline="always")
def _quad(clouds, ci, ri):
    """The index in clouds.fine of quad (ci, ri) (CloudImage), or -1: not refined, or past the
    image's rows (or its columns, unless they wrap), where the texels are clamped."""
    quad = clouds.quad
    ncc = quad.shape[0]
    if ri < 0 or ri >= quad.shape[1] - 1:
        return -1
    if clouds.full:
        return quad[ci % ncc, ri]
    if ci < 0 or ci >= ncc - 1:
        return -1
    return quad[ci, ri]


@njit(cache=True, inline="always")
def _column(ci, ncols, full):
    """Column index ci of an image of ncols columns: round the circle if full, else clamped."""
    return ci % ncols if full else min(max(ci, 0), ncols - 1)


@njit(cache=True, inline="always")
def _row(ri, nrows):
    """Row index ri of an image of nrows rows, clamped."""
    return min(max(ri, 0), nrows - 1)
