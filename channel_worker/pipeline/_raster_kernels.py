"""numba kernels for the depth-tested multi-sample rasterizer (see raster.py).

Coverage is decided exactly: vertices and samples sit on a 1/SUBPIXEL pixel grid and edge
functions are evaluated in int64, so two polygons that share an edge (same snapped endpoints)
compute exactly opposite values for it. The top-left rule then gives every sample that lies on a
shared edge to exactly one of the two polygons: no crack, no double hit.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _edges(fixed, s0, n, ex, ey, edx, edy, bias):
    """Edge setup: origin, direction and top-left bias of each edge of one polygon.

    Polygons arrive with negative doubled area (project.py), which makes the edge function
    E(P) = (Px - X0) dy - (Py - Y0) dx positive inside. In that orientation an edge is a left
    edge when dy > 0 and a top edge when dy == 0 and dx < 0; samples exactly on such an edge
    belong to the polygon (E >= 0), on any other edge they do not (E >= 1).
    """
    for i in range(n):
        k = i + 1 if i + 1 < n else 0
        ex[i] = fixed[s0 + i, 0]
        ey[i] = fixed[s0 + i, 1]
        edx[i] = fixed[s0 + k, 0] - fixed[s0 + i, 0]
        edy[i] = fixed[s0 + k, 1] - fixed[s0 + i, 1]
        top_left = edy[i] > 0 or (edy[i] == 0 and edx[i] < 0)
        bias[i] = 0 if top_left else 1


@njit(cache=True, parallel=True)
def raster_kernel(fixed, start, order, inv_z, colour, opacity, feature_id, offsets_fixed,
                  subpixel, buf_colour, buf_inv_z, buf_feature, blend):
    """Draw the polygons listed in order into the sample buffer.

    Opaque pass (blend False): a sample takes the polygon's colour, 1/z and identity where the
    polygon's 1/z is larger (nearer) than the stored one. Translucent pass (blend True): the
    polygon's colour is blended over the stored colour where it is nearer; 1/z and identity
    keep the opaque feature behind it. The pass runs rows of the image in parallel and walks the
    polygons in order within each row, so the result does not depend on the thread count.
    """
    h, w, s_count = buf_inv_z.shape
    n_poly = order.shape[0]
    # Bounding rows of every polygon, so each row visits only the polygons that touch it.
    row_lo = np.empty(n_poly, np.int64)
    row_hi = np.empty(n_poly, np.int64)
    col_lo = np.empty(n_poly, np.int64)
    col_hi = np.empty(n_poly, np.int64)
    for q in range(n_poly):
        p = order[q]
        x0 = fixed[start[p], 0]
        x1 = x0
        y0 = fixed[start[p], 1]
        y1 = y0
        for i in range(start[p] + 1, start[p + 1]):
            x0 = min(x0, fixed[i, 0])
            x1 = max(x1, fixed[i, 0])
            y0 = min(y0, fixed[i, 1])
            y1 = max(y1, fixed[i, 1])
        col_lo[q] = max(x0 // subpixel - 1, 0)
        col_hi[q] = min(x1 // subpixel + 1, w - 1)
        row_lo[q] = max(y0 // subpixel - 1, 0)
        row_hi[q] = min(y1 // subpixel + 1, h - 1)
    max_n = 3
    for p in range(start.shape[0] - 1):
        max_n = max(max_n, start[p + 1] - start[p])
    inv_sub = 1.0 / subpixel
    for y in prange(h):
        ex = np.empty(max_n, np.int64)
        ey = np.empty(max_n, np.int64)
        edx = np.empty(max_n, np.int64)
        edy = np.empty(max_n, np.int64)
        bias = np.empty(max_n, np.int64)
        for q in range(n_poly):
            if y < row_lo[q] or y > row_hi[q]:
                continue
            p = order[q]
            s0 = start[p]
            n = start[p + 1] - s0
            _edges(fixed, s0, n, ex, ey, edx, edy, bias)
            a = inv_z[p, 0]
            b = inv_z[p, 1]
            c = inv_z[p, 2]
            alpha = opacity[p]
            for x in range(col_lo[q], col_hi[q] + 1):
                for s in range(s_count):
                    px = x * subpixel + offsets_fixed[s, 0]
                    py = y * subpixel + offsets_fixed[s, 1]
                    inside = True
                    for i in range(n):
                        e = (px - ex[i]) * edy[i] - (py - ey[i]) * edx[i]
                        if e < bias[i]:
                            inside = False
                            break
                    if not inside:
                        continue
                    iz = np.float32(a * (px * inv_sub) + b * (py * inv_sub) + c)
                    if iz <= buf_inv_z[y, x, s]:
                        continue
                    if blend:
                        for ch in range(3):
                            buf_colour[y, x, s, ch] = alpha * colour[p, ch] + (1.0 - alpha) * buf_colour[y, x, s, ch]
                    else:
                        buf_inv_z[y, x, s] = iz
                        buf_feature[y, x, s] = feature_id[p]
                        for ch in range(3):
                            buf_colour[y, x, s, ch] = colour[p, ch]
