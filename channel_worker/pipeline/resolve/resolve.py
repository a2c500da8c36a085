"""Resolve: shade every sample from the features it sees and filter samples into pixels."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from channel_worker.pipeline.contract import (
    Background,
    Edges,
    FrameConstants,
    Image,
    SampleBuffer,
    ScreenPolygons,
    rgb_array,
)
from channel_worker.pipeline.shade.group import shade_frame
from services.rig.options import RenderOptions

from ._resolve_kernels import StoreIn, box_kernel, filter_kernel, shade_kernel


def _box(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    return ((np.abs(dx) < 0.5) & (np.abs(dy) < 0.5)).astype(np.float64)


def _tent(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    return np.maximum(0.0, 1.0 - np.abs(dx)) * np.maximum(0.0, 1.0 - np.abs(dy))


def _gaussian(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    r2 = dx * dx + dy * dy
    return np.where(r2 <= 1.5 ** 2, np.exp(-r2 / (2.0 * 0.5 ** 2)), 0.0)


#: The reconstruction filter of each name registered in services.rig.options.FILTERS: weight of
#: a sample at (dx, dy) pixels from the pixel centre. box: the pixel's own samples, equal
#: weights (EP 0611020's pixel output); tent: bilinear, radius 1 pixel; gaussian: sigma 0.5
#: pixel, cut at 1.5. The wider two also read the samples of the 8 neighbouring pixels:
#: softer edges, less crawling on thin features.
FILTERS: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "box": _box,
    "tent": _tent,
    "gaussian": _gaussian,
}


def filter_weights(name: str, offsets: np.ndarray) -> np.ndarray:
    """(3, 3, S) weights of sample s of the pixel at offset (i - 1, j - 1), index [j, i, s]."""
    d = np.arange(-1, 2, dtype=np.float64)
    dx = d[None, :, None] + offsets[None, None, :, 0] - 0.5
    dy = d[:, None, None] + offsets[None, None, :, 1] - 0.5
    return FILTERS[name](dx, dy)


def resolve(buffer: SampleBuffer, screen: ScreenPolygons, frame: FrameConstants,
            background: Background, options: RenderOptions, *, edges: Edges | None = None,
            out: np.ndarray | None = None) -> Image:
    """Pixel colours from the sample store and the pixel's nearest range.

    A sample's colour is its translucent features, nearest first, each covering opacity of
    what is behind it, over the nearest opaque feature (or the background, sky or earth).

    Args:
        buffer: the sample store (visibility stage).
        screen: the frame's polygons the store refers to.
        frame: the frame's constants (sky and earth colours, horizon, screen mapping).
        background: the background stage's output the store's BACKGROUND_ID samples refer
            to; polygon samples are seen through its air (haze, fog) at their range.
        options: filter (a name of FILTERS) and coverage (with the box filter, "area" takes
            the exact area of pixels one edge crosses: _coverage_kernels).
        edges: the polygons' edges (binning.edges.setup_edges), which coverage "area" reads;
            without them every pixel is the mean of its samples.
        out: optional (H, W, 3) float32 array to write the colours into.

    Returns:
        Image with linear RGB and range in metres (+inf where every sample sees sky), the
        range only if the buffer has polygon ranges.
    """
    h, w = frame.height, frame.width
    rgb = rgb_array(out, h, w)
    want_range = buffer.polygon_range is not None
    range_m = np.empty((h, w) if want_range else (1, 1), np.float32)
    polygon_range = range_m if buffer.polygon_range is None else buffer.polygon_range
    k = buffer.translucent.shape[3]
    store = StoreIn(buffer.opaque, buffer.translucent.reshape(-1, k), buffer.translucent_count,
                    polygon_range, want_range, buffer.opaque.reshape(-1),
                    buffer.translucent_count.reshape(-1))
    sf = shade_frame(screen, frame, background, options, edges)
    if options.filter == "box":
        box_kernel(store, sf.frame, sf.background, sf.sh, sf.cov, rgb, range_m)
    else:
        samples = np.empty(buffer.opaque.shape + (3,), np.float32)
        shade_kernel(store, sf.frame, sf.background, sf.sh, samples, range_m)
        filter_kernel(samples, filter_weights(options.filter, buffer.offsets), rgb)
    return Image(rgb=rgb, range_m=range_m if want_range else None)
