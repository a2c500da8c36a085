"""numba kernels that paint the sky and the earth plane through the air (background.py).

_sky_and_earth is the one place the sky and earth plane are painted: the warp (_warp_kernels)
calls it for what the terrain leaves uncovered, sky_earth_kernel for every pixel of a scene
with haze or fog but neither terrain nor clouds.
"""

from __future__ import annotations

import math

from numba import njit, prange

from channel_worker.pipeline.contract import F_ON
from channel_worker.pipeline.fog.fog import fog_blend, fog_cos

from .haze import haze_amount


@njit(cache=True, parallel=True)
def sky_earth_kernel(frame, air, out_rgb, out_range):
    """The background of a scene with haze or fog but neither terrain nor clouds: per pixel
    (at its centre) the sky over the earth plane (the share of the pixel's samples below the
    horizon sees the earth), through the air. What warp_kernel paints there, without its
    pre-image.

    Args:
        frame: the frame's constants (FrameConstants: mapping, horizon, dz_row,
            height_above, sky, earth, offsets, width, height).
        air: the frame's air array (haze, then fog; contract.py).
        out_rgb: (H, W, 3) float32 linear colour.
        out_range: (H, W) float32 the earth plane's range where seen, metres; +inf for sky.
    """
    mapping = frame.mapping
    dz_row = frame.dz_row
    s_count = frame.offsets.shape[0]
    # Guard: screen_mapping's scales are nonzero (check_channel: left < right, bottom < top).
    inv_sxs = 1.0 / mapping[0]
    inv_sys = 1.0 / mapping[2]
    for y in prange(frame.height):
        ty = (y + 0.5 - mapping[3]) * inv_sys
        for x in range(frame.width):
            tx = (x + 0.5 - mapping[1]) * inv_sxs
            n_earth = earth_samples(frame, x, y)
            hs = 0.0
            if air[0] != 0.0 and n_earth < s_count:
                # Guard: the ray (tx, ty, 1) is at least 1 long.
                sin_el = (dz_row[0] * tx + dz_row[1] * ty + dz_row[2]) / math.sqrt(
                    tx * tx + ty * ty + 1.0)
                hs = haze_amount(air, math.inf, max(sin_el, 0.0))
            r, g, b, out_range[y, x] = sky_and_earth(frame, air, n_earth, tx, ty, hs)
            out_rgb[y, x, 0] = r
            out_rgb[y, x, 1] = g
            out_rgb[y, x, 2] = b


@njit(cache=True, inline="always")
def earth_samples(frame, x, y):
    """How many of pixel (x, y)'s samples lie below the horizon line kx sx + ky sy + k0 = 0
    (frame.horizon)."""
    offsets = frame.offsets
    kx = frame.horizon[0]
    ky = frame.horizon[1]
    k0 = frame.horizon[2]
    n = 0
    for s in range(offsets.shape[0]):
        if kx * (x + offsets[s, 0]) + ky * (y + offsets[s, 1]) + k0 < 0.0:
            n += 1
    return n


@njit(cache=True, inline="always")
def sky_and_earth(frame, air, n_earth, tx, ty, sky_haze):
    """(r, g, b, earth range) of what lies behind everything along eye ray (tx, ty, 1): the
    earth plane for n_earth of the pixel's samples, the sky for the rest, each through the
    haze and the fog (sky_haze: the sky's haze share, the caller's). The earth's range
    (metres) is +inf where no sample sees it."""
    dz_row = frame.dz_row
    sky = frame.sky
    earth = frame.earth
    s_count = frame.offsets.shape[0]
    ez = dz_row[0] * tx + dz_row[1] * ty + dz_row[2]  # world z of the ray
    ray = math.sqrt(tx * tx + ty * ty + 1.0)
    fogged = air[F_ON] != 0.0
    cos_ax = fog_cos(air, tx, ty, ray) if fogged else 0.0
    er, eg, eb = earth[0], earth[1], earth[2]
    earth_range = math.inf
    if n_earth > 0:
        # Guard: ez < 0 below the horizon; at it rounding may give 0 or a tiny positive: the
        # range becomes huge, never negative.
        earth_range = ray * frame.height_above / max(-ez, 1e-300)
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
