"""Clip eye-space polygons to the view frustum (Sutherland-Hodgman, near plane first)."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import Polygons, View

from ._clip_kernels import clip_kernel


def frustum_planes(view: View) -> np.ndarray:
    """(6, 4) planes (a, b, c, w), inside where a x + b y + c z + w >= 0, near plane first."""
    return np.array([
        [0.0, 0.0, 1.0, -view.near],
        [1.0, 0.0, -view.tan_left, 0.0],
        [-1.0, 0.0, view.tan_right, 0.0],
        [0.0, 1.0, -view.tan_bottom, 0.0],
        [0.0, -1.0, view.tan_top, 0.0],
        [0.0, 0.0, -1.0, view.far],
    ])


def clip(polys: Polygons, view: View) -> Polygons:
    """Clip every polygon to the frustum of the view.

    The near plane goes first so that geometry through or behind the eye plane is cut before
    any side plane sees it (a point behind the eye would otherwise pass the side tests with its
    signs flipped). Output polygons keep their attributes; empty ones are dropped.
    """
    n = polys.polygon_count
    planes = frustum_planes(view)
    cap = polys.verts.shape[0] + n * (planes.shape[0] + 1)
    out_verts = np.empty((cap, 3))
    out_start = np.empty(n + 1, np.int64)
    out_src = np.empty(n, np.int64)
    n_out, v_out = clip_kernel(np.ascontiguousarray(polys.verts), polys.start, planes,
                               out_verts, out_start, out_src)
    src = out_src[:n_out]
    return polys.take(src, out_verts[:v_out], out_start[:n_out + 1].copy())
