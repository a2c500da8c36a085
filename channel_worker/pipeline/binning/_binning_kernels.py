"""numba kernels for sub-area binning (see binning.py)."""

from __future__ import annotations

import numpy as np
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


@njit(cache=True)
def row_buckets(edges, order, size, tiles_y):
    """The polygons that reach each row of sub-areas, nearest first (a counting sort of
    `order` by row), and how many (polygon, sub-area) pairs of its bounds each row holds.

    Returns (row_start (tiles_y + 1,), row_polygon, pair_start (tiles_y + 1,)): row ty's
    polygons are row_polygon[row_start[ty]:row_start[ty + 1]], its pairs are slots
    pair_start[ty] .. pair_start[ty + 1] - 1 of the classification buffer.
    """
    x0, x1, y0, y1 = edges.x0, edges.x1, edges.y0, edges.y1
    row_start = np.zeros(tiles_y + 1, np.int64)
    pair_start = np.zeros(tiles_y + 1, np.int64)
    for q in range(order.shape[0]):
        p = order[q]
        if y1[p] < y0[p] or x1[p] < x0[p]:
            continue
        span = x1[p] // size - x0[p] // size + 1
        for ty in range(y0[p] // size, y1[p] // size + 1):
            row_start[ty + 1] += 1
            pair_start[ty + 1] += span
    for ty in range(tiles_y):
        row_start[ty + 1] += row_start[ty]
        pair_start[ty + 1] += pair_start[ty]
    row_polygon = np.empty(row_start[tiles_y], np.int64)
    cursor = row_start[:tiles_y].copy()
    for q in range(order.shape[0]):
        p = order[q]
        if y1[p] < y0[p] or x1[p] < x0[p]:
            continue
        for ty in range(y0[p] // size, y1[p] // size + 1):
            row_polygon[cursor[ty]] = p
            cursor[ty] += 1
    return row_start, row_polygon, pair_start


@njit(cache=True, parallel=True)
def bin_classify_kernel(edges, start, dcrit, size, tiles_x, tiles_y, rows, classes, counts):
    """Classify every (polygon, sub-area) pair of each row of sub-areas once (classes, in
    row_buckets' slots) and count the features touching each sub-area; rows run in parallel.
    edges: contract.Edges; start: polygon offsets into its rows; dcrit: each edge's limiting
    distance for this sub-area size; rows: row_buckets' (row_start, row_polygon, pair_start).
    """
    row_start, row_polygon, pair_start = rows
    x0, x1 = edges.x0, edges.x1
    e, f, g = edges.e, edges.f, edges.g
    half = size * 0.5
    for ty in prange(tiles_y):
        cy = ty * size + half
        slot = pair_start[ty]
        for k in range(row_start[ty], row_start[ty + 1]):
            p = row_polygon[k]
            for tx in range(x0[p] // size, x1[p] // size + 1):
                c = classify(p, start, e, f, g, dcrit, tx * size + half, cy)
                classes[slot] = c
                slot += 1
                if c != OUTSIDE:
                    counts[ty * tiles_x + tx] += 1


@njit(cache=True, parallel=True)
def bin_fill_kernel(edges, size, tiles_x, tiles_y, rows, classes, tile_start, out_polygon,
                    out_full):
    """Write the lists counted by bin_classify_kernel from its classes, in the same
    (nearest-first) order. Each row of sub-areas is written by one thread only, so the
    cursors need no atomics and the lists do not depend on the thread count.
    """
    row_start, row_polygon, pair_start = rows
    x0, x1 = edges.x0, edges.x1
    for ty in prange(tiles_y):
        cursor = tile_start[ty * tiles_x:(ty + 1) * tiles_x].copy()
        slot = pair_start[ty]
        for k in range(row_start[ty], row_start[ty + 1]):
            p = row_polygon[k]
            for tx in range(x0[p] // size, x1[p] // size + 1):
                c = classes[slot]
                slot += 1
                if c != OUTSIDE:
                    k_out = cursor[tx]
                    out_polygon[k_out] = p
                    out_full[k_out] = c == FULL
                    cursor[tx] = k_out + 1
