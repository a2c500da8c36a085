"""Depth-tested multi-sample rasterization of convex screen polygons, watertight."""

from __future__ import annotations

import numpy as np

from ._raster_kernels import raster_kernel
from .types import SUBPIXEL, SampleBuffer, ScreenPolygons


def rasterize(polys: ScreenPolygons, buffer: SampleBuffer) -> SampleBuffer:
    """Draw the polygons into the sample buffer (updated in place and returned).

    Opaque polygons go first with a depth test on 1/z; translucent ones (opacity < 1) follow,
    farthest first by the 1/z at their vertex centroid, each blended over whatever opaque
    feature is nearest at the sample. This first version has no per-sample translucency store,
    so intersecting translucent polygons blend in centroid order.
    """
    offsets_fixed = np.round(buffer.offsets * SUBPIXEL).astype(np.int64)
    opaque = np.nonzero(polys.opacity >= 1.0)[0].astype(np.int64)
    translucent = np.nonzero(polys.opacity < 1.0)[0].astype(np.int64)
    args = (polys.fixed, polys.start)
    attrs = (polys.inv_z, polys.colour, polys.opacity, polys.feature_id, offsets_fixed, SUBPIXEL,
             buffer.colour, buffer.inv_z, buffer.feature)
    if opaque.size:
        raster_kernel(*args, opaque, *attrs, False)
    if translucent.size:
        raster_kernel(*args, translucent[np.argsort(_centroid_inv_z(polys, translucent), kind="stable")],
                      *attrs, True)
    return buffer


def _centroid_inv_z(polys: ScreenPolygons, which: np.ndarray) -> np.ndarray:
    """1/z at the vertex centroid of each listed polygon (smaller = farther)."""
    counts = np.diff(polys.start)[which]
    sums = np.add.reduceat(polys.fixed.astype(np.float64), polys.start[:-1], axis=0)[which] \
        if polys.fixed.shape[0] else np.zeros((0, 2))
    centre = sums / counts[:, None] / SUBPIXEL
    abc = polys.inv_z[which]
    return abc[:, 0] * centre[:, 0] + abc[:, 1] * centre[:, 1] + abc[:, 2]
