"""Multi-sample visibility with opaque and translucent features (EP 0611020).

The features of each sub-area's list are read nearest first. Each one's coverage of the
sub-area is built as bit masks from its edges, a sample row at a time (no edge test where it
covers the sub-area fully), and merged into the samples' coverage 64 at a time, after
N. Greene's coverage masks: samples that hold nothing take it without a depth test, held
samples are compared only where the order is ambiguous, and a feature wholly behind covered
samples costs one test. A small per-sample store keeps:

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

The store holds identities; the shading (shade/) turns them into colours, per sub-area on
the fused path (visible_pixels), or over the frame's store in the resolve stage.
"""

from __future__ import annotations

import numba
import numpy as np

from channel_worker.pipeline.binning.binning import bin_features
from channel_worker.pipeline.binning.edges import setup_edges
from channel_worker.pipeline.contract import (
    Background,
    Bins,
    Edges,
    FrameConstants,
    Image,
    SampleBuffer,
    ScreenPolygons,
    rgb_array,
    subpixel_offsets,
)
from channel_worker.pipeline.shade.group import ShadeFrame, shade_frame
from channel_worker.pipeline.shade.scratch import mask_layout
from services.rig.options import RenderOptions

from ._visibility_kernels import StoreOut, coverage_kernel, visibility_kernel


def sample_store(screen: ScreenPolygons, edges: Edges, bins: Bins, frame: FrameConstants,
                 background: Background, options: RenderOptions,
                 counters: dict[str, int]) -> SampleBuffer:
    """The sample store of one frame: nearest opaque and nearer translucent features per sample.

    Args:
        screen: the frame's projected polygons.
        edges: their edge equations (binning.edges.setup_edges).
        bins: per-sub-area feature lists (binning.binning.bin_features).
        frame: the frame's constants (raster size, sample positions, horizon, screen mapping).
        background: the background stage's output (or no_background()); samples no polygon
            covers see it (BACKGROUND_ID), or the sky or the earth plane without one.
        options: max_translucent (K, translucent features kept per sample) and with_range
            (compute polygon_range; else it is None and costs nothing).
        counters: receives the stage's counters (Bins.counters(), "translucent_dropped",
            "entries_skipped_by_depth", "entries_hidden").
    """
    k = options.max_translucent
    h, w, s = frame.height, frame.width, frame.offsets.shape[0]
    with_range = options.with_range
    any_translucent = bool((screen.opacity < 1.0).any())
    # Without translucent polygons the store stays empty: zeroed counts cost no writes.
    trans = np.empty((h, w, s, k) if any_translucent else (1, 1, 1, k), np.int32)
    count = np.empty((h, w, s), np.uint8) if any_translucent else np.zeros((h, w, s), np.uint8)
    polygon_range = np.empty((h, w) if with_range else (1, 1), np.float32)
    opaque = np.empty((h, w, s), np.int32)
    n_tiles = bins.tiles_x * bins.tiles_y
    out = StoreOut(False, with_range, any_translucent, opaque, trans, count, polygon_range,
                   np.empty((1, 1, 3), np.float32), np.zeros(n_tiles, np.int64),
                   np.zeros(n_tiles, np.int64), np.zeros(n_tiles, np.int64))
    _run(screen, edges, bins, out, counters, shade_frame(screen, frame, background, options, None))
    return SampleBuffer(offsets=frame.offsets, opaque=opaque, translucent=trans,
                        translucent_count=count,
                        polygon_range=polygon_range if with_range else None)


def visible_pixels(screen: ScreenPolygons, edges: Edges, bins: Bins, frame: FrameConstants,
                   background: Background, options: RenderOptions, counters: dict[str, int], *,
                   out: np.ndarray | None = None) -> Image:
    """The same visibility with the box filter applied inside each sub-area (EP 0611020: "an
    output for each pixel within a sub-area"): no sample store is written, which is what makes
    the default quality fast. Identical to resolve(sample_store(...)) with the box filter up
    to float summation order (tested).

    Args:
        out: (H, W, 3) float32 array to write the colours into (a caller rendering frame after
            frame keeps one, so the pages are not faulted in anew every frame).
    """
    k = options.max_translucent
    h, w = frame.height, frame.width
    rgb = rgb_array(out, h, w)
    range_m = np.empty((h, w) if options.with_range else (1, 1), np.float32)
    n_tiles = bins.tiles_x * bins.tiles_y
    pixels = StoreOut(True, options.with_range, bool((screen.opacity < 1.0).any()),
                      np.empty((1, 1, 1), np.int32), np.empty((1, 1, 1, k), np.int32),
                      np.empty((1, 1, 1), np.uint8), range_m, rgb, np.zeros(n_tiles, np.int64),
                      np.zeros(n_tiles, np.int64), np.zeros(n_tiles, np.int64))
    _run(screen, edges, bins, pixels, counters,
         shade_frame(screen, frame, background, options, edges))
    return Image(rgb=rgb, range_m=range_m if options.with_range else None)


def _run(screen: ScreenPolygons, edges: Edges, bins: Bins, out: StoreOut,
         counters: dict[str, int], sf: ShadeFrame) -> None:
    # Layers as int32, like the store's: one integer type in every depth comparison.
    visibility_kernel(bins, screen._replace(layer=screen.layer.astype(np.int32)), edges, sf.frame,
                      sf.background, sf.sh, sf.cov, out, numba.get_num_threads(),
                      mask_layout(bins.size, sf.frame.offsets_fixed))
    counters.update(bins.counters())
    counters["translucent_dropped"] = int(out.dropped.sum())
    counters["entries_skipped_by_depth"] = int(out.stopped.sum())
    counters["entries_hidden"] = int(out.hidden.sum())


def coverage_counts(screen: ScreenPolygons, width: int, height: int, offsets: np.ndarray, *,
                    subarea: int = RenderOptions.subarea) -> np.ndarray:
    """(H, W, S) int32: how many polygons cover each sample, ignoring depth.

    Uses the renderer's edge setup and sub-area classification, but decides each sample with
    the direct exact edge test instead of the renderer's per-row run solver: the property
    tests check that a mesh covers each sample once here, and that the renderer's own store
    agrees with this sample for sample.
    """
    edges = setup_edges(screen, width, height)
    bins = bin_features(edges, screen.start, width, height, subarea)
    out = np.zeros((height, width, offsets.shape[0]), np.int32)
    coverage_kernel(bins, screen, edges, subpixel_offsets(offsets), out)
    return out
