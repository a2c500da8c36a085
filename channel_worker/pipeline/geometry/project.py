"""Perspective projection with the channel's off-axis frustum."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import SUBPIXEL, Polygons, ScreenPolygons, View

from ._project_kernels import project_kernel
from .view import screen_mapping


def project(polys: Polygons, view: View) -> ScreenPolygons:
    """Project clipped eye-space polygons to snapped screen positions with depth planes.

    Depth is interpolated exactly: for a planar face n . p = d, along the ray through screen
    point (sx, sy) 1/z = (n_x tx + n_y ty + n_z) / d, and the tangents tx, ty are affine in
    (sx, sy), so 1/z = A sx + B sy + C. Guard: backface elimination keeps only faces with
    d < 0 strictly, so the divisions by d are safe.
    """
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    n = polys.polygon_count
    out_fixed = np.empty((polys.verts.shape[0], 2), np.int64)
    out_start = np.empty(n + 1, np.int64)
    out_src = np.empty(n, np.int64)
    n_out, v_out = project_kernel(np.ascontiguousarray(polys.verts), polys.start,
                                  np.array([sx_scale, sx_off, sy_scale, sy_off]),
                                  (view.width * SUBPIXEL, view.height * SUBPIXEL),
                                  (out_fixed, out_start, out_src))
    src = out_src[:n_out]
    plane = polys.plane[src]
    nx, ny, nz, d = plane[:, 0], plane[:, 1], plane[:, 2], plane[:, 3]
    # tx = (sx - sx_off) / sx_scale, ty = (sy - sy_off) / sy_scale
    a = nx / (sx_scale * d)
    b = ny / (sy_scale * d)
    c = (nz - nx * sx_off / sx_scale - ny * sy_off / sy_scale) / d
    screen = ScreenPolygons(
        fixed=out_fixed[:v_out],
        start=out_start[:n_out + 1].copy(),
        inv_z=np.column_stack([a, b, c]),
        colour=polys.colour[src],
        opacity=polys.opacity[src],
        feature_id=polys.feature_id[src],
        layer=polys.layer[src],
    )
    if polys.look is None or polys.surface is None:
        return screen
    # value = G . p + k on the face; with p = z (tx, ty, 1) and tx, ty affine in the screen
    # position, value / z = G . (tx, ty, 1) + k / z is affine in (sx, sy) too: numerators
    # over the 1/z plane, evaluated per sample (perspective-correct, any screen rotation).
    maps = polys.surface[src]
    gx, gy, gz, k = maps[..., 0], maps[..., 1], maps[..., 2], maps[..., 3]
    num = np.empty((n_out, 3, 3))
    num[..., 0] = gx / sx_scale + k * a[:, None]
    num[..., 1] = gy / sy_scale + k * b[:, None]
    num[..., 2] = gz - gx * sx_off / sx_scale - gy * sy_off / sy_scale + k * c[:, None]
    return screen._replace(look=polys.look[src], surface=num.reshape(n_out, 9))
