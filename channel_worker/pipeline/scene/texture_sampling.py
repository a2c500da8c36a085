"""Texture sampling for the polygons' shading and the terrain's detail: bilinear and
trilinear look-ups in a texture store (scene/textures.py), the fade of a texture whose finest
detail approaches the sampling rate (*An image generator*, docs/textures.md), and a texture
code's whole modulation at one point of its texture plane (texture_modulation).

Coordinates are in texels of a texture's level 0, texel centres at +0.5; every texture repeats
(its sides are powers of two, so wrapping is a mask). Coordinates arrive in float64 and are
wrapped into one period in float64 before anything narrows: a runway's texture coordinate
may be 1e6 texels from its origin, where float32 has no fraction left.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from channel_worker.pipeline.jit import borrowing
from services.rig.options import TEXTURE_FILTERS

from .surfaces import (
    LOOK_AMPLITUDE,
    LOOK_DETAIL,
    LOOK_INTENSITY,
    LOOK_OFFSET,
    LOOK_PER_COLOUR,
    LOOK_PRIMARY,
    LOOK_TEXTURE,
    MAX_CODE_TEXTURES,
)


class TextureArrays(NamedTuple):
    """The texture store's arrays the samplers read (scene/textures.TextureStore's names): a
    caller with more in its own group passes these alone, as the calls take their arguments by
    value."""

    texels: np.ndarray
    level: np.ndarray
    levels: np.ndarray
    finest: np.ndarray


#: The filters as the kernels get them (FrameConstants.texture_filter: the index of the name in
#: the options' registry).
FADE = list(TEXTURE_FILTERS).index("fade")
MIPMAP = list(TEXTURE_FILTERS).index("mipmap")


@njit(cache=True, inline="always")
def _wrap(u, period):
    """u modulo period (a power of two, >= 1), in [0, period] in float64. Exact: floor(u /
    period) * period is an integer multiple of a power of two, representable for |u| < 2**52,
    and its difference from u loses nothing (Sterbenz). The result may equal period only by
    rounding of a tiny negative u; the caller's mask handles that texel."""
    return u - period * math.floor(u / period)  # period >= 1: a level's side


@njit(cache=True, inline="always")
def _bilinear_at(offset, width_log2, height_log2, sx, sy):
    """The four texels around (sx, sy) in a level stored at offset (2**width_log2 x
    2**height_log2, row-major), wrapped, and their weights: (i00, i10, i01, i11, w00, w10,
    w01, w11); every weight 0 for a non-finite coordinate (nothing sensible to sample)."""
    width = 1 << width_log2
    height = 1 << height_log2
    if not (math.isfinite(sx) and math.isfinite(sy)):
        return offset, offset, offset, offset, 0.0, 0.0, 0.0, 0.0
    u = _wrap(sx - 0.5, float(width))
    v = _wrap(sy - 0.5, float(height))
    x0 = int(math.floor(u))
    y0 = int(math.floor(v))
    fx = u - x0
    fy = v - y0
    # Masks keep every index inside the level whatever rounding did (u == width wraps to 0).
    mx = width - 1
    my = height - 1
    c0 = x0 & mx
    c1 = (x0 + 1) & mx
    r0 = offset + (y0 & my) * width
    r1 = offset + ((y0 + 1) & my) * width
    return (r0 + c0, r0 + c1, r1 + c0, r1 + c1,
            (1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy)


@njit(cache=True, inline="always")
def _bilinear(texels, offset, width_log2, height_log2, sx, sy):
    """Bilinear sample (r, g, b) of the level stored at texels[offset:] (2**width_log2 x
    2**height_log2, row-major) at (sx, sy) in that level's texels, wrapped; 0 for a
    non-finite coordinate."""
    i00, i10, i01, i11, w00, w10, w01, w11 = _bilinear_at(offset, width_log2, height_log2, sx, sy)
    tex = texels
    r = w00 * tex[i00, 0] + w10 * tex[i10, 0] + w01 * tex[i01, 0] + w11 * tex[i11, 0]
    g = w00 * tex[i00, 1] + w10 * tex[i10, 1] + w01 * tex[i01, 1] + w11 * tex[i11, 1]
    b = w00 * tex[i00, 2] + w10 * tex[i10, 2] + w01 * tex[i01, 2] + w11 * tex[i11, 2]
    return r, g, b


# Not inlined: a texture code's shading reads it in three places (level 0, and the two
# levels of a trilinear read); inlined, it made the shading's compile twice as long. The fade
# filter's level-0 read (texture_modulation) inlines _bilinear_at instead: one place.
@borrowing
def texel_bilinear(store, t, level, x, y):
    """Bilinear sample of texture t's level `level` at (x, y) in texels of level 0.

    level is clamped to the texture's levels (0 to levels[t] - 1); (x, y) is scaled to the
    level (an exact power-of-two scale) and wrapped, for negative and large (|x| up to
    1e15) coordinates alike. Exact at texel centres (x = i + 0.5 in that level's texels).
    A non-finite coordinate gives 0, no modulation: nothing sensible to sample.

    Returns:
        (r, g, b) float64 signal values.
    """
    last = store.levels[t] - 1
    lv = min(max(level, 0), last)
    width_log2 = store.level[t, lv, 1]
    height_log2 = store.level[t, lv, 2]
    # Level 0 texels -> this level's: divide by 2**(level 0 log2 side - this level's), exact.
    sx = x * ((1 << width_log2) / (1 << store.level[t, 0, 1]))
    sy = y * ((1 << height_log2) / (1 << store.level[t, 0, 2]))
    return _bilinear(store.texels, store.level[t, lv, 0], width_log2, height_log2, sx, sy)


@njit(cache=True, inline="always")
def texel_trilinear(store, t, x, y, lod):
    """Trilinear sample of texture t at (x, y) in level-0 texels (Williams' mip-mapping).

    lod: log2 of the sample's footprint in level-0 texels. lod <= 0 (or NaN) samples level 0
    bilinearly (magnification: nothing finer to blend with); at or beyond the last level,
    the last level; between, the two bracketing levels blended linearly in lod. At an integer
    lod the result is exactly that level's bilinear sample.

    Returns:
        (r, g, b) float64 signal values.
    """
    last = store.levels[t] - 1
    if not lod > 0.0:
        return texel_bilinear(store, t, np.int64(0), x, y)  # a literal 0 would compile anew
    if lod >= last:
        return texel_bilinear(store, t, last, x, y)
    below = int(math.floor(lod))
    f = lod - below
    r0, g0, b0 = texel_bilinear(store, t, below, x, y)
    if f == 0.0:
        return r0, g0, b0
    r1, g1, b1 = texel_bilinear(store, t, below + 1, x, y)
    return r0 + f * (r1 - r0), g0 + f * (g1 - g0), b0 + f * (b1 - b0)


@njit(cache=True, inline="always")
def texture_lod(rho):
    """The trilinear lod for a sample spacing of rho level-0 texels: log2(rho), 0 for rho <= 1
    (magnified: level 0) and for a non-finite or non-positive rho (no footprint to speak of;
    the fade, which sees the same rho, decides whether the texture shows at all)."""
    if not (rho > 1.0 and math.isfinite(rho)):
        return 0.0
    return math.log2(rho)


@njit(cache=True, inline="always")
def fade_amplitude(finest, rho):
    """How much of a texture to show: 1 while its finest frequency is well under the sampling's
    Nyquist frequency, 0 from there on, smoothstep between.

    finest: the texture's finest significant frequency (cycles per level-0 texel,
    TextureStore.finest). rho: level-0 texels per sample spacing (its sign means nothing).
    q = 2 finest |rho| is that frequency over the Nyquist frequency of the samples; 1 for
    q <= 0.5, 0 for q >= 1. Why fade as well as filter: trilinear filtering picks its level
    from one spacing, but a sample's footprint is longer in some directions than others (a
    runway at a grazing angle), and along those the level still holds detail above Nyquist,
    which shimmers as the eye moves. A texture faded out before its finest detail reaches
    Nyquist has nothing left to alias, and a coarser texture of the face's code carries on
    (the patent's scheme). Non-finite rho or finest gives 0: no footprint, no texture.
    """
    q = 2.0 * finest * abs(rho)
    if not math.isfinite(q):
        return 0.0
    if q <= 0.5:
        return 1.0
    if q >= 1.0:
        return 0.0
    s = (q - 0.5) * 2.0  # in (0, 1): the span 0.5 < q < 1 mapped onto it
    return 1.0 - s * s * (3.0 - 2.0 * s)


# Inlined: its callers (the polygons' surface_colour, the terrain's detail) are each compiled
# once, and the call passed the store and the look row by value at every read (a quarter of
# the terrain detail's cost in its profile). texel_bilinear stays a call.
@njit(cache=True, inline="always")
def texture_modulation(store, row, texture_filter, u, v, ux, vx, uy, vy):
    """The colour factors (r, g, b) of a texture code at texture-plane point (u, v), metres,
    filtered to a pixel whose two sides span (ux, vx) and (uy, vy) metres of the plane.

    row: the code's row of the look table (scene/surfaces.py LOOK_*). store: the texture
    store's arrays (texels, level, levels, finest, as TextureStore names them). The textures of
    the code are read at their own scales (the primary's u and v scales, the secondary's and
    tertiary's common scale and offset), weighted by their amplitudes, and the sum s modulates
    the colour as max(0, 1 + intensity s): one signal for all three colours (mono), or one per
    colour. Filtering (texture_filter, TEXTURE_FILTERS): fade keeps level 0 and fades its
    amplitude as its finest detail nears the sampling rate; mipmap reads the pyramid at the
    footprint; both keeps level 0 as far as the fade would and the pyramid beyond.
    """
    sr = 0.0
    sg = 0.0
    sb = 0.0
    mono = row[LOOK_PER_COLOUR] == 0.0
    for k in range(MAX_CODE_TEXTURES):
        t = int(row[LOOK_TEXTURE + k])
        if t < 0:
            break
        if k == 0:
            ru = row[LOOK_PRIMARY]
            rv = row[LOOK_PRIMARY + 1]
            ou = 0.0
            ov = 0.0
            amp = 1.0
        else:
            ru = row[LOOK_DETAIL]
            rv = row[LOOK_DETAIL + 1]
            ou = row[LOOK_OFFSET]
            ov = row[LOOK_OFFSET + 1]
            amp = row[LOOK_AMPLITUDE + k - 1]
            if amp == 0.0:
                continue  # a texture the code silences: nothing to read
        tw = ru * (1 << store.level[t, 0, 1])  # texels per metre along u, v
        th = rv * (1 << store.level[t, 0, 2])
        tx = (u + ou) * tw
        ty = (v + ov) * th
        # The footprint: level-0 texels along the pixel's two sides.
        side_x = math.sqrt((ux * tw) ** 2 + (vx * th) ** 2)
        side_y = math.sqrt((uy * tw) ** 2 + (vy * th) ** 2)
        rho = max(side_x, side_y)
        # How much of the level-0 read to keep (the rest from the pyramid at the footprint)
        # and the texture's amplitude. One bilinear and one trilinear read in the code,
        # whichever the filter.
        fade = 1.0
        keep = 1.0
        if texture_filter == FADE:
            fade = fade_amplitude(store.finest[t], rho)
            if fade <= 0.0:
                continue
        elif texture_filter == MIPMAP:
            keep = 0.0
        else:
            keep = fade_amplitude(store.finest[t], rho)
        cr = 0.0
        cg = 0.0
        cb = 0.0
        if keep > 0.0:
            # Level 0: read in place (the fade filter's only read); a mono code reads the
            # texels' mean channel alone, a third of the loads.
            i00, i10, i01, i11, w00, w10, w01, w11 = _bilinear_at(
                store.level[t, 0, 0], store.level[t, 0, 1], store.level[t, 0, 2], tx, ty)
            tex = store.texels
            if mono:
                m = keep * (w00 * tex[i00, 3] + w10 * tex[i10, 3] + w01 * tex[i01, 3] + w11 * tex[i11, 3])
                cr = m
                cg = m
                cb = m
            else:
                cr = keep * (w00 * tex[i00, 0] + w10 * tex[i10, 0] + w01 * tex[i01, 0] + w11 * tex[i11, 0])
                cg = keep * (w00 * tex[i00, 1] + w10 * tex[i10, 1] + w01 * tex[i01, 1] + w11 * tex[i11, 1])
                cb = keep * (w00 * tex[i00, 2] + w10 * tex[i10, 2] + w01 * tex[i01, 2] + w11 * tex[i11, 2])
        if keep < 1.0:
            mr, mg, mb = texel_trilinear(store, t, tx, ty, texture_lod(rho))
            cr += (1.0 - keep) * mr
            cg += (1.0 - keep) * mg
            cb += (1.0 - keep) * mb
        amp *= fade
        sr += amp * cr
        sg += amp * cg
        sb += amp * cb
    intensity = row[LOOK_INTENSITY]
    if not mono:
        return max(0.0, 1.0 + intensity * sr), max(0.0, 1.0 + intensity * sg), max(0.0, 1.0 + intensity * sb)
    grey = max(0.0, 1.0 + intensity * (sr + sg + sb) * (1.0 / 3.0))
    return grey, grey, grey
