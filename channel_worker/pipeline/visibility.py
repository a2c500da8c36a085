"""Multi-sample visibility with opaque and translucent features (seed 000, EP 0611020).

For every sampling point of every sub-area, the features of that sub-area's list are tested in
turn (no edge test where the sub-area is fully covered), and a small per-sample store keeps:

- the nearest opaque feature (its 1/z and identity; an opaque feature is never dropped);
- up to K translucent features nearer than it, nearest first. When a (K + 1)-th nearer
  translucent feature covers a sample, the farthest of them is dropped and counted in
  stats["translucent_dropped"]: it is the one seen through all K others, so its share of
  the sample is the smallest.

Depth is compared on 1/z evaluated exactly from each feature's plane. Coplanar features that
the scene declares to lie on one another share a plane bit for bit (scene "on"), so they tie
exactly at every sample and the declared layer decides, at any range, with no depth offset.

With terrain (a Background from the terrain stage) every sample starts out holding the
terrain as its nearest opaque feature, at the terrain's depth: polygons behind a hill are
hidden like polygons behind polygons (and the sub-area lists stop early behind it), and what
no polygon covers shows the background.

The store holds identities; the resolve stage turns them into colours.
"""

from __future__ import annotations

import numba
import numpy as np

from ._visibility_kernels import coverage_kernel, visibility_kernel
from .air import frame_air
from .binning import DEFAULT_SUBAREA, Bins, bin_features
from .edges import Edges, setup_edges
from .horizon import earth_dz_row, earth_dz_screen, height_above_earth
from .project import screen_mapping
from .types import (
    DEFAULT_MAX_TRANSLUCENT,
    SUBPIXEL,
    Background,
    Database,
    Image,
    SampleBuffer,
    ScreenPolygons,
    View,
    background_arrays,
    check_max_translucent,
    rgb_array,
)


def resolve_visibility(screen: ScreenPolygons, edges: Edges, bins: Bins, view: View,
                       offsets: np.ndarray, max_translucent: int = DEFAULT_MAX_TRANSLUCENT, *,
                       with_range: bool = True,
                       background: Background | None = None) -> SampleBuffer:
    """The sample store of one frame: nearest opaque and nearer translucent features per sample.

    Args:
        screen: the frame's projected polygons.
        edges: their edge equations (edges.setup_edges).
        bins: per-sub-area feature lists (binning.bin_features).
        view: the channel's view (raster size, horizon, screen mapping).
        offsets: (S, 2) sample positions inside the pixel (samples.sample_pattern).
        max_translucent: K, translucent features kept per sample (1..15).
        with_range: compute polygon_range (else it is None: a frame that only needs colour
            pays nothing for ranges).
        background: the terrain stage's output, or None (samples no polygon covers then see
            the sky or the earth plane); samples showing it hold BACKGROUND_ID.
    """
    k = check_max_translucent(max_translucent)
    h, w, s = view.height, view.width, offsets.shape[0]
    any_translucent = bool((screen.opacity < 1.0).any())
    # Without translucent polygons the store stays empty: zeroed counts cost no writes.
    trans = np.empty((h, w, s, k) if any_translucent else (1, 1, 1, k), np.int32)
    count = np.empty((h, w, s), np.uint8) if any_translucent else np.zeros((h, w, s), np.uint8)
    polygon_range = np.empty((h, w) if with_range else (1, 1), np.float32)
    opaque = np.empty((h, w, s), np.int32)
    stats = _run(screen, edges, bins, view, offsets, k, any_translucent, with_range,
                 opaque, trans, count, polygon_range, None, background, frame_air(None))
    return SampleBuffer(offsets=offsets, opaque=opaque, translucent=trans, translucent_count=count,
                        polygon_range=polygon_range if with_range else None, stats=stats)


def visible_pixels(screen: ScreenPolygons, edges: Edges, bins: Bins, view: View, database: Database,
                   offsets: np.ndarray, max_translucent: int = DEFAULT_MAX_TRANSLUCENT, *,
                   with_range: bool = True, stats: dict | None = None,
                   out: np.ndarray | None = None,
                   background: Background | None = None) -> Image:
    """The same visibility with the box filter applied inside each sub-area (seed 000: "an
    output for each pixel within a sub-area"): no sample store is written, which is what makes
    the default quality fast. Identical to resolve(resolve_visibility(...), filter="box") up to
    float32 summation order (tested).

    Args:
        database: for the sky and earth colours and the eye height above the earth.
        stats: if given, receives the visibility counters.
        out: (H, W, 3) float32 array to write the colours into (a caller rendering frame after
            frame keeps one, so the pages are not faulted in anew every frame).
        background: the terrain stage's output, or None; polygons are seen per sample
            through its air (the scene's haze and fog; None: clear air).
    """
    k = check_max_translucent(max_translucent)
    h, w = view.height, view.width
    rgb = rgb_array(out, h, w)
    range_m = np.empty((h, w) if with_range else (1, 1), np.float32)
    counters = _run(screen, edges, bins, view, offsets, k, bool((screen.opacity < 1.0).any()),
                    with_range, np.empty((1, 1, 1), np.int32), np.empty((1, 1, 1, k), np.int32),
                    np.empty((1, 1, 1), np.uint8), range_m, (database, rgb), background,
                    frame_air(background))
    if stats is not None:
        stats.update(counters)
    return Image(rgb=rgb, range_m=range_m if with_range else None)


def _run(screen, edges, bins, view, offsets, k, any_translucent, with_range, opaque, trans, count,
         polygon_range, fused, background, air) -> dict[str, int]:
    n_tiles = bins.tiles_x * bins.tiles_y
    dropped = np.zeros(n_tiles, np.int64)
    stopped = np.zeros(n_tiles, np.int64)
    if fused is None:
        database, rgb = None, np.empty((1, 1, 3), np.float32)
        sky = earth = np.zeros(3, np.float32)
        height = 1.0
    else:
        database, rgb = fused
        sky, earth = database.sky_colour, database.earth_colour
        height = height_above_earth(database, view)
    # Rows of sub-areas are handed to threads one at a time: their cost varies a lot.
    previous = numba.set_parallel_chunksize(1)
    try:
        _kernel(bins, view, screen, edges, offsets, any_translucent, with_range, opaque, trans, count,
                polygon_range, dropped, stopped, fused is not None, sky, earth, height, rgb,
                background, air)
    finally:
        numba.set_parallel_chunksize(previous)
    stats = dict(bins.stats)
    stats["translucent_dropped"] = int(dropped.sum())
    stats["entries_skipped_by_depth"] = int(stopped.sum())
    return stats


def _kernel(bins, view, screen, edges, offsets, any_translucent, with_range, opaque, trans, count,
            polygon_range, dropped, stopped, fused, sky, earth, height, rgb, background,
            air) -> None:
    bg_on, bg_rgb, bg_iz, bg_range, cloud_on, cloud = background_arrays(background)
    visibility_kernel(bins.start, bins.polygon, bins.full, bins.size, bins.tiles_x, view.width,
                      view.height, screen.start, edges.ia, edges.ib, edges.ic, edges.bias,
                      edges.x0, edges.x1, edges.y0, edges.y1, edges.nearest_inv_z,
                      screen.inv_z, screen.opacity, screen.layer.astype(np.int32),
                      _offsets_fixed(offsets), SUBPIXEL, np.array(earth_dz_screen(view)),
                      np.array(screen_mapping(view)), any_translucent, with_range,
                      opaque, trans, count, polygon_range, dropped, stopped,
                      fused, screen.colour, sky, earth, earth_dz_row(view), height, rgb, bg_on, bg_rgb, bg_iz,
                      bg_range, air, cloud_on, cloud)


def coverage_counts(screen: ScreenPolygons, width: int, height: int, offsets: np.ndarray, *,
                    subarea: int = DEFAULT_SUBAREA) -> np.ndarray:
    """(H, W, S) int32: how many polygons cover each sample, ignoring depth.

    Uses the renderer's edge setup and sub-area classification, but decides each sample with
    the direct exact edge test instead of the renderer's per-row run solver: the property
    tests check that a mesh covers each sample once here, and that the renderer's own store
    agrees with this sample for sample.
    """
    edges = setup_edges(screen, width, height)
    bins = bin_features(edges, screen.start, width, height, subarea)
    out = np.zeros((height, width, offsets.shape[0]), np.int32)
    coverage_kernel(bins.start, bins.polygon, bins.full, bins.size, bins.tiles_x, width, height,
                    screen.start, edges.ia, edges.ib, edges.ic, edges.bias,
                    edges.x0, edges.x1, edges.y0, edges.y1, _offsets_fixed(offsets), SUBPIXEL, out)
    return out


def _offsets_fixed(offsets: np.ndarray) -> np.ndarray:
    """Sample offsets on the 1/SUBPIXEL grid (every named pattern lies on it exactly)."""
    return np.round(np.asarray(offsets, np.float64) * SUBPIXEL).astype(np.int64)
