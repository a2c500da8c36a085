"""Shading of one sample: what the features a sample sees look like from the eye, through the air.

One function for every path that turns a sample's features into a colour: the box filter inside
each sub-area during visibility (EP 0611020's per-sub-area pixel output, visibility.py's fused
path) and the resolve stage's filters (resolve.py). So the atmosphere is applied the same way
wherever a polygon is seen: haze (JP H07-76990), layered fog (US 5,535,374), then the pixel's
cloud if the polygon lies beyond the cloud's entry range.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from channel_worker.pipeline.background.haze import haze_amount
from channel_worker.pipeline.contract import (
    BACKGROUND_ID,
    EARTH_ID,
    F_ON,
    SUBPIXEL,
    Background,
    FrameConstants,
    ScreenPolygons,
)
from channel_worker.pipeline.fog.fog import fog_blend, fog_cos
from channel_worker.pipeline.jit import borrowing

from .texturing import surface_colour


class Shading(NamedTuple):
    """What the shading of a sample reads, for one frame.

    Attributes:
        colour: (N, 3) float32 linear RGB of each polygon, lit (ScreenPolygons.colour).
        opacity: (N,) float32 (ScreenPolygons.opacity).
        inv_z: (N, 3) float64 each polygon's 1/z plane on the screen (ScreenPolygons.inv_z).
        sky, earth: (3,) float32 linear RGB (FrameConstants).
        bg_rgb: (H, W, 3) float32 the background's colour per pixel (Background.rgb).
        air: the frame's air array (Background.air).
        cloud_on: the frame has clouds; cloud: (H, W, 5) float32 (Background.cloud).
        by_range: haze, fog or clouds: a polygon's colour depends on its range, so every
            sample's ray is needed.
        fogged: the air holds fog (its axis cosine is needed per ray).
        textured: some polygon has a look (ScreenPolygons.textured); else look and surface
            are never read.
        look, surface: ScreenPolygons.look and .surface.
        looks, texture_filter: FrameConstants' (the scene's look table, the filter's index).
        texels, level, levels, finest: the scene's TextureStore's (FrameConstants.texels, ...)
            under the store's names, so the texture reads take the Shading as their store.
    """

    colour: np.ndarray
    opacity: np.ndarray
    inv_z: np.ndarray
    sky: np.ndarray
    earth: np.ndarray
    bg_rgb: np.ndarray
    air: np.ndarray
    cloud_on: bool
    cloud: np.ndarray
    by_range: bool
    fogged: bool
    textured: bool
    look: np.ndarray
    surface: np.ndarray
    looks: np.ndarray
    texture_filter: int
    texels: np.ndarray
    level: np.ndarray
    levels: np.ndarray
    finest: np.ndarray


def shading(screen: ScreenPolygons, frame: FrameConstants, background: Background) -> Shading:
    """The frame's Shading."""
    air = background.air
    fogged = bool(air[F_ON] != 0.0)
    return Shading(screen.colour, screen.opacity, screen.inv_z, frame.sky, frame.earth,
                   background.rgb, air, bool(background.cloud_on), background.cloud,
                   bool(air[0] != 0.0 or fogged or background.cloud_on), fogged,
                   screen.textured, screen.look, screen.surface, frame.looks, frame.texture_filter,
                   frame.texels, frame.tex_level, frame.tex_levels, frame.tex_finest)


# Not inlined: inlined at its three call sites it tripled the compile of the fused resolve
# (8.6 -> 1.9 s of a cold compile), for no measurable frame time.
@borrowing
def through_air(air, cloud_on, cloud, y, x, range_m, sin_el, cos_ax, r, g, b):
    """A polygon's colour seen at range_m along a ray of elevation sine sin_el and fog-axis
    cosine cos_ax: through the haze and the fog (the air array), then through pixel (x, y)'s
    cloud (Background.cloud) if the polygon lies beyond the cloud's entry range."""
    if air[0] != 0.0:
        h = haze_amount(air, range_m, sin_el)
        r = r * (1.0 - h) + air[3] * h
        g = g * (1.0 - h) + air[4] * h
        b = b * (1.0 - h) + air[5] * h
    if air[F_ON] != 0.0:
        r, g, b = fog_blend(air, range_m, cos_ax, r, g, b)
    if cloud_on and cloud[y, x, 3] > 0.0 and range_m > cloud[y, x, 4]:
        keep = 1.0 - cloud[y, x, 3]
        r = cloud[y, x, 0] + keep * r
        g = cloud[y, x, 1] + keep * g
        b = cloud[y, x, 2] + keep * b
    return r, g, b


@njit(cache=True, inline="always")
def sample_point(frame, x, y, s):
    """Screen position (pixels) of sample s of pixel (x, y): exact, on the 1/SUBPIXEL grid."""
    inv_sub = 1.0 / SUBPIXEL
    return ((x * SUBPIXEL + frame.offsets_fixed[s, 0]) * inv_sub,
            (y * SUBPIXEL + frame.offsets_fixed[s, 1]) * inv_sub)


@njit(cache=True, inline="always")
def eye_ray(frame, sh, sx, sy):
    """The eye ray (rx, ry, 1) through screen point (sx, sy), its length, its elevation sine
    and its fog-axis cosine (0 without fog)."""
    m = frame.mapping
    rx = (sx - m[1]) / m[0]  # guard: the scales are nonzero (check_channel: left < right ...)
    ry = (sy - m[3]) / m[2]
    ray = math.sqrt(rx * rx + ry * ry + 1.0)
    dz = frame.dz_row
    sin_el = (dz[0] * rx + dz[1] * ry + dz[2]) / ray  # guard: ray >= 1
    cos_ax = fog_cos(sh.air, rx, ry, ray) if sh.fogged else 0.0
    return rx, ry, ray, sin_el, cos_ax


@njit(cache=True, inline="always")
def earth_range(frame, rx, ry):
    """Range to the earth plane along eye ray (rx, ry, 1), metres. Guard: the ray's world z is
    < 0 for every sample that sees the earth (visibility decided so); at the horizon rounding
    may give 0 or a tiny positive, clamped: the range becomes huge, never negative."""
    dz = frame.dz_row
    ez = dz[0] * rx + dz[1] * ry + dz[2]
    return math.sqrt(rx * rx + ry * ry + 1.0) * frame.height_above / max(-ez, 1e-300)


@njit(cache=True, inline="always")
def polygon_colour(sh, p, y, x, point, range_m, sin_el, cos_ax):
    """Polygon p's colour at screen point point = (sx, sy, spacing) of pixel (x, y): its
    surface there (texturing.surface_colour: textures, Gouraud light, filtered to a footprint
    of spacing pixels: 1, a pixel's, wherever it is shaded, so that a pixel shaded per sample
    where features meet matches its neighbours shaded once), seen through the air at range_m
    when the frame has any (sh.by_range)."""
    r, g, b = sh.colour[p, 0], sh.colour[p, 1], sh.colour[p, 2]
    if sh.textured and sh.look[p] >= 0:
        # One signature, whatever integer and float types the caller holds: one compile
        # (numba's int() and float() keep an int32 or a float32 as it is).
        r, g, b = surface_colour(sh, np.int64(p), np.float64(point[0]), np.float64(point[1]),
                                 np.float64(point[2]), np.float64(r), np.float64(g), np.float64(b))
    if sh.by_range:
        return through_air(sh.air, sh.cloud_on, sh.cloud, y, x, range_m, sin_el, cos_ax, r, g, b)
    return r, g, b


@njit(cache=True, inline="always")
def flat_colour(sh, f):
    """The unlit-by-range colour of a feature (f >= 0), the earth plane (EARTH_ID) or the sky
    (SKY_ID): what a pixel takes when every sample sees that one thing and nothing varies with
    range. Not for BACKGROUND_ID, whose colour is per pixel, nor for a polygon whose colour
    varies over it (texturing.varies)."""
    if f >= 0:
        return sh.colour[f, 0], sh.colour[f, 1], sh.colour[f, 2]
    if f == EARTH_ID:
        return sh.earth[0], sh.earth[1], sh.earth[2]
    return sh.sky[0], sh.sky[1], sh.sky[2]


@njit(cache=True, inline="always")
def shade_sample(sh, y, x, point, ray, f, n_trans, t_id, i, acc):
    """acc (r, g, b) plus the linear RGB of one sample of pixel (x, y): its n_trans translucent
    polygons t_id[i, :n_trans], nearest first, each covering its opacity of what lies behind
    it, over what it sees: polygon f (>= 0), the background (BACKGROUND_ID), the earth plane
    (EARTH_ID) or the sky.

    point: (sx, sy) the sample's screen position; ray: (length, elevation sine, fog-axis
    cosine) of its eye ray, read only when sh.by_range: polygons are then seen through the air
    at their own range (1/z from their exact plane). The colour is added to acc term by term,
    nearest first, so a caller summing a pixel's samples gets them in one running sum.
    """
    sx, sy = point
    length, sin_el, cos_ax = ray
    r, g, b = acc
    through = 1.0
    for q in range(n_trans):
        p = t_id[i, q]
        a = sh.opacity[p] * through
        rng = 0.0
        if sh.by_range:
            # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
            rng = length / (sh.inv_z[p, 0] * sx + (sh.inv_z[p, 1] * sy + sh.inv_z[p, 2]))
        cr, cg, cb = polygon_colour(sh, p, y, x, (sx, sy, 1.0), rng, sin_el, cos_ax)
        r += a * cr
        g += a * cg
        b += a * cb
        through *= 1.0 - sh.opacity[p]
    if f >= 0:
        rng = 0.0
        if sh.by_range:
            rng = length / (sh.inv_z[f, 0] * sx + (sh.inv_z[f, 1] * sy + sh.inv_z[f, 2]))
        cr, cg, cb = polygon_colour(sh, f, y, x, (sx, sy, 1.0), rng, sin_el, cos_ax)
    elif f == BACKGROUND_ID:
        cr, cg, cb = sh.bg_rgb[y, x, 0], sh.bg_rgb[y, x, 1], sh.bg_rgb[y, x, 2]
    elif f == EARTH_ID:
        cr, cg, cb = sh.earth[0], sh.earth[1], sh.earth[2]
    else:
        cr, cg, cb = sh.sky[0], sh.sky[1], sh.sky[2]
    return r + through * cr, g + through * cg, b + through * cb
