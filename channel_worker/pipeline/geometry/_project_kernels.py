"""numba kernel for perspective projection and sub-pixel snapping (see project.py)."""

from __future__ import annotations

from numba import njit

from channel_worker.pipeline.contract import SUBPIXEL


@njit(cache=True)
def project_kernel(verts, start, mapping, limits, out):
    """Project, snap to the sub-pixel grid, drop repeated vertices and empty polygons.

    Screen x = (x / z) * sx_scale + sx_offset, y likewise. Guard: every z is >= the near
    distance (> 0) after clipping, so the divisions are safe. Snapped coordinates are clamped to
    the raster ([0, max]) because clipping leaves them on the boundary only to rounding.
    Output polygons are wound so that their doubled signed area is negative in y-down screen
    coordinates, the orientation the rasterizer's edge functions assume (interior > 0).
    mapping: (sx_scale, sx_offset, sy_scale, sy_offset) (view.screen_mapping); limits:
    (max_x, max_y) in 1/SUBPIXEL units; out: (fixed (Nv, 2), start (N + 1,), src (N,)).
    Returns (polygons out, vertices out).
    """
    sx_scale, sx_offset, sy_scale, sy_offset = mapping[0], mapping[1], mapping[2], mapping[3]
    max_x, max_y = limits
    out_fixed, out_start, out_src = out
    subpixel = float(SUBPIXEL)
    n_poly = start.shape[0] - 1
    n_out = 0
    v_out = 0
    out_start[0] = 0
    for p in range(n_poly):
        s0 = start[p]
        n = start[p + 1] - s0
        first = v_out
        m = 0
        for i in range(n):
            z = verts[s0 + i, 2]
            fx = round((verts[s0 + i, 0] / z * sx_scale + sx_offset) * subpixel)
            fy = round((verts[s0 + i, 1] / z * sy_scale + sy_offset) * subpixel)
            ix = min(max(int(fx), 0), max_x)
            iy = min(max(int(fy), 0), max_y)
            if m > 0 and out_fixed[first + m - 1, 0] == ix and out_fixed[first + m - 1, 1] == iy:
                continue
            out_fixed[first + m, 0] = ix
            out_fixed[first + m, 1] = iy
            m += 1
        while m > 1 and out_fixed[first + m - 1, 0] == out_fixed[first, 0] and \
                out_fixed[first + m - 1, 1] == out_fixed[first, 1]:
            m -= 1
        if m < 3:
            continue
        area2 = 0
        for i in range(m):
            k = i + 1 if i + 1 < m else 0
            area2 += (out_fixed[first + i, 0] * out_fixed[first + k, 1]
                      - out_fixed[first + k, 0] * out_fixed[first + i, 1])
        if area2 == 0:
            continue
        if area2 > 0:
            for i in range(m // 2):
                a = first + i
                b = first + m - 1 - i
                tx = out_fixed[a, 0]
                ty = out_fixed[a, 1]
                out_fixed[a, 0] = out_fixed[b, 0]
                out_fixed[a, 1] = out_fixed[b, 1]
                out_fixed[b, 0] = tx
                out_fixed[b, 1] = ty
        v_out += m
        n_out += 1
        out_start[n_out] = v_out
        out_src[n_out - 1] = p
    return n_out, v_out
