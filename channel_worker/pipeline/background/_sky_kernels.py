"""numba kernels that paint the sky and the earth plane through the air (background.py).

sky_and_earth is the one place the sky and earth plane are computed. Where the air depends on
elevation alone (no fog, or fog strata stacked along the vertical), sky_table_kernel tabulates
both once a frame by the sine of the elevation and backdrop reads a pixel's from the table
(one interpolated read); otherwise backdrop computes them per pixel. The terrain cast
(_cast_kernels) calls backdrop for what the terrain leaves uncovered, sky_earth_kernel for
every pixel of a scene without terrain.
"""

from __future__ import annotations

import math

from numba import njit, prange

from channel_worker.pipeline.contract import F_ON, F_WORLD_AXIS
from channel_worker.pipeline.fog.fog import fog_blend, fog_cos

from .haze import haze_amount

#: Entries of the sky table, uniform in the sine of the elevation over [-1, 1]: 1/2048 of
#: elevation near the horizon (a fifth of a pixel of a 1280-pixel, 60-degree channel).
SKY_TABLE_SIZE = 4097


@njit(cache=True)
def sky_table_kernel(frame, air, out_sky, out_earth):
    """The sky's and the earth plane's colour through the air at SKY_TABLE_SIZE elevations
    (sine -1 .. 1): valid where the air depends on elevation alone (SkyTable.tabulated).

    Args:
        frame: the frame's constants (sky, earth, height_above).
        air: the frame's air array.
        out_sky, out_earth: (SKY_TABLE_SIZE, 3) float64.
    """
    n = out_sky.shape[0]
    fogged = air[F_ON] != 0.0
    axz = air[F_WORLD_AXIS + 2]
    for i in range(n):
        sn = -1.0 + 2.0 * i / (n - 1)  # guard: n > 1
        hs = haze_amount(air, math.inf, max(sn, 0.0)) if air[0] != 0.0 else 0.0
        sr = frame.sky[0] * (1.0 - hs) + air[3] * hs
        sg = frame.sky[1] * (1.0 - hs) + air[4] * hs
        sb = frame.sky[2] * (1.0 - hs) + air[5] * hs
        if fogged:
            sr, sg, sb = fog_blend(air, math.inf, axz * sn, sr, sg, sb)
        out_sky[i, 0] = sr
        out_sky[i, 1] = sg
        out_sky[i, 2] = sb
        er, eg, eb = frame.earth[0], frame.earth[1], frame.earth[2]
        se = min(sn, -1e-9)
        rng = frame.height_above / -se  # guard: se < 0
        if air[0] != 0.0:
            he = haze_amount(air, rng, se)
            er = er * (1.0 - he) + air[3] * he
            eg = eg * (1.0 - he) + air[4] * he
            eb = eb * (1.0 - he) + air[5] * he
        if fogged:
            er, eg, eb = fog_blend(air, rng, axz * se, er, eg, eb)
        out_earth[i, 0] = er
        out_earth[i, 1] = eg
        out_earth[i, 2] = eb


@njit(cache=True, inline="always")
def backdrop(frame, air, sky, x, y):
    """(r, g, b, earth range) of what lies behind everything at pixel (x, y)'s centre
    (backdrop_along its own ray)."""
    m = frame.mapping
    tx = (x + 0.5 - m[1]) / m[0]  # guard: screen_mapping's scales are nonzero
    ty = (y + 0.5 - m[3]) / m[2]
    dz = frame.dz_row
    return backdrop_along(frame, air, sky, x, y, math.sqrt(tx * tx + ty * ty + 1.0),
                          dz[0] * tx + dz[1] * ty + dz[2])


@njit(cache=True, inline="always")
def backdrop_along(frame, air, sky, x, y, ray, ez):
    """(r, g, b, earth range) of what lies behind everything at pixel (x, y): the earth plane
    for the share of its samples below the horizon, the sky for the rest, through the air,
    looked up by the elevation of an eye ray (tx, ty, 1) of length ray and world z ez within
    the pixel (the caller's: its centre's, or a cast line's point in it); from the frame's
    table (sky: SkyTable) where it is tabulated, else computed at the pixel's centre. The
    earth's range is +inf where no sample sees it."""
    s_count = frame.offsets.shape[0]
    kx = frame.horizon[0]
    ky = frame.horizon[1]
    side = kx * (x + 0.5) + ky * (y + 0.5) + frame.horizon[2]
    # Samples lie within half a pixel of its centre each way: farther from the horizon line
    # than that, all are on the centre's side (one test instead of one per sample).
    reach = 0.5 * (abs(kx) + abs(ky))
    if side > reach:
        n_earth = 0
    elif side < -reach:
        n_earth = s_count
    else:
        n_earth = earth_samples(frame, x, y)
    if not sky.tabulated:
        m = frame.mapping
        tx = (x + 0.5 - m[1]) / m[0]  # guard: screen_mapping's scales are nonzero
        ty = (y + 0.5 - m[3]) / m[2]
        hs = 0.0
        if air[0] != 0.0 and n_earth < s_count:
            dz = frame.dz_row
            # Guard: the ray (tx, ty, 1) is at least 1 long.
            sin_el = (dz[0] * tx + dz[1] * ty + dz[2]) / math.sqrt(tx * tx + ty * ty + 1.0)
            hs = haze_amount(air, math.inf, max(sin_el, 0.0))
        return sky_and_earth(frame, air, n_earth, tx, ty, hs)
    sn = ez / ray  # guard: ray >= 1
    n = sky.sky.shape[0]
    f = (min(max(sn, -1.0), 1.0) + 1.0) * 0.5 * (n - 1)
    i0 = min(int(f), n - 2)
    fr = f - i0
    fe = n_earth / s_count  # guard: a pattern has at least one sample
    r = 0.0
    g = 0.0
    b = 0.0
    earth_range = math.inf
    if n_earth > 0:
        t = sky.earth
        r = fe * (t[i0, 0] + fr * (t[i0 + 1, 0] - t[i0, 0]))
        g = fe * (t[i0, 1] + fr * (t[i0 + 1, 1] - t[i0, 1]))
        b = fe * (t[i0, 2] + fr * (t[i0 + 1, 2] - t[i0, 2]))
        # Guard: ez < 0 below the horizon; at it rounding may give 0 or a tiny positive: the
        # range becomes huge, never negative.
        earth_range = ray * frame.height_above / max(-ez, 1e-300)
    if n_earth < s_count:
        t = sky.sky
        fs = 1.0 - fe
        r += fs * (t[i0, 0] + fr * (t[i0 + 1, 0] - t[i0, 0]))
        g += fs * (t[i0, 1] + fr * (t[i0 + 1, 1] - t[i0, 1]))
        b += fs * (t[i0, 2] + fr * (t[i0 + 1, 2] - t[i0, 2]))
    return r, g, b, earth_range


@njit(cache=True, parallel=True)
def sky_earth_kernel(frame, air, sky, out_rgb, out_range):
    """The background of a scene without terrain: per pixel (at its centre) the sky over the
    earth plane (the share of the pixel's samples below the horizon sees the earth), through
    the air (backdrop).

    Args:
        frame: the frame's constants (FrameConstants: mapping, horizon, dz_row,
            height_above, sky, earth, offsets, width, height).
        air: the frame's air array (haze, then fog; contract.py).
        sky: the frame's sky table (SkyTable).
        out_rgb: (H, W, 3) float32 linear colour.
        out_range: (H, W) float32 the earth plane's range where seen, metres; +inf for sky.
    """
    for y in prange(frame.height):
        for x in range(frame.width):
            r, g, b, out_range[y, x] = backdrop(frame, air, sky, x, y)
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
