"""Clouds of JP H07-76990: a coarse cloud database scanned like the ground, blended by range.

JP H07-76990: "Clouds are inserted by scanning another database ... by the same mechanism.
This separate database describes cloud patterns in three dimensions, similar to the way ground
is described. The cloud pattern is intentionally made very rough to produce a blurry cloud with
translucent edges ... the linear resolution of clouds is one-eighth the resolution of the
earth. ... an interpolation stage smooths the cloud scene between coarse pixels ... Pixel range
comparisons are used to determine what is visible."

Here the cloud database is a coarse 2-D grid of cells, each holding a cloud slab (base and top
heights, metres) of uniform extinction; the background stage scans it along the same azimuth
columns as the terrain at one eighth of the pre-image's resolution (CLOUD_FACTOR), integrating
each coarse row's ray through the slabs front to back (_cloud_kernels.scan_clouds_kernel), and
the warp interpolates that coarse image bilinearly and lays it over whatever lies beyond the
cloud's entry range (terrain, sky, earth plane, polygons).
"""

from __future__ import annotations

import math

import numpy as np

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.scene.database import Database

from ._cloud_kernels import scan_clouds_kernel
from ._groups import CLOUD_CHANNELS, CloudColumns, CloudImage, CloudSlabs
from .terrain import PreimageGrid

#: Pre-image texels per cloud texel along each axis (JP H07-76990: one eighth).
CLOUD_FACTOR = 8

#: Brightness of a cloud's base relative to its top: light through a cloud dims downwards.
BASE_SHADE = 0.62


def scan_clouds(database: Database, view: View, grid: PreimageGrid, air: np.ndarray) -> CloudImage:
    """The coarse cloud image of database.clouds: one cloud texel per CLOUD_FACTOR x
    CLOUD_FACTOR pre-image texels (JP H07-76990: one eighth of the linear resolution).

    Args:
        database: the scene; database.clouds is not None.
        view: the channel's view for this frame.
        grid: the view's pre-image grid (the cloud columns share its azimuth range).
        air: the frame's air array (air.air_params).

    Returns:
        The cloud image, its ratios counted in texels of grid (the terrain's pre-image).

    Raises:
        ValueError: the scene has no clouds.
    """
    clouds = database.clouds
    if clouds is None:
        raise ValueError("scan_clouds: the scene has no clouds")
    ncols = max(1, math.ceil(grid.ncols / CLOUD_FACTOR))
    nrows = max(1, math.ceil(grid.nrows / CLOUD_FACTOR))
    dphi = grid.span / ncols
    dtheta = (grid.theta1 - grid.theta0) / nrows
    # Texel centres stop short of +-90 deg, so 1 / cos stays finite.
    centres = np.clip(grid.theta0 + (np.arange(nrows) + 0.5) * dtheta,
                      -0.5 * math.pi + 1e-6, 0.5 * math.pi - 1e-6)
    eye = np.array([view.eye[0] - clouds.origin[0], view.eye[1] - clouds.origin[1], view.eye[2]])
    out = np.empty((ncols, nrows, CLOUD_CHANNELS), np.float32)
    slabs = CloudSlabs(clouds.base_m, clouds.top_m, clouds.density, clouds.cell_m, clouds.colour,
                       BASE_SHADE)
    columns = CloudColumns(grid.phi_lo, dphi, ncols, np.tan(centres), 1.0 / np.cos(centres),
                           np.sin(centres))
    scan_clouds_kernel(slabs, columns, eye, float(view.far), air, out)
    return CloudImage(True, out, dphi / grid.dphi, dtheta / grid.dtheta)
