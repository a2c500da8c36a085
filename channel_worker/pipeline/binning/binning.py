"""Sub-area coverage: which features touch which sub-area, and which cover it completely.

The screen is divided into square sub-areas of `subarea` pixels (EP 0611020). For
each feature and each sub-area inside its bounding box, every edge's perpendicular distance d
from the sub-area centre is compared with the limiting distance dcrit = |e a| + |f b| (a, b the
half width and height): d < -dcrit means the whole sub-area is outside that edge, d > dcrit
that it is wholly inside, anything else that the edge may cross it. The per-edge outcodes are
AND-combined: outside any edge -> the feature misses the sub-area; inside every edge -> fully
covered (its samples need no edge test); otherwise partially covered.

Features are listed in each sub-area nearest first (by the largest 1/z over the feature), so
the visibility stage can stop reading a list once every sample holds an opaque feature nearer
than anything left in it.
"""

from __future__ import annotations

import numba
import numpy as np

from channel_worker.pipeline.contract import Bins, Edges

from ._binning_kernels import bin_classify_kernel, bin_fill_kernel, row_buckets

#: Guard band, pixels, added to every limiting distance. d is computed in float64 from
#: coordinates below 2^20 with relative rounding near 1e-16, so its absolute error is below
#: 1e-9 px; with this band a sub-area classed fully covered is inside every edge by a positive
#: margin at every point, which the exact integer sample test then also finds.
DCRIT_GUARD = 1e-6
#: Candidate (feature, sub-area) pairs per thread the binning kernels are given at least: the
#: demo frame's ten thousand took 0.34 ms on one thread of a 16-core Xeon and 0.55 ms on 16,
#: where starting and joining the threads of two parallel loops outweighed the work. A
#: scene with many more features still bins on every thread.
CANDIDATES_PER_THREAD = 32768


def bin_features(edges: Edges, start: np.ndarray, width: int, height: int, subarea: int) -> Bins:
    """Build the feature list of every sub-area.

    Args:
        edges: edge equations and bounds of the frame's polygons (edges.py).
        start: (N + 1,) polygon offsets into the edge rows (ScreenPolygons.start).
        width, height: raster size, pixels.
        subarea: sub-area edge length in pixels (RenderOptions.subarea, 1..64; 16 by
            measurement: smaller ones classify more sub-areas as fully covered but lengthen
            the lists, bench/bench_visibility.py).
    """
    size = int(subarea)
    tiles_x = -(-width // size)
    tiles_y = -(-height // size)
    half = size / 2.0
    dcrit = np.abs(edges.e) * half + np.abs(edges.f) * half + DCRIT_GUARD
    order = np.argsort(-edges.nearest_inv_z, kind="stable").astype(np.int64)
    counts = np.zeros(tiles_x * tiles_y, np.int64)
    rows = row_buckets(edges, order, size, tiles_y)
    classes = np.empty(int(rows[2][-1]), np.uint8)
    threads = numba.get_num_threads()
    numba.set_num_threads(max(1, min(threads, classes.shape[0] // CANDIDATES_PER_THREAD)))
    try:
        bin_classify_kernel(edges, start, dcrit, size, tiles_x, tiles_y, rows, classes, counts)
        tile_start = np.zeros(tiles_x * tiles_y + 1, np.int64)
        np.cumsum(counts, out=tile_start[1:])
        total = int(tile_start[-1])
        polygon = np.empty(total, np.int32)
        full = np.empty(total, np.bool_)
        bin_fill_kernel(edges, size, tiles_x, tiles_y, rows, classes, tile_start, polygon, full)
    finally:
        numba.set_num_threads(threads)
    return Bins(size=size, tiles_x=tiles_x, tiles_y=tiles_y, start=tile_start,
                polygon=polygon, full=full)
