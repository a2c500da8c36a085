"""Analytic edge coverage for the box filter (RenderOptions.coverage = "area").

S point samples estimate how much of a pixel an edge covers to within the pattern's
half-plane discrepancy (0.31 for rgss4, 0.17 for d3d16: coverage_reference.
half_plane_discrepancy); on random eye-facing quads nine tenths of the squared error of every
pattern lies in pixels one straight edge crosses. For such a pixel the covered area has a closed
form, so it is computed instead of estimated, from the snapped geometry the samples were tested
against (the exact int64 edge functions of contract.Edges). The samples still decide what is
seen; the area only replaces their count where it is certain to be exact:

- the pixel's samples see exactly two features, and nothing translucent (sky, earth or the
  background count as one feature "behind" without edges; the horizon must not cross the
  pixel: its four corners on one side);
- of the two, one polygon P has exactly one edge whose line crosses the open pixel square and
  the other has none (it covers the whole square, so P is in front), or both have exactly one
  and it is the same line, reversed (a shared mesh edge);
- every sample that does not see P lies outside that edge (nothing else hides part of P in
  the pixel: terrain, an interpenetrating face).

The pixel's colour is then Q + a (P - Q), a the exact area of the pixel inside P's edge, each
feature's colour shaded as its first sample's (shading.shade_sample, so haze, fog and clouds
apply as on every other path). Anything else (a vertex inside the pixel, two different edges,
translucency, a sliver no sample caught) keeps the samples' estimate. Both box paths (the fused
box_subarea and box_kernel over the sample store) call edge_pixel with the same samples, so
they stay identical.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from channel_worker.pipeline.contract import (
    BACKGROUND_ID,
    EARTH_ID,
    SKY_ID,
    SUBPIXEL,
    Edges,
    ScreenPolygons,
)
from channel_worker.pipeline.jit import borrowing

from .shading import eye_ray, flat_colour, sample_point, shade_sample
from .texturing import varies

#: The features a pixel's samples see that have no edges (sky, earth, background), as one.
_BEHIND = -1


class Coverage(NamedTuple):
    """What edge_pixel reads, for one frame.

    Attributes:
        on: analytic coverage of single-edge pixels (coverage "area", box filter, >= 2 samples).
        start: (N + 1,) int64 each polygon's rows of the edge arrays (ScreenPolygons.start).
        ia, ib, ic, bias: (Nv,) int64 the exact edge functions (contract.Edges).
    """

    on: bool
    start: np.ndarray
    ia: np.ndarray
    ib: np.ndarray
    ic: np.ndarray
    bias: np.ndarray


def coverage_group(on: bool, screen: ScreenPolygons, edges: Edges | None) -> Coverage:
    """The frame's Coverage; off (one-element stand-ins) when on is False or edges is None."""
    if not on or edges is None:
        z = np.zeros(1, np.int64)
        return Coverage(False, z, z, z, z, z)
    return Coverage(True, screen.start, edges.ia, edges.ib, edges.ic, edges.bias)


@njit(cache=True, inline="always")
def square_fraction(a, b, c):
    """Area of the part of the unit square 0 <= u, v <= 1 where a u + b v + c > 0.

    Reflections (u -> 1 - u where a < 0, likewise v, then swapping u and v) leave the area and
    give a >= b >= 0; the part where a u + b v < t = -c is then a triangle, a trapezoid or the
    square less a triangle, by where t lies among 0, b, a, a + b.
    Guards: a = b = 0 (no line) is decided by the sign of c before any division; b = 0 (the
    line parallel to an axis) takes the trapezoid's limit t / a with a > 0; a b > 0 otherwise.
    """
    if a < 0.0:
        c += a
        a = -a
    if b < 0.0:
        c += b
        b = -b
    if b > a:
        a, b = b, a
    t = -c
    if t <= 0.0:
        return 1.0
    if t >= a + b:
        return 0.0
    if b == 0.0:
        return 1.0 - t / a
    if t < b:
        outside = t * t / (2.0 * a * b)
    elif t <= a:
        outside = (t - 0.5 * b) / a
    else:
        s = a + b - t
        outside = 1.0 - s * s / (2.0 * a * b)
    return 1.0 - outside


@njit(cache=True, inline="always")
def _crossing(cov, p, x, y):
    """(how many of polygon p's edges have a line crossing the open square of pixel (x, y),
    counted up to 2; the row of the last one). Exact: the edge function at the square's lowest
    and highest corner, in int64 (the limiting-distance test |d| < dcrit of EP 0611020)."""
    count = 0
    row = -1
    for j in range(cov.start[p], cov.start[p + 1]):
        a = cov.ia[j] * SUBPIXEL
        b = cov.ib[j] * SUBPIXEL
        lo = cov.ia[j] * (x * SUBPIXEL) + cov.ib[j] * (y * SUBPIXEL) + cov.ic[j]
        lo += min(a, 0) + min(b, 0)
        if lo < 0 < lo + abs(a) + abs(b):
            count += 1
            row = j
            if count == 2:
                break
    return count, row


@njit(cache=True, inline="always")
def _seen(f):
    """A sample's feature as edge_pixel counts it: a polygon, or _BEHIND for everything
    without edges (the fused store's uncovered -1 and terrain, the store's sky, earth and
    background ids)."""
    return f if f >= 0 else _BEHIND


@njit(cache=True, inline="always")
def edge_pixel(sf, ids, counts, translucent, t_id, base, stride, x, y):
    """(applies, r, g, b): pixel (x, y)'s colour by analytic coverage (the module docstring),
    or applies = False where its samples' estimate stays.

    sf: the frame's ShadeFrame (group.py: its frame, background, Shading and Coverage).
    ids, counts: the pixel's samples' nearest opaque feature and translucent count at
    ids[base + s stride], counts[base + s stride] (visibility's Scratch: stride the sub-area's
    width; the flat sample store: stride 1), counts
    read only if translucent (the Scratch of a frame without translucency has one count);
    t_id their translucent features (not read: nothing translucent here).
    """
    cov, frame, background, sh = sf.cov, sf.frame, sf.background, sf.sh
    s_count = frame.offsets_fixed.shape[0]
    f0 = _seen(ids[base])
    f1 = f0
    s1 = 0
    for s in range(s_count):
        if translucent and counts[base + s * stride] != 0:
            return False, 0.0, 0.0, 0.0
        f = _seen(ids[base + s * stride])
        if f == f0:
            continue
        if f1 == f0:
            f1 = f
            s1 = s
        elif f != f1:
            return False, 0.0, 0.0, 0.0
    if f1 == f0:
        return False, 0.0, 0.0, 0.0
    n0, j0 = 0, -1
    if f0 >= 0:
        n0, j0 = _crossing(cov, f0, x, y)
    n1, j1 = 0, -1
    if f1 >= 0:
        n1, j1 = _crossing(cov, f1, x, y)
    if n0 == 1 and n1 == 0:
        p, j, q, sp, sq = f0, j0, f1, 0, s1
    elif n1 == 1 and n0 == 0:
        p, j, q, sp, sq = f1, j1, f0, s1, 0
    elif (n0 == 1 and n1 == 1 and cov.ia[j0] == -cov.ia[j1] and cov.ib[j0] == -cov.ib[j1]
          and cov.ic[j0] == -cov.ic[j1]):
        p, j, q, sp, sq = f0, j0, f1, 0, s1
    else:
        return False, 0.0, 0.0, 0.0
    # A sample that does not see P must lie outside its edge, or something hides part of P.
    ia, ib, ic, bias = cov.ia[j], cov.ib[j], cov.ic[j], cov.bias[j]
    for s in range(s_count):
        if _seen(ids[base + s * stride]) != p:
            px = x * SUBPIXEL + frame.offsets_fixed[s, 0]
            py = y * SUBPIXEL + frame.offsets_fixed[s, 1]
            if ia * px + ib * py + ic >= bias:
                return False, 0.0, 0.0, 0.0
    # What "behind" is: the background's pixel, or the sky or earth if the horizon (affine:
    # its extremes are at corners) does not cross the pixel.
    behind = BACKGROUND_ID
    if q == _BEHIND and not background.on:
        kx, ky, k0 = frame.horizon[0], frame.horizon[1], frame.horizon[2]
        h = kx * x + ky * y + k0
        lo = h + min(kx, 0.0) + min(ky, 0.0)
        hi = h + max(kx, 0.0) + max(ky, 0.0)
        if lo >= 0.0:
            behind = SKY_ID
        elif hi < 0.0:
            behind = EARTH_ID
        else:
            return False, 0.0, 0.0, 0.0
    pr, pg, pb = _feature_colour(frame, sh, t_id, ids, base, stride, p, x, y, sp)
    qr, qg, qb = _feature_colour(frame, sh, t_id, ids, base, stride, q if q >= 0 else behind, x,
                                 y, sq)
    # Area inside P's edge: E = ia X + ib Y + ic over the pixel, in pixel units u, v and
    # divided by SUBPIXEL (the area does not change with the scale): ia u + ib v + E0.
    e0 = ia * (x * SUBPIXEL) + ib * (y * SUBPIXEL) + ic
    a = square_fraction(float(ia), float(ib), e0 / SUBPIXEL)
    # Q + a (P - Q): exactly Q's colour where both are one colour (a mesh's shared edge).
    return True, qr + a * (pr - qr), qg + a * (pg - qg), qb + a * (pb - qb)


@njit(cache=True, inline="always")
def _feature_colour(frame, sh, t_id, ids, base, stride, f, x, y, s):
    """Feature f's colour in pixel (x, y) as _colour gives it; a polygon, the sky or the earth
    whose colour varies neither over the pixel nor with range is its flat colour, with no call
    and no sample shaded (most edge pixels: the call alone passes the whole Shading group)."""
    if not sh.by_range and f != BACKGROUND_ID and (f < 0 or not varies(sh, f)):
        cr, cg, cb = flat_colour(sh, f)
        return float(cr), float(cg), float(cb)
    # One signature of _colour (a compile each) whatever integer types hold the ids.
    return _colour(frame, sh, t_id, ids, np.int64(base), np.int64(stride), np.int64(f),
                   np.int64(x), np.int64(y), np.int64(s))


# Not inlined: edge_pixel is inlined into both box paths, and the sample shading this inlines
# (twice, once in a loop) more than doubled their compile; it runs only for the pixels that
# take an exact area.
@borrowing
def _colour(frame, sh, t_id, ids, base, stride, f, x, y, s):
    """Feature f's colour in pixel (x, y), through the air: the mean of the pixel's samples that
    see it (ids[base + k stride] == f; for what has no edges, the background, sky or earth, sample s),
    so that the area weighs what the samples would have seen (a texture varies over them)."""
    r = 0.0
    g = 0.0
    b = 0.0
    n = 0
    for k in range(frame.offsets_fixed.shape[0]):
        if k == s or (f >= 0 and ids[base + k * stride] == f):
            r, g, b = _sample(frame, sh, t_id, f, x, y, k, (r, g, b))
            n += 1
    # Guard: sample s is always taken, so n >= 1.
    inv = 1.0 / n
    return r * inv, g * inv, b * inv


@njit(cache=True, inline="always")
def _sample(frame, sh, t_id, f, x, y, s, acc):
    """acc plus feature f's colour as sample s of pixel (x, y) sees it, through the air."""
    sx, sy = sample_point(frame, x, y, s)
    ray = (1.0, 0.0, 0.0)
    if sh.by_range:
        _, _, length, sin_el, cos_ax = eye_ray(frame, sh, sx, sy)
        ray = (length, sin_el, cos_ax)
    return shade_sample(sh, y, x, (sx, sy), ray, f, 0, t_id, 0, acc)
