"""numba kernels for sub-area binning (see binning.py)."""

from __future__ import annotations

from numba import njit, prange

OUTSIDE = 0
PARTIAL = 1
FULL = 2


@njit(cache=True, inline="always")
def classify(p, start, e, f, g, dcrit, cx, cy):
    """Outcodes of every edge of polygon p against the sub-area centred at (cx, cy), combined.

    Per edge: d < -dcrit -> outside (the AND of the "not outside" bits becomes 0, stop);
    d > dcrit -> inside; otherwise the edge may cross the sub-area.
    """
    result = FULL
    for j in range(start[p], start[p + 1]):
        d = e[j] * cx + f[j] * cy + g[j]
        if d < -dcrit[j]:
            return OUTSIDE
        if d <= dcrit[j]:
            result = PARTIAL
    return result


@njit(cache=True, parallel=True)
def bin_count_kernel(edges, start, order, dcrit, size, tiles_x, tiles_y, counts):
    """Count the features touching each sub-area; rows of sub-areas run in parallel.

    edges: contract.Edges; start: polygon offsets into its rows; order: polygons nearest first;
    dcrit: each edge's limiting distance for this sub-area size.
    """
    x0, x1, y0, y1 = edges.x0, edges.x1, edges.y0, edges.y1
    e, f, g = edges.e, edges.f, edges.g
    half = size * 0.5
    for ty in prange(tiles_y):
        top = ty * size
        bottom = top + size - 1
        cy = top + half
        for q in range(order.shape[0]):
            p = order[q]
            if y1[p] < top or y0[p] > bottom:
                continue
            for tx in range(x0[p] // size, x1[p] // size + 1):
                if classify(p, start, e, f, g, dcrit, tx * size + half, cy) != OUTSIDE:
                    counts[ty * tiles_x + tx] += 1


@njit(cache=True, parallel=True)
def bin_fill_kernel(edges, start, order, dcrit, size, tiles_x, tiles_y, tile_start, out_polygon,
                    out_full):
    """Write the lists counted by bin_count_kernel, in the same (nearest-first) order.

    Each row of sub-areas is written by one thread only, so the cursors need no atomics and
    the lists do not depend on the thread count.
    """
    x0, x1, y0, y1 = edges.x0, edges.x1, edges.y0, edges.y1
    e, f, g = edges.e, edges.f, edges.g
    half = size * 0.5
    for ty in prange(tiles_y):
        top = ty * size
        bottom = top + size - 1
        cy = top + half
        cursor = tile_start[ty * tiles_x:(ty + 1) * tiles_x].copy()
        for q in range(order.shape[0]):
            p = order[q]
            if y1[p] < top or y0[p] > bottom:
                continue
            for tx in range(x0[p] // size, x1[p] // size + 1):
                c = classify(p, start, e, f, g, dcrit, tx * size + half, cy)
                if c != OUTSIDE:
                    k = cursor[tx]
                    out_polygon[k] = p
                    out_full[k] = c == FULL
                    cursor[tx] = k + 1
