"""The box filter inside one sub-area (EP 0611020's per-sub-area pixel output): each pixel of
a sub-area's sample store shaded and averaged, called by the visibility stage as soon as a
sub-area's list is read, so that no frame-sized sample store is written on the default path.
The resolve stage's box kernel over a sample store shares its pixel rules (one_look,
centre_colour)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID, SKY_ID
from channel_worker.pipeline.fog.fog import fog_cos
from channel_worker.pipeline.jit import borrowing

from ._coverage_kernels import edge_pixel
from .shading import earth_range, eye_ray, flat_colour, polygon_colour, sample_point, shade_sample
from .texturing import varies

#: Marks a sub-area whose samples do not all see one thing (not a feature identity).
_MIXED = -100


@borrowing
def box_subarea(sf, rect, backdrop, any_translucent, want_range, sc, out_rgb, out_range, area):
    """The pixels of one sub-area from its sample store sc (visibility's Scratch): each
    sample shaded, averaged over the pixel; with want_range the pixel's nearest range.

    sf: the frame's ShadeFrame (group.py); rect: (x0, y0, x1, y1) the sub-area's pixels;
    backdrop: EARTH_ID or SKY_ID if every uncovered sample of it sees that, else 0 (the
    horizon crosses it, or the frame has a background); sc: the sub-area's store
    (scratch.Scratch, its mixed masks included); area: take single-edge pixels' exact area
    (sf.cov.on, and the sub-area's list has a partially covering feature: else no edge crosses
    any of its pixels).
    """
    frame, background, sh = sf.frame, sf.background, sf.sh
    tx0, ty0, tx1, ty1 = rect
    tw = tx1 - tx0
    s_count = frame.offsets_fixed.shape[0]
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
        for r in range(ty1 - ty0):
            for i in range(r * s_count * tw, r * s_count * tw + tw):
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
            # Sample s of the pixel is base + s * tw (scratch.Scratch's layout).
            base = (y - ty0) * s_count * tw + (x - tx0)
            if sh.textured and one_look(sh, o_id, t_cnt, any_translucent, base, s_count, tw):
                iz = 0.0
                for s in range(s_count):
                    iz += o_iz[base + s * tw]
                cr, cg, cb = centre_colour(sh, frame, o_id[base], iz * inv_s, x, y)
                out_rgb[y, x, 0] = cr
                out_rgb[y, x, 1] = cg
                out_rgb[y, x, 2] = cb
                if want_range:
                    near_range = np.inf
                    for s in range(s_count):
                        sx, sy = sample_point(frame, x, y, s)
                        _, _, ray, _, _ = eye_ray(frame, sh, sx, sy)
                        # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
                        near_range = min(near_range, ray / o_iz[base + s * tw])
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
                mixed = ((sc.mixed[y - ty0] >> np.uint64(x - tx0)) & np.uint64(1)) != 0
                for s in range(1, s_count if mixed else 1):
                    if o_id[base + s * tw] != f0 and not (bg_only and o_id[base + s * tw] < 0):
                        same = False
                        break
                if same and mixed and any_translucent:
                    for s in range(s_count):
                        if t_cnt[base + s * tw] != 0:
                            same = False
                            break
                if same:
                    if f0 >= 0 and sh.by_range:
                        iz = 0.0
                        for s in range(s_count):
                            iz += o_iz[base + s * tw]
                        cr, cg, cb = centre_colour(sh, frame, f0, iz * inv_s, x, y)
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
                exact, ar, ag, ab = edge_pixel(sf, o_id, t_cnt, any_translucent, t_id, base, tw, x,
                                               y)
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
                i = base + s * tw
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
def one_look(sh, ids, counts, translucent, base, s_count, stride):
    """Every sample of the pixel (ids[base + s * stride], s < s_count) sees one polygon whose colour
    varies over it (a texture, Gouraud light), and nothing translucent: like a GPU's
    multisampling, it is then shaded once, at the pixel's centre and footprint (the samples
    still decide coverage; pixels where features meet are shaded per sample)."""
    f0 = ids[base]
    if f0 < 0 or not varies(sh, f0):
        return False
    for s in range(s_count):
        if ids[base + s * stride] != f0 or (translucent and counts[base + s * stride] != 0):
            return False
    return True


@njit(cache=True, inline="always")
def centre_colour(sh, frame, f, iz, x, y):
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
