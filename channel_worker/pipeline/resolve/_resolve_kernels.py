"""numba kernels for the resolve stage (see resolve.py): the samples of a frame's sample store
shaded (shade.shading.shade_sample) and filtered into pixels. (The fused path's box filter,
inside one sub-area during visibility, is shade._box_kernels.box_subarea.)"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID
from channel_worker.pipeline.jit import borrowing
from channel_worker.pipeline.shade._box_kernels import centre_colour, one_look
from channel_worker.pipeline.shade._coverage_kernels import edge_pixel
from channel_worker.pipeline.shade.group import ShadeFrame
from channel_worker.pipeline.shade.shading import (
    earth_range,
    eye_ray,
    flat_colour,
    sample_point,
    shade_sample,
)
from channel_worker.pipeline.shade.texturing import varies


class StoreIn(NamedTuple):
    """The sample store as the resolve kernels read it (contract.SampleBuffer).

    Attributes:
        opaque: (H, W, S) int32 nearest opaque feature, or SKY_ID / EARTH_ID / BACKGROUND_ID.
        trans: (H * W * S, K) int32 translucent features, nearest first, row (y W + x) S + s
            (a (1, K) stand-in when the frame has none: every count is then 0).
        trans_count: (H, W, S) uint8 how many of them are meaningful.
        polygon_range: (H, W) float32 nearest polygon's range per pixel (when want_range).
        want_range: compute each pixel's range.
        opaque_flat, count_flat: opaque and trans_count flattened (sample (y W + x) S + s),
            as edge_pixel reads a pixel's samples.
    """

    opaque: np.ndarray
    trans: np.ndarray
    trans_count: np.ndarray
    polygon_range: np.ndarray
    want_range: bool
    opaque_flat: np.ndarray
    count_flat: np.ndarray


@njit(cache=True, inline="always")
def _sample_colour(store, frame, background, sh, y, x, s, acc):
    """acc plus the colour of sample s of pixel (x, y) of the store."""
    w = store.opaque.shape[1]
    s_count = store.opaque.shape[2]
    sx, sy = sample_point(frame, x, y, s)
    ray = 1.0
    sin_el = 0.0
    cos_ax = 0.0
    if sh.by_range:
        _, _, ray, sin_el, cos_ax = eye_ray(frame, sh, sx, sy)
    return shade_sample(sh, y, x, (sx, sy), (ray, sin_el, cos_ax), store.opaque[y, x, s],
                        store.trans_count[y, x, s], store.trans, (y * w + x) * s_count + s, acc)


@njit(cache=True, inline="always")
def _pixel_range(store, frame, background, y, x):
    """Nearest surface seen by the pixel: its nearest polygon or, nearer, the background or
    the earth plane."""
    nearest = store.polygon_range[y, x]
    for s in range(store.opaque.shape[2]):
        f = store.opaque[y, x, s]
        if f == BACKGROUND_ID:
            nearest = min(nearest, background.range_m[y, x])
        elif f == EARTH_ID:
            sx, sy = sample_point(frame, x, y, s)
            m = frame.mapping
            nearest = min(nearest, earth_range(frame, (sx - m[1]) / m[0], (sy - m[3]) / m[2]))
    return nearest


@njit(cache=True, parallel=True)
def box_kernel(store, frame, background, sh, cov, out_rgb, out_range):
    """Shade and average the samples of each pixel in one pass (no sample colour buffer);
    frame, background, sh, cov: the frame's ShadeFrame in its parts (see
    visibility_kernel; with cov.on, single-edge pixels take their exact area)."""
    for y in prange(store.opaque.shape[0]):
        _box_row(y, store, ShadeFrame(frame, background, sh, cov), out_rgb, out_range)


@borrowing
def _box_row(y, store, sf, out_rgb, out_range):
    """One row of box_kernel. A pixel whose samples all see one feature and nothing
    translucent (most pixels) takes that feature's colour without a per-sample sum."""
    frame, background, sh, cov = sf.frame, sf.background, sf.sh, sf.cov
    w, s_count = store.opaque.shape[1], store.opaque.shape[2]
    inv_s = 1.0 / s_count
    for x in range(w):
        f0 = store.opaque[y, x, 0]
        # Those vary per sample or pixel: haze, fog, clouds, the background, a look.
        uniform = not (sh.by_range or f0 == BACKGROUND_ID or (f0 >= 0 and varies(sh, f0)))
        for s in range(s_count):
            if not uniform or store.opaque[y, x, s] != f0 or store.trans_count[y, x, s] != 0:
                uniform = False
                break
        exact = False
        cr = cg = cb = 0.0
        base = (y * w + x) * s_count
        if not uniform and sh.textured and one_look(sh, store.opaque_flat, store.count_flat, True,
                                                    base, s_count, 1):
            # As box_subarea does: once at the pixel's centre, at the samples' mean 1/z.
            iz = 0.0
            for s in range(s_count):
                sx, sy = sample_point(frame, x, y, s)
                iz += sh.inv_z[f0, 0] * sx + (sh.inv_z[f0, 1] * sy + sh.inv_z[f0, 2])
            exact = True
            cr, cg, cb = centre_colour(sh, frame, f0, iz * inv_s, x, y)
        elif not uniform and cov.on:  # one edge across the pixel: its exact area (coverage "area")
            exact, cr, cg, cb = edge_pixel(sf, store.opaque_flat, store.count_flat, True,
                                           store.trans, base, 1, x, y)
        if uniform:
            cr, cg, cb = flat_colour(sh, f0)
        if uniform or exact:
            out_rgb[y, x, 0] = cr
            out_rgb[y, x, 1] = cg
            out_rgb[y, x, 2] = cb
        else:
            acc = (0.0, 0.0, 0.0)
            for s in range(s_count):
                acc = _sample_colour(store, frame, background, sh, y, x, s, acc)
            out_rgb[y, x, 0] = acc[0] * inv_s
            out_rgb[y, x, 1] = acc[1] * inv_s
            out_rgb[y, x, 2] = acc[2] * inv_s
        if store.want_range:
            out_range[y, x] = _pixel_range(store, frame, background, y, x)


@njit(cache=True, parallel=True)
def shade_kernel(store, frame, background, sh, out_samples, out_range):
    """Every sample's colour, for filters that also read neighbouring pixels' samples."""
    for y in prange(store.opaque.shape[0]):
        _shade_row(y, store, frame, background, sh, out_samples, out_range)


@borrowing
def _shade_row(y, store, frame, background, sh, out_samples, out_range):
    """One row of shade_kernel."""
    w, s_count = store.opaque.shape[1], store.opaque.shape[2]
    for x in range(w):
        for s in range(s_count):
            r, g, b = _sample_colour(store, frame, background, sh, y, x, s, (0.0, 0.0, 0.0))
            out_samples[y, x, s, 0] = r
            out_samples[y, x, s, 1] = g
            out_samples[y, x, s, 2] = b
        if store.want_range:
            out_range[y, x] = _pixel_range(store, frame, background, y, x)


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
