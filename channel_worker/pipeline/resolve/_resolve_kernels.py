"""numba kernels for the resolve stage (see resolve.py): samples shaded (shading.shade_sample)
and filtered into pixels, from the sample store or, during visibility, from one sub-area's
store (box_subarea, EP 0611020's per-sub-area pixel output)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID, SKY_ID
from channel_worker.pipeline.fog.fog import fog_cos
from channel_worker.pipeline.jit import borrowing

from ._coverage_kernels import edge_pixel
from .shading import earth_range, eye_ray, flat_colour, polygon_colour, sample_point, shade_sample
from .texturing import varies

#: Marks a sub-area whose samples do not all see one thing (not a feature identity).
_MIXED = -100


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


@borrowing
def box_subarea(rect, backdrop, frame, background, sh, any_translucent, want_range, sc, out_rgb,
                out_range, cov, area):
    """The pixels of one sub-area from its sample store sc (visibility's Scratch): each
    sample shaded, averaged over the pixel; with want_range the pixel's nearest range.

    rect: (x0, y0, x1, y1) the sub-area's pixels; backdrop: EARTH_ID or SKY_ID if every
    uncovered sample of it sees that, else 0 (the horizon crosses it, or the frame has a
    background). cov: the frame's Coverage (_coverage_kernels); area: take single-edge pixels'
    exact area (cov.on, and the sub-area's list has a partially covering feature: else no
    edge crosses any of its pixels).
    """
    tx0, ty0, tx1, ty1 = rect
    tw = tx1 - tx0
    s_count = frame.offsets_fixed.shape[0]
    n = tw * (ty1 - ty0) * s_count
    o_id, o_iz, t_id, t_cnt = sc.o_id, sc.o_iz, sc.t_id, sc.t_cnt
    # A sub-area whose every sample sees one thing and nothing translucent (open sky, open
    # ground, the inside of a large face) is one colour: fill it without shading.
    # Visibility's mixed masks name every pixel whose samples may differ or see translucency;
    # the others are known by their first sample.
    uniform = o_id[0]
    for r in range(ty1 - ty0):
        if sc.mixed[r] != 0:
            uniform = _MIXED
            break
    if uniform != _MIXED:
        for i in range(0, n, s_count):
            if o_id[i] != uniform:
                uniform = _MIXED
                break
    if uniform < 0 and uniform != _MIXED:
        uniform = backdrop if backdrop != 0 else _MIXED
    if sh.by_range or (uniform >= 0 and varies(sh, uniform)):
        uniform = _MIXED  # hazed, fogged, clouded, textured or Gouraud colours vary
    if uniform != _MIXED and not want_range:
        cr, cg, cb = flat_colour(sh, uniform)
        for y in range(ty0, ty1):
            for x in range(tx0, tx1):
                out_rgb[y, x, 0] = cr
                out_rgb[y, x, 1] = cg
                out_rgb[y, x, 2] = cb
        return
    kx, ky, k0 = frame.horizon[0], frame.horizon[1], frame.horizon[2]
    inv_s = 1.0 / s_count
    for y in range(ty0, ty1):
        for x in range(tx0, tx1):
            base = ((y - ty0) * tw + (x - tx0)) * s_count
            if sh.textured and _one_look(sh, o_id, t_cnt, any_translucent, base, s_count):
                iz = 0.0
                for s in range(s_count):
                    iz += o_iz[base + s]
                cr, cg, cb = _centre_colour(sh, frame, o_id[base], iz * inv_s, x, y)
                out_rgb[y, x, 0] = cr
                out_rgb[y, x, 1] = cg
                out_rgb[y, x, 2] = cb
                if want_range:
                    near_range = np.inf
                    for s in range(s_count):
                        sx, sy = sample_point(frame, x, y, s)
                        _, _, ray, _, _ = eye_ray(frame, sh, sx, sy)
                        # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
                        near_range = min(near_range, ray / o_iz[base + s])
                    out_range[y, x] = near_range
                continue
            if not want_range:
                # Most pixels, even in a busy sub-area, see one thing with every sample (with
                # haze or clouds: one polygon, seen through the air at the pixel's centre).
                f0 = o_id[base]
                # A pixel whose every sample sees the background takes the background's pixel
                # colour (already through the air): no per-sample ray.
                same = f0 >= 0 or background.on or (backdrop != 0 and not sh.by_range)
                # With a background every sample that no polygon covers sees it, terrain or not.
                bg_only = f0 < 0 and background.on
                # A pixel visibility left unmixed sees one thing with every sample, nothing
                # translucent: no need to look at its samples.
                mixed = (sc.mixed[y - ty0] >> np.uint64(x - tx0)) & np.uint64(1) != 0
                for s in range(1, s_count if mixed else 1):
                    if o_id[base + s] != f0 and not (bg_only and o_id[base + s] < 0):
                        same = False
                        break
                if same and mixed and any_translucent:
                    for s in range(s_count):
                        if t_cnt[base + s] != 0:
                            same = False
                            break
                if same:
                    if f0 >= 0 and sh.by_range:
                        iz = 0.0
                        for s in range(s_count):
                            iz += o_iz[base + s]
                        cr, cg, cb = _centre_colour(sh, frame, f0, iz * inv_s, x, y)
                    elif bg_only:
                        cr = background.rgb[y, x, 0]
                        cg = background.rgb[y, x, 1]
                        cb = background.rgb[y, x, 2]
                    else:
                        cr, cg, cb = flat_colour(sh, f0 if f0 >= 0 else backdrop)
                    out_rgb[y, x, 0] = cr
                    out_rgb[y, x, 1] = cg
                    out_rgb[y, x, 2] = cb
                    continue
            # Where one edge crosses the pixel its exact area beats the samples' count
            # (coverage "area", _coverage_kernels); the range still comes from the samples.
            exact = False
            if area:
                exact, ar, ag, ab = edge_pixel(cov, frame, background, sh, o_id, t_cnt,
                                               any_translucent, t_id, base, x, y)
                if exact:
                    out_rgb[y, x, 0] = ar
                    out_rgb[y, x, 1] = ag
                    out_rgb[y, x, 2] = ab
                    if not want_range:
                        continue
            r = 0.0
            g = 0.0
            b = 0.0
            near_range = np.inf
            for s in range(s_count):
                i = base + s
                # The sample's position and ray only where something needs them: most samples
                # of a frame without haze, fog or clouds need neither.
                sx = 0.0
                sy = 0.0
                rx = 0.0
                ry = 0.0
                ray = 1.0
                sin_el = 0.0
                cos_ax = 0.0
                f = o_id[i]
                if f < 0:
                    if background.on:
                        f = BACKGROUND_ID
                    elif backdrop != 0:
                        f = backdrop
                    else:
                        sx, sy = sample_point(frame, x, y, s)
                        f = EARTH_ID if kx * sx + ky * sy + k0 < 0.0 else SKY_ID
                if sh.by_range or want_range:
                    sx, sy = sample_point(frame, x, y, s)
                    rx, ry, ray, sin_el, cos_ax = eye_ray(frame, sh, sx, sy)
                elif sh.textured:
                    sx, sy = sample_point(frame, x, y, s)
                n_trans = t_cnt[i] if any_translucent else 0
                r, g, b = shade_sample(sh, y, x, (sx, sy), (ray, sin_el, cos_ax), f, n_trans, t_id,
                                       i, (r, g, b))
                if want_range:
                    if f >= 0:
                        # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
                        near_range = min(near_range, ray / o_iz[i])
                    elif f == BACKGROUND_ID:
                        near_range = min(near_range, background.range_m[y, x])
                    elif f == EARTH_ID:
                        near_range = min(near_range, earth_range(frame, rx, ry))
            if not exact:
                out_rgb[y, x, 0] = r * inv_s
                out_rgb[y, x, 1] = g * inv_s
                out_rgb[y, x, 2] = b * inv_s
            if want_range:
                out_range[y, x] = near_range


@njit(cache=True, inline="always")
def _one_look(sh, ids, counts, translucent, base, s_count):
    """Every sample of the pixel (ids[base:base + s_count]) sees one polygon whose colour
    varies over it (a texture, Gouraud light), and nothing translucent: like a GPU's
    multisampling, it is then shaded once, at the pixel's centre and footprint (the samples
    still decide coverage; pixels where features meet are shaded per sample)."""
    f0 = ids[base]
    if f0 < 0 or not varies(sh, f0):
        return False
    for s in range(s_count):  # noqa: SIM110  (numba compiles the loop, not all())
        if ids[base + s] != f0 or (translucent and counts[base + s] != 0):
            return False
    return True


@njit(cache=True, inline="always")
def _centre_colour(sh, frame, f, iz, x, y):
    """Polygon f's colour for pixel (x, y) shaded once at its centre (a pixel whose samples all
    see it: _one_look, or any polygon seen through the air), through the air at the samples'
    mean 1/z (iz)."""
    m = frame.mapping
    cx = x + 0.5
    cy = y + 0.5
    rng = 0.0
    sin_el = 0.0
    cos_ax = 0.0
    if sh.by_range:
        rx = (cx - m[1]) / m[0]
        ry = (cy - m[3]) / m[2]
        ray = math.sqrt(rx * rx + ry * ry + 1.0)
        if sh.fogged:
            cos_ax = fog_cos(sh.air, rx, ry, ray)
        dz = frame.dz_row
        # Guards: 1/z > 0 for polygons (clipped to z >= near); ray >= 1.
        rng = ray / iz
        sin_el = (dz[0] * rx + dz[1] * ry + dz[2]) / ray
    return polygon_colour(sh, f, y, x, (cx, cy, 1.0), rng, sin_el, cos_ax)


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
def box_kernel(store, frame, background, sh, out_rgb, out_range, cov):
    """Shade and average the samples of each pixel in one pass (no sample colour buffer);
    cov: the frame's Coverage (with cov.on, single-edge pixels take their exact area)."""
    for y in prange(store.opaque.shape[0]):
        _box_row(y, store, frame, background, sh, out_rgb, out_range, cov)


@borrowing
def _box_row(y, store, frame, background, sh, out_rgb, out_range, cov):
    """One row of box_kernel. A pixel whose samples all see one feature and nothing
    translucent (most pixels) takes that feature's colour without a per-sample sum."""
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
        if not uniform and sh.textured and _one_look(sh, store.opaque_flat, store.count_flat, True,
                                                     base, s_count):
            # As box_subarea does: once at the pixel's centre, at the samples' mean 1/z.
            iz = 0.0
            for s in range(s_count):
                sx, sy = sample_point(frame, x, y, s)
                iz += sh.inv_z[f0, 0] * sx + (sh.inv_z[f0, 1] * sy + sh.inv_z[f0, 2])
            exact = True
            cr, cg, cb = _centre_colour(sh, frame, f0, iz * inv_s, x, y)
        elif not uniform and cov.on:  # one edge across the pixel: its exact area (coverage "area")
            exact, cr, cg, cb = edge_pixel(cov, frame, background, sh, store.opaque_flat,
                                           store.count_flat, True, store.trans, base, x, y)
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
