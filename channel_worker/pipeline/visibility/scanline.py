"""Scan-line hidden-surface visibility, one sample per pixel centre (ARL Systems Note 77).

ARL Systems Note 77 (Sandor and Jost, 1981), "A scan line algorithm for computer generated
flight visuals", as a second renderer beside the sub-area one (EP 0611020), kept as an
independent cross-check: it reaches the same per-pixel answer by a different route.

- Edge generation (Note 77, 3.3, 3.5, 3.6): every polygon edge becomes an EDGE LIST entry with its
  first and last scan line (jmin, jmax), its orientation (ENTER where the scan enters the face,
  EXIT where it leaves; horizontal edges are a third kind here, a GATE that keeps or removes the
  whole line) and its face. The PRIORITY LIST orders the faces by centroid depth, nearest first.
- Frame Phase (4.1): the INCIDENCE LIST, the edges sorted by jmin.
- Line Phase (4.2): per scan line, the ACTIVE LIST drops edges past their jmax, steps the others'
  intercepts by the recursion i(j + 1) = i(j) + delta_i, appends the INCIDENCE LIST entries
  that start on the line and is re-sorted by intercept (insertion sort: nearly in order).
- Element Phase (4.3): walking the ACTIVE LIST left to right, the ENTER/EXIT routine turns faces
  on and off in the ON/OFF LIST, and the highest-priority face on is the one seen until the
  next intercept (BR register). Edges meeting the line at the same pixel go through the
  MULTIPLE EDGE routine: every ENTER first, then every EXIT.
- Horizon synthesis (3.7): the sky is the whole screen at the lowest priority and the earth a
  polygon bounded by the horizon line above it; every face is in front of both.

Where this implementation is stricter than the Note (docs/scanline.md): intercepts are exact
integer quotients on the 1/SUBPIXEL grid (remainder carried, not a 9-bit fraction), so a face
covers a pixel centre exactly when the exact edge test with the top-left rule says so, shared
edges leave no crack and no double cover, and ties at one pixel are decided by that rule; the
ON/OFF flag is a count, so a face is on only inside all of its active half-planes (and a face
that snapping left non-convex has every edge active over its whole height); faces
sharing one plane (scene "on") are kept together in the PRIORITY LIST, higher layer first, the
Note's precedence of runway markings over the runway (2.1).

Hidden surfaces are decided per face, not per pixel: where the centroid order of two
overlapping faces is not their depth order at a pixel (interpenetrating or cyclically
overlapping faces, a large face behind a small one whose centroid is farther) this renderer
shows the face the priority list prefers, and may legitimately differ from a depth buffer.
"""

from __future__ import annotations

import numba
import numpy as np

from channel_worker.pipeline.contract import SUBPIXEL, FrameConstants, SampleBuffer, ScreenPolygons
from services.rig.options import RenderOptions

from ._scanline_kernels import (
    N_STATS,
    STAT_ACTIVE_MAX,
    STAT_CROSSINGS,
    STAT_DROPPED,
    STAT_FIELD,
    STAT_MULTIPLE,
    STAT_ON_MAX,
    STAT_OVERFLOW,
    EdgeList,
    PriorityList,
    ScanOut,
    edge_list_kernel,
    scan_frame_kernel,
)

#: The one sample per pixel: its centre.
CENTRE_OFFSETS = np.array([[0.5, 0.5]], np.float64)

#: Bands of scan lines per thread. A band is the unit of parallel work (each builds its own
#: ACTIVE LIST at its first line); a few per thread, interleaved, balance sky rows against
#: busy ones.
BANDS_PER_THREAD = 4


def scanline_visibility(screen: ScreenPolygons, frame: FrameConstants, options: RenderOptions,
                        counters: dict[str, int]) -> SampleBuffer:
    """The sample store of one frame by the scan-line algorithm, one sample per pixel centre.

    Args:
        screen: the frame's projected polygons (snapped to 1/SUBPIXEL pixel, negative doubled
            area in y-down screen coordinates).
        frame: the frame's constants (raster size, screen mapping, horizon line: the sky and
            the earth are told apart by it alone).
        options: max_translucent, K, translucent faces kept per pixel (1..15); with_range.
        counters: receives the stage's counters (below).

    Returns:
        SampleBuffer with offsets [[0.5, 0.5]]: per pixel the face the priority list shows (or
        SKY_ID / EARTH_ID), up to K translucent faces ahead of it in priority order, nearest
        first, and the range in metres to the visible face at the pixel centre (+inf where no
        face is seen; None without with_range). Counters: "edges", "nonconvex_faces", "edge_crossings", "active_max",
        "multiple_edges", "on_max", "field_entries", "translucent_overflow" (pixels with more
        than K translucent faces ahead of the opaque one) and "translucent_dropped" (faces
        dropped from those pixels, the sub-area renderer's counter).
    """
    k = options.max_translucent
    h, w = frame.height, frame.width
    edges, nonconvex = _edge_list(screen, h)
    rank = _priority_list(screen)
    # INCIDENCE LIST: edges in the order the scan meets them (stable, so the same frame
    # always gives the same list).
    incidence = np.argsort(edges.jmin, kind="stable").astype(np.int64)
    out = ScanOut(np.empty((h, w, 1), np.int32), np.zeros((h, w, 1, k), np.int32),
                  np.zeros((h, w, 1), np.uint8), np.empty((h, w), np.float32))
    threads = numba.get_num_threads()
    n_bands = max(1, min(h, BANDS_PER_THREAD * threads))
    band_stats = np.zeros((n_bands, N_STATS), np.int64)
    faces = PriorityList(rank, screen.opacity >= 1.0, np.ascontiguousarray(screen.inv_z, np.float64))
    scan_frame_kernel(edges, incidence, faces, frame, n_bands, out, band_stats, threads)
    totals = band_stats.sum(axis=0)
    counters.update({
        "edges": int(edges.kind.shape[0]),
        "nonconvex_faces": nonconvex,
        "edge_crossings": int(totals[STAT_CROSSINGS]),
        "active_max": int(band_stats[:, STAT_ACTIVE_MAX].max()),
        "multiple_edges": int(totals[STAT_MULTIPLE]),
        "on_max": int(band_stats[:, STAT_ON_MAX].max()),
        "field_entries": int(totals[STAT_FIELD]),
        "translucent_overflow": int(totals[STAT_OVERFLOW]),
        "translucent_dropped": int(totals[STAT_DROPPED]),
    })
    return SampleBuffer(offsets=CENTRE_OFFSETS.copy(), opaque=out.opaque, translucent=out.trans,
                        translucent_count=out.trans_count,
                        polygon_range=out.range_m if options.with_range else None)


def _edge_list(screen: ScreenPolygons, height: int) -> tuple[EdgeList, int]:
    """The EDGE LIST (edge_list_kernel) as arrays, and how many faces had to be extended."""
    nv = screen.fixed.shape[0]
    n = screen.polygon_count
    kind = np.empty(nv, np.int64)
    poly = np.empty(nv, np.int64)
    jmin = np.empty(nv, np.int64)
    jmax = np.empty(nv, np.int64)
    num0 = np.empty(nv, np.int64)
    den = np.empty(nv, np.int64)
    step = np.empty(nv, np.int64)
    extended = np.zeros(n, np.int64)
    m = edge_list_kernel(np.ascontiguousarray(screen.fixed, np.int64),
                         np.ascontiguousarray(screen.start, np.int64), height,
                         (kind, poly, jmin, jmax, num0, den, step), extended)
    den = den[:m]
    step = step[:m]
    # The per-line increment as quotient and remainder (floor division: 0 <= step_r < den).
    # Guard: den >= 1 for every edge (S |dy| with dy != 0, or 1 for a horizontal edge).
    step_q = np.floor_divide(step, den)
    edges = EdgeList(kind[:m], poly[:m], jmin[:m], jmax[:m], num0[:m], den, step, step_q,
                     step - step_q * den)
    return edges, int(extended.sum())


def _priority_list(screen: ScreenPolygons) -> np.ndarray:
    """Per face its index in the PRIORITY LIST (0 is seen in front of everything else).

    The Note orders faces by the distance of their centroid; here by 1/z of the screen plane
    at the mean of the snapped vertices (larger is nearer). Faces on one plane bit for bit (a
    runway and its markings, scene "on") are one surface: they all take the nearest centroid
    1/z among them, so they sit together in the list and their layer orders them, higher
    first, as the Note's precedence puts markings over the runway. Remaining ties: the higher
    layer first, then the lower polygon index.
    """
    n = screen.polygon_count
    if n == 0:
        return np.zeros(0, np.int64)
    counts = np.diff(screen.start)
    # Guard: projection keeps only polygons of three or more vertices, so counts >= 3.
    centroid = np.add.reduceat(screen.fixed.astype(np.float64), screen.start[:-1], axis=0)
    centroid /= counts[:, None] * float(SUBPIXEL)
    abc = screen.inv_z
    inv_z = abc[:, 0] * centroid[:, 0] + abc[:, 1] * centroid[:, 1] + abc[:, 2]
    _, surface = np.unique(abc, axis=0, return_inverse=True)
    surface = surface.reshape(-1)
    nearest = np.full(surface.max() + 1, -np.inf)
    np.maximum.at(nearest, surface, inv_z)
    key = nearest[surface]
    # lexsort: the last key is the primary one.
    order = np.lexsort((np.arange(n), -screen.layer.astype(np.int64), -key))
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    return rank
