"""Sub-area coverage: which features touch which sub-area, and which cover it completely.

The screen is divided into square sub-areas of `subarea` pixels (seed 000, EP 0611020). For
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

from dataclasses import dataclass

import numpy as np

from ._binning_kernels import bin_count_kernel, bin_fill_kernel
from .edges import Edges

#: Guard band, pixels, added to every limiting distance. d is computed in float64 from
#: coordinates below 2^20 with relative rounding near 1e-16, so its absolute error is below
#: 1e-9 px; with this band a sub-area classed fully covered is inside every edge by a positive
#: margin at every point, which the exact integer sample test then also finds.
DCRIT_GUARD = 1e-6

#: Sub-area size, pixels, chosen by measurement (bench/bench_visibility.py): smaller ones
#: classify more sub-areas as fully covered but lengthen the lists; 16 balanced them best.
DEFAULT_SUBAREA = 16


@dataclass(frozen=True)
class Bins:
    """Per-sub-area feature lists, concatenated.

    Attributes:
        size: sub-area edge length, pixels.
        tiles_x, tiles_y: number of sub-areas across and down.
        start: (tiles_x * tiles_y + 1,) int64; the list of sub-area t (row-major) is
            entries start[t]:start[t + 1].
        polygon: (M,) int32 polygon index of each entry, nearest first within a list.
        full: (M,) bool, the polygon covers the whole sub-area.
    """

    size: int
    tiles_x: int
    tiles_y: int
    start: np.ndarray
    polygon: np.ndarray
    full: np.ndarray

    @property
    def stats(self) -> dict[str, int]:
        full = int(self.full.sum())
        return {"subarea_entries_full": full,
                "subarea_entries_partial": int(self.full.shape[0]) - full,
                "subarea_list_max": int(np.diff(self.start).max(initial=0))}


def check_subarea(subarea: int) -> int:
    """The size as an int, or ValueError naming the value."""
    if isinstance(subarea, bool) or not isinstance(subarea, (int, np.integer)) or not 1 <= subarea <= 256:
        raise ValueError(f"subarea: expected an integer number of pixels in 1..256, got {subarea!r}")
    return int(subarea)


def bin_features(edges: Edges, start: np.ndarray, width: int, height: int,
                 subarea: int = DEFAULT_SUBAREA) -> Bins:
    """Build the feature list of every sub-area.

    Args:
        edges: edge equations and bounds of the frame's polygons (edges.py).
        start: (N + 1,) polygon offsets into the edge rows (ScreenPolygons.start).
        width, height: raster size, pixels.
        subarea: sub-area edge length in pixels (1..256).

    Raises:
        ValueError: subarea out of range.
    """
    size = check_subarea(subarea)
    tiles_x = -(-width // size)
    tiles_y = -(-height // size)
    half = size / 2.0
    dcrit = np.abs(edges.e) * half + np.abs(edges.f) * half + DCRIT_GUARD
    order = np.argsort(-edges.nearest_inv_z, kind="stable").astype(np.int64)
    counts = np.zeros(tiles_x * tiles_y, np.int64)
    args = (order, start, edges.x0, edges.x1, edges.y0, edges.y1, edges.e, edges.f, edges.g,
            dcrit, size, tiles_x, tiles_y)
    bin_count_kernel(*args, counts)
    tile_start = np.zeros(tiles_x * tiles_y + 1, np.int64)
    np.cumsum(counts, out=tile_start[1:])
    total = int(tile_start[-1])
    polygon = np.empty(total, np.int32)
    full = np.empty(total, np.bool_)
    bin_fill_kernel(*args, tile_start, polygon, full)
    return Bins(size=size, tiles_x=tiles_x, tiles_y=tiles_y, start=tile_start,
                polygon=polygon, full=full)
