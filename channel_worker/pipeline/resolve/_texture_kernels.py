"""TEMPORARY stand-in until the texture kernels land (helper branch tex)."""
from __future__ import annotations
import math
from numba import njit
@njit(cache=True, inline="always")
def texel_bilinear(store, t, level, x, y):
    lv = min(level, store.levels[t] - 1)
    off, lw, lh = store.level[t, lv, 0], store.level[t, lv, 1], store.level[t, lv, 2]
    w = 1 << lw
    h = 1 << lh
    fx = x / (1 << lv) - 0.5
    fy = y / (1 << lv) - 0.5
    x0 = math.floor(fx)
    y0 = math.floor(fy)
    ax = fx - x0
    ay = fy - y0
    i0 = int(x0) & (w - 1)
    i1 = (i0 + 1) & (w - 1)
    j0 = int(y0) & (h - 1)
    j1 = (j0 + 1) & (h - 1)
    r = 0.0
    g = 0.0
    b = 0.0
    for jj, wy in ((j0, 1.0 - ay), (j1, ay)):
        for ii, wx in ((i0, 1.0 - ax), (i1, ax)):
            k = off + jj * w + ii
            wt = wx * wy
            r += wt * store.texels[k, 0]
            g += wt * store.texels[k, 1]
            b += wt * store.texels[k, 2]
    return r, g, b
@njit(cache=True, inline="always")
def texel_trilinear(store, t, x, y, lod):
    if lod <= 0.0:
        return texel_bilinear(store, t, 0, x, y)
    l0 = int(math.floor(lod))
    f = lod - l0
    r0, g0, b0 = texel_bilinear(store, t, l0, x, y)
    r1, g1, b1 = texel_bilinear(store, t, l0 + 1, x, y)
    return r0 + f * (r1 - r0), g0 + f * (g1 - g0), b0 + f * (b1 - b0)
@njit(cache=True, inline="always")
def fade_amplitude(finest, rho):
    if not math.isfinite(rho):
        return 0.0
    q = 2.0 * finest * rho
    if q <= 0.5:
        return 1.0
    if q >= 1.0:
        return 0.0
    t = (1.0 - q) * 2.0
    return t * t * (3.0 - 2.0 * t)
