"""numba kernel of the per-sample terrain depth (background.py): 1/z of the terrain at every
sample the visibility stage tests polygons against, from the cast's per-pixel coverage and
1/z (_cast_kernels), only in the sub-areas that hold polygons.

1/z is affine in screen space across a plane, so interpolating it bilinearly between pixel
centres is exact for planar ground and close across the bilinear voxel surface; a sample is
the terrain's where the interpolated coverage is at least one half, so a hill's silhouette
against a polygon behind it keeps the samples' resolution.
"""

from __future__ import annotations

import math

from numba import njit, prange

from channel_worker.pipeline.jit import borrowing, claim, lanes, new_queue


@njit(cache=True, parallel=True)
def sample_depth_kernel(frame, aux, depth, out_inv_z, threads):
    """1/z of the terrain pushed back by the polygon margin at every sample of the sub-areas
    that want it (depth.need), where the terrain covers the sample; 0 elsewhere (sky and
    earth never hide a polygon, and sub-areas without polygons are never tested: zeroed here,
    by the threads, rather than by a serial memset or fresh pages each frame).

    Args:
        frame: the frame's constants (FrameConstants: offsets, mapping, dz_row).
        aux: the cast's per-pixel coverage and 1/z (CastPixels).
        depth: where depth is wanted and the polygon margin (SampleDepth).
        out_inv_z: (H, W, S) float32.
        threads: numba.get_num_threads() (jit.lanes).
    """
    tile = depth.tile
    tiles_x = (frame.width + tile - 1) // tile
    tiles_y = (frame.height + tile - 1) // tile
    # Rows of sub-areas from a queue (jit.lanes): a row under the polygons costs a depth per
    # sample, one without them a store of zeros.
    n_lanes = lanes(threads, tiles_y)
    queue = new_queue()
    for _lane in prange(n_lanes):
        while True:
            ty = claim(queue)
            if ty >= tiles_y:
                break
            for tx in range(tiles_x):
                if depth.need[ty * tiles_x + tx]:
                    _tile(frame, aux, depth, out_inv_z, tx * tile, ty * tile)
                else:
                    _zero_tile(frame, depth, out_inv_z, tx * tile, ty * tile)


@borrowing
def _zero_tile(frame, depth, out_inv_z, x0, y0):
    """0 at every sample of the sub-area whose top-left pixel is (x0, y0)."""
    for y in range(y0, min(y0 + depth.tile, frame.height)):
        for x in range(x0, min(x0 + depth.tile, frame.width)):
            for s in range(out_inv_z.shape[2]):
                out_inv_z[y, x, s] = 0.0


@borrowing
def _tile(frame, aux, depth, out_inv_z, x0, y0):
    """The samples of the sub-area whose top-left pixel is (x0, y0)."""
    w = frame.width
    h = frame.height
    px = aux.pixels
    offsets = frame.offsets
    n_s = offsets.shape[0]
    m = frame.mapping
    dz = frame.dz_row
    inv_sxs = 1.0 / m[0]  # guard: screen_mapping's scales are nonzero
    inv_sys = 1.0 / m[2]
    margin = depth.margin_m
    for y in range(y0, min(y0 + depth.tile, h)):
        ty = (y + 0.5 - m[3]) * inv_sys
        for x in range(x0, min(x0 + depth.tile, w)):
            for s in range(n_s):
                out_inv_z[y, x, s] = 0.0
            # A sample's four neighbouring pixel centres lie among the 3 x 3 around its own;
            # none covered: nothing to interpolate (most pixels of a sub-area under sky).
            near = False
            for yy in range(max(y - 1, 0), min(y + 2, h)):
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    if px[yy, xx, 0] > 0.0:
                        near = True
            if not near:
                continue
            # The eye ray's length and world z at the pixel centre, and across it to first
            # order (z is linear in the screen; the length's second-order term is ~1e-7
            # relative at a pixel's angle).
            tx = (x + 0.5 - m[1]) * inv_sxs
            ray = math.sqrt(tx * tx + ty * ty + 1.0)
            grad_x = tx / ray * inv_sxs  # guard: ray >= 1
            grad_y = ty / ray * inv_sys
            wz = dz[0] * tx + dz[1] * ty + dz[2]
            for s in range(n_s):
                ox = offsets[s, 0] - 0.5
                oy = offsets[s, 1] - 0.5
                # The cell of pixel centres around the sample; at the image's border the
                # nearest cell, extrapolated (1/z stays affine, as it is across a plane).
                gx = x + ox
                gy = y + oy
                xa = min(max(int(math.floor(gx)), 0), max(w - 2, 0))
                ya = min(max(int(math.floor(gy)), 0), max(h - 2, 0))
                fx = gx - xa
                fy = gy - ya
                xb = min(xa + 1, w - 1)
                yb = min(ya + 1, h - 1)
                w00 = (1.0 - fx) * (1.0 - fy)
                w10 = fx * (1.0 - fy)
                w01 = (1.0 - fx) * fy
                w11 = fx * fy
                if (w00 * px[ya, xa, 0] + w10 * px[ya, xb, 0] + w01 * px[yb, xa, 0]
                        + w11 * px[yb, xb, 0]) < 0.5:
                    continue
                # 1/z over the pixels that hold one (a pixel the terrain never reached holds
                # 0 and is left out).
                num = 0.0
                den = 0.0
                if px[ya, xa, 1] != 0.0:
                    num += w00 * px[ya, xa, 1]
                    den += w00
                if px[ya, xb, 1] != 0.0:
                    num += w10 * px[ya, xb, 1]
                    den += w10
                if px[yb, xa, 1] != 0.0:
                    num += w01 * px[yb, xa, 1]
                    den += w01
                if px[yb, xb, 1] != 0.0:
                    num += w11 * px[yb, xb, 1]
                    den += w11
                if den <= 0.0 or num <= 0.0:
                    continue
                inv = num / den  # guard: den > 0
                ray_s = ray + ox * grad_x + oy * grad_y
                wz_s = wz + (ox * dz[0] * inv_sxs + oy * dz[1] * inv_sys)
                # The terrain pushed back by the margin of height: margin / sin(depression) of
                # range, the sine floored at 1e-3 (at most 1000 margins), so a polygon lying on
                # the terrain (a runway on its pad) wins against terrain rounded by
                # interpolation. z + push / ray, as 1/z: inv d / (d + inv margin) with d the
                # depression's sine times the ray's length (1 above the horizon); guard: the
                # denominator is > 0 (d > 0, inv > 0, margin >= 0).
                d = max(-wz_s, 1e-3 * ray_s) if wz_s < 0.0 else ray_s
                out_inv_z[y, x, s] = inv * d / (d + inv * margin)
