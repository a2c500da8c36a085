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

from numba import njit

from channel_worker.pipeline.jit import borrowing
from channel_worker.pipeline.scene.surfaces import LOOK_SMOOTH, LOOK_TEXTURE
from channel_worker.pipeline.scene.texture_sampling import texture_modulation


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
    # Metres of the texture plane per pixel step along screen x and y, times the footprint.
    ux = (m[0] - u * a) * w * spacing
    uy = (m[1] - u * bb) * w * spacing
    vx = (m[3] - v * a) * w * spacing
    vy = (m[4] - v * bb) * w * spacing
    # sh has the TextureStore's fields (shading.Shading).
    mr, mg, mb = texture_modulation(sh, row, sh.texture_filter, u, v, ux, vx, uy, vy)
    return r * mr, g * mg, b * mb
