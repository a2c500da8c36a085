"""numba kernel for Sutherland-Hodgman clipping of convex polygons (see clip.py)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _edge_point(a, b, da, db, out, k):
    """Write the crossing of segment ab with the plane into out[k].

    The endpoints are put in a canonical (lexicographic) order first, so the two polygons that
    share an edge compute bit-identical crossing points whichever way round they traverse it:
    that is what keeps clipped shared edges watertight.
    Guard: callers only call this when da and db have strictly different inside/outside
    signs (one >= 0, the other < 0), so da - db is never zero.
    """
    swap = False
    for i in range(3):
        if a[i] != b[i]:
            swap = a[i] > b[i]
            break
    if swap:
        t = db / (db - da)
        for i in range(3):
            out[k, i] = b[i] + t * (a[i] - b[i])
    else:
        t = da / (da - db)
        for i in range(3):
            out[k, i] = a[i] + t * (b[i] - a[i])


@njit(cache=True)
def clip_kernel(verts, start, planes, out_verts, out_start, out_src):
    """Clip each polygon against every plane (a, b, c, w): inside where a x + b y + c z + w >= 0.

    Planes are applied in the given order (the near plane first, so that nothing behind the eye
    reaches the side planes). Returns (polygons out, vertices out); polygons left with fewer
    than three vertices are dropped. out_src[i] is the input index of output polygon i.
    """
    n_poly = start.shape[0] - 1
    n_planes = planes.shape[0]
    max_n = 3
    for p in range(n_poly):
        max_n = max(max_n, start[p + 1] - start[p])
    cap = max_n + n_planes + 1
    buf_a = np.empty((cap, 3))
    buf_b = np.empty((cap, 3))
    dist = np.empty(cap)
    n_out = 0
    v_out = 0
    out_start[0] = 0
    for p in range(n_poly):
        s0 = start[p]
        n = start[p + 1] - s0
        all_in = True
        for j in range(n_planes):
            for i in range(n):
                v = verts[s0 + i]
                if planes[j, 0] * v[0] + planes[j, 1] * v[1] + planes[j, 2] * v[2] + planes[j, 3] < 0.0:
                    all_in = False
                    break
            if not all_in:
                break
        if all_in:
            for i in range(n):
                for c in range(3):
                    out_verts[v_out + i, c] = verts[s0 + i, c]
            v_out += n
            n_out += 1
            out_start[n_out] = v_out
            out_src[n_out - 1] = p
            continue
        for i in range(n):
            for c in range(3):
                buf_a[i, c] = verts[s0 + i, c]
        src = buf_a
        dst = buf_b
        for j in range(n_planes):
            if n < 3:
                break
            for i in range(n):
                dist[i] = planes[j, 0] * src[i, 0] + planes[j, 1] * src[i, 1] + planes[j, 2] * src[i, 2] + planes[j, 3]
            m = 0
            for i in range(n):
                k = i + 1 if i + 1 < n else 0
                d_i = dist[i]
                d_k = dist[k]
                if d_i >= 0.0:
                    for c in range(3):
                        dst[m, c] = src[i, c]
                    m += 1
                if (d_i >= 0.0) != (d_k >= 0.0):
                    _edge_point(src[i], src[k], d_i, d_k, dst, m)
                    m += 1
            n = m
            tmp = src
            src = dst
            dst = tmp
        if n < 3:
            continue
        for i in range(n):
            for c in range(3):
                out_verts[v_out + i, c] = src[i, c]
        v_out += n
        n_out += 1
        out_start[n_out] = v_out
        out_src[n_out - 1] = p
    return n_out, v_out
