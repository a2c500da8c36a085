"""numba kernels for the resolve stage (see resolve.py)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID, F_ON
from channel_worker.pipeline.fog.fog import fog_cos

from .shading import through_air


@njit(cache=True, inline="always")
def _polygon_colour(p, y, x, s, colour, air, inv_z, sxs, sys_, tx, ty, dz_row, cloud_on, cloud):
    """Colour of polygon p at sample s of pixel (x, y); with haze or fog (air: air.air_params)
    seen through it at the polygon's range there (1/z from its exact depth plane), and through the pixel's
    cloud if that range lies beyond the cloud's entry range."""
    r, g, b = colour[p, 0], colour[p, 1], colour[p, 2]
    if air[0] == 0.0 and air[F_ON] == 0.0 and not cloud_on:
        return r, g, b
    a = tx[x, s]
    c = ty[y, s]
    ray = math.sqrt(a * a + c * c + 1.0)
    iz = inv_z[p, 0] * sxs[x, s] + (inv_z[p, 1] * sys_[y, s] + inv_z[p, 2])
    # Guards: polygons are clipped to z >= near > 0 (1/z > 0); ray >= 1.
    return through_air(air, cloud_on, cloud, y, x, ray / max(iz, 1e-300),
                       (dz_row[0] * a + dz_row[1] * c + dz_row[2]) / ray,
                       fog_cos(air, a, c, ray), r, g, b)


@njit(cache=True, inline="always")
def _shade(y, x, s, opaque, trans, count, colour, opacity, sky, earth, bg_rgb, air, inv_z, sxs,
           sys_, tx, ty, dz_row, cloud_on, cloud):
    """Linear RGB of one sample: its translucent features front to back over the opaque one,
    each seen through the air (haze, fog) at its own range."""
    r = np.float32(0.0)
    g = np.float32(0.0)
    b = np.float32(0.0)
    through = np.float32(1.0)
    for q in range(count[y, x, s]):
        p = trans[y, x, s, q]
        a = opacity[p] * through
        cr, cg, cb = _polygon_colour(p, y, x, s, colour, air, inv_z, sxs, sys_, tx, ty, dz_row,
                                     cloud_on, cloud)
        r += a * cr
        g += a * cg
        b += a * cb
        through *= np.float32(1.0) - opacity[p]
    f = opaque[y, x, s]
    if f >= 0:
        cr, cg, cb = _polygon_colour(f, y, x, s, colour, air, inv_z, sxs, sys_, tx, ty, dz_row,
                                     cloud_on, cloud)
        return r + through * cr, g + through * cg, b + through * cb
    if f == BACKGROUND_ID:
        return r + through * bg_rgb[y, x, 0], g + through * bg_rgb[y, x, 1], b + through * bg_rgb[y, x, 2]
    if f == EARTH_ID:
        return r + through * earth[0], g + through * earth[1], b + through * earth[2]
    return r + through * sky[0], g + through * sky[1], b + through * sky[2]


@njit(cache=True, inline="always")
def _pixel_range(y, x, opaque, polygon_range, tx, ty, dz_row, height_above, bg_range):
    """Nearest surface seen by the pixel: its nearest polygon or, nearer, the earth plane.

    Range to the earth along the ray (tx, ty, 1): |ray| * height_above / -dz; dz < 0 for
    every earth sample (visibility decided so) except by rounding right at the horizon, where
    the divisor is clamped to a tiny positive value (range -> huge, never negative).
    """
    nearest = polygon_range[y, x]
    for s in range(opaque.shape[2]):
        if opaque[y, x, s] == BACKGROUND_ID:
            nearest = min(nearest, bg_range[y, x])
        elif opaque[y, x, s] == EARTH_ID:
            a = tx[x, s]
            c = ty[y, s]
            dz = dz_row[0] * a + dz_row[1] * c + dz_row[2]
            nearest = min(nearest, math.sqrt(a * a + c * c + 1.0) * height_above / max(-dz, 1e-300))
    return nearest


@njit(cache=True, parallel=True)
def box_kernel(opaque, trans, count, polygon_range, colour, opacity, sky, earth, tx, ty, dz_row,
               height_above, want_range, bg_rgb, bg_range, air, inv_z, sxs, sys_, cloud_on,
               cloud, out_rgb, out_range):
    """Shade and average the samples of each pixel in one pass (no sample colour buffer).

    A pixel whose samples all see one feature and nothing translucent (most pixels) takes that
    feature's colour without a per-sample sum.
    """
    h, w, s_count = opaque.shape
    inv_s = np.float32(1.0 / s_count)
    for y in prange(h):
        for x in range(w):
            f0 = opaque[y, x, 0]
            uniform = True
            for s in range(s_count):
                if opaque[y, x, s] != f0 or count[y, x, s] != 0:
                    uniform = False
                    break
            if uniform and (air[0] != 0.0 or air[F_ON] != 0.0 or cloud_on or f0 == BACKGROUND_ID):
                uniform = False  # hazed colours vary per sample; the background per pixel
            if uniform:
                if f0 >= 0:
                    out_rgb[y, x, 0] = colour[f0, 0]
                    out_rgb[y, x, 1] = colour[f0, 1]
                    out_rgb[y, x, 2] = colour[f0, 2]
                else:
                    bg = earth if f0 == EARTH_ID else sky
                    out_rgb[y, x, 0] = bg[0]
                    out_rgb[y, x, 1] = bg[1]
                    out_rgb[y, x, 2] = bg[2]
            else:
                r = np.float32(0.0)
                g = np.float32(0.0)
                b = np.float32(0.0)
                for s in range(s_count):
                    sr, sg, sb = _shade(y, x, s, opaque, trans, count, colour, opacity, sky, earth,
                                        bg_rgb, air, inv_z, sxs, sys_, tx, ty, dz_row, cloud_on,
                                        cloud)
                    r += sr
                    g += sg
                    b += sb
                out_rgb[y, x, 0] = r * inv_s
                out_rgb[y, x, 1] = g * inv_s
                out_rgb[y, x, 2] = b * inv_s
            if want_range:
                out_range[y, x] = _pixel_range(y, x, opaque, polygon_range, tx, ty, dz_row, height_above,
                                               bg_range)


@njit(cache=True, parallel=True)
def shade_kernel(opaque, trans, count, polygon_range, colour, opacity, sky, earth, tx, ty, dz_row,
                 height_above, want_range, bg_rgb, bg_range, air, inv_z, sxs, sys_, cloud_on,
                 cloud, out_samples, out_range):
    """Every sample's colour, for filters that also read neighbouring pixels' samples."""
    h, w, s_count = opaque.shape
    for y in prange(h):
        for x in range(w):
            for s in range(s_count):
                sr, sg, sb = _shade(y, x, s, opaque, trans, count, colour, opacity, sky, earth,
                                    bg_rgb, air, inv_z, sxs, sys_, tx, ty, dz_row, cloud_on,
                                    cloud)
                out_samples[y, x, s, 0] = sr
                out_samples[y, x, s, 1] = sg
                out_samples[y, x, s, 2] = sb
            if want_range:
                out_range[y, x] = _pixel_range(y, x, opaque, polygon_range, tx, ty, dz_row, height_above,
                                               bg_range)


@njit(cache=True, parallel=True)
def filter_kernel(samples, weights, out_rgb):
    """Weighted sum of the samples of the (2R+1)^2 pixels around each pixel.

    weights[j, i, s]: weight of sample s of the pixel at offset (i - R, j - R). At the raster
    border the missing neighbours' weights are left out and the rest renormalised; the
    centre pixel's own weights are positive for every filter, so the sum is never zero.
    """
    h, w, s_count, _ = samples.shape
    radius = weights.shape[0] // 2
    for y in prange(h):
        for x in range(w):
            r = 0.0
            g = 0.0
            b = 0.0
            total = 0.0
            for j in range(-radius, radius + 1):
                yy = y + j
                if yy < 0 or yy >= h:
                    continue
                for i in range(-radius, radius + 1):
                    xx = x + i
                    if xx < 0 or xx >= w:
                        continue
                    for s in range(s_count):
                        wt = weights[j + radius, i + radius, s]
                        if wt == 0.0:
                            continue
                        r += wt * samples[yy, xx, s, 0]
                        g += wt * samples[yy, xx, s, 1]
                        b += wt * samples[yy, xx, s, 2]
                        total += wt
            out_rgb[y, x, 0] = r / total
            out_rgb[y, x, 1] = g / total
            out_rgb[y, x, 2] = b / total
