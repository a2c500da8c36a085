"""Resolve sample outputs to pixels."""

from __future__ import annotations

import numpy as np

from ._resolve_kernels import box_resolve_kernel
from .horizon import earth_dz_row, height_above_earth
from .project import screen_mapping
from .types import Database, Image, SampleBuffer, View


def resolve(buffer: SampleBuffer, view: View, database: Database) -> Image:
    """Box-filter the samples of each pixel into its colour; the pixel's range is the nearest.

    Returns:
        Image with linear RGB and range in metres (+inf where every sample sees sky).
    """
    h, w = view.height, view.width
    rgb = np.empty((h, w, 3), np.float32)
    range_m = np.empty((h, w), np.float32)
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    tx = (np.arange(w)[:, None] + buffer.offsets[None, :, 0] - sx_off) / sx_scale
    ty = (np.arange(h)[:, None] + buffer.offsets[None, :, 1] - sy_off) / sy_scale
    box_resolve_kernel(buffer.colour, buffer.inv_z, buffer.feature, tx, ty, earth_dz_row(view),
                       height_above_earth(database, view), rgb, range_m)
    return Image(rgb=rgb, range_m=range_m)
