"""A polygon's surface at one screen point: its Gouraud light and its texture code's textures
(the texture patent *An image generator*), perspective-correct from per-face, per-frame screen
planes (contract.ScreenPolygons.surface).

The patent computes texture-plane coordinates per raster spot from nine per-frame constants,
x_t = (A x + B y + C) / (P x + Q y + R) and y_t likewise: here P, Q, R are the face's 1/z plane
(the same for every attribute of the face) and each attribute (u, v, light) has its own
numerator plane. The textures of one code are read at their own scales (the primary's x and y
scales, the secondary's and tertiary's common scales and offset), weighted by their
amplitudes relative to the overall intensity, and the sum modulates the face's colour: one
signal for all three colours, or one per colour (hue changes).

Anti-aliasing by fading (the patent): a texture's amplitude falls as its finest spatial
frequency approaches the rate at which the pixel grid samples it; the sampling rate comes from
the screen derivatives of (u, v), exact for the homogeneous map:
d(N / D)/dsx = (N_x - (N / D) D_x) / D. Alternatives (RenderOptions.texture_filter): a
trilinear read of the pre-filtered pyramid at the footprint (L. Williams, *Pyramidal
parametrics*), or level 0 for as long as the fade keeps it and the pyramid beyond.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from channel_worker.pipeline.jit import borrowing
from channel_worker.pipeline.scene.surfaces import (
    LOOK_AMPLITUDE,
    LOOK_DETAIL,
    LOOK_INTENSITY,
    LOOK_OFFSET,
    LOOK_PER_COLOUR,
    LOOK_PRIMARY,
    LOOK_SMOOTH,
    LOOK_TEXTURE,
    MAX_CODE_TEXTURES,
)
from services.rig.options import TEXTURE_FILTERS

from ._texture_kernels import fade_amplitude, texel_bilinear, texel_trilinear, texture_lod

#: The filters as the kernels get them (FrameConstants.texture_filter: the index of the name in
#: the options' registry).
_FADE = list(TEXTURE_FILTERS).index("fade")
_MIPMAP = list(TEXTURE_FILTERS).index("mipmap")


@njit(cache=True, inline="always")
def varies(sh, p):
    """Polygon p's colour varies over it (a texture or Gouraud light): it cannot be filled
    as one colour."""
    return sh.textured and sh.look[p] >= 0


# Not inlined: inlined into each of its callers (the fused and resolve paths' pixel, sample
# and edge-pixel shading) it made a cold compile of the render kernels minutes long; a call
# costs nothing next to the texture reads it makes.
@borrowing
def surface_colour(sh, p, sx, sy, spacing, r, g, b):
    """Polygon p's colour (r, g, b) at screen point (sx, sy) with its look: lit by its Gouraud
    light and modulated by its textures, filtered to a footprint of spacing pixels."""
    look = sh.look[p]
    if not sh.textured or look < 0:
        return r, g, b
    row = sh.looks[look]
    m = sh.surface[p]
    a = sh.inv_z[p, 0]
    bb = sh.inv_z[p, 1]
    # Guard: polygons are clipped to z >= near > 0, so 1/z > 0 on them.
    w = 1.0 / (a * sx + (bb * sy + sh.inv_z[p, 2]))
    if row[LOOK_SMOOTH] != 0.0:
        light = (m[6] * sx + m[7] * sy + m[8]) * w
        r *= light
        g *= light
        b *= light
    if row[LOOK_TEXTURE] < 0.0:
        return r, g, b
    u = (m[0] * sx + m[1] * sy + m[2]) * w
    v = (m[3] * sx + m[4] * sy + m[5]) * w
    # Metres of the texture plane per pixel step along screen x and y.
    ux = (m[0] - u * a) * w
    uy = (m[1] - u * bb) * w
    vx = (m[3] - v * a) * w
    vy = (m[4] - v * bb) * w
    sr = 0.0
    sg = 0.0
    sb = 0.0
    store = sh  # it has the TextureStore's fields (shading.Shading)
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
        tw = ru * (1 << store.level[t, 0, 1])  # texels per metre along u, v
        th = rv * (1 << store.level[t, 0, 2])
        tx = (u + ou) * tw
        ty = (v + ov) * th
        # The footprint: level-0 texels per spacing along the pixel's two sides.
        side_x = spacing * math.sqrt((ux * tw) ** 2 + (vx * th) ** 2)
        side_y = spacing * math.sqrt((uy * tw) ** 2 + (vy * th) ** 2)
        rho = max(side_x, side_y)
        # How much of the level-0 read to keep (the rest from the pyramid at the footprint)
        # and the texture's amplitude: fade keeps level 0 and fades its amplitude, mipmap
        # reads the pyramid, both keeps level 0 as far as the fade would and the pyramid
        # beyond. One bilinear and one trilinear read in the code, whichever the filter.
        fade = 1.0
        keep = 1.0
        if sh.texture_filter == _FADE:
            fade = fade_amplitude(store.finest[t], rho)
            if fade <= 0.0:
                continue
        elif sh.texture_filter == _MIPMAP:
            keep = 0.0
        else:
            keep = fade_amplitude(store.finest[t], rho)
        cr = 0.0
        cg = 0.0
        cb = 0.0
        if keep > 0.0:
            br, bg, bb = texel_bilinear(store, t, np.int64(0), tx, ty)
            cr = keep * br
            cg = keep * bg
            cb = keep * bb
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
    if row[LOOK_PER_COLOUR] != 0.0:
        return (r * max(0.0, 1.0 + intensity * sr), g * max(0.0, 1.0 + intensity * sg),
                b * max(0.0, 1.0 + intensity * sb))
    mono = max(0.0, 1.0 + intensity * (sr + sg + sb) * (1.0 / 3.0))
    return r * mono, g * mono, b * mono
