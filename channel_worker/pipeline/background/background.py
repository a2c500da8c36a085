"""Background stage: what every sample sees behind the polygons (docs/terrain.md, docs/fog.md).

The voxel terrain (terrain.py), the sky and the earth plane, the coarse clouds (clouds.py), all
through the haze (haze.py) and the layered fog (fog/), in one Background that the visibility
stage starts every sample from. The frame's air (air.py) is built here, once, and handed on in
the Background to the stages that see polygons through it. A scene with none of terrain, haze,
fog or clouds does not run this stage (render.py).
"""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import (
    F_COARSENED,
    Background,
    Bins,
    FrameConstants,
    View,
    no_background,
    no_cloud,
)
from channel_worker.pipeline.scene.database import Database
from services.rig.options import RenderOptions

from ._terrain_kernels import PRE_CHANNELS, sky_earth_kernel, warp_kernel
from .air import air_params
from .clouds import scan_clouds
from .haze import sky_haze_table
from .terrain import WARP_BLOCK, PreimageGrid, preimage_grid, scan_terrain


def render_background(database: Database, view: View, frame: FrameConstants,
                      options: RenderOptions, bins: Bins | None, counters: dict[str, int]) -> Background:
    """The terrain, the sky and earth through haze and fog, and the clouds every sample sees.

    Args:
        database: the scene (database.terrain, .haze, .fog, .clouds, sky, earth); at least one
            of terrain, haze, fog and clouds.
        view: the channel's view for this frame.
        frame: the frame's constants (sample offsets, screen mapping, horizon).
        options: terrain_bias (voxels 2**bias to 2**(bias + 1) pixels wide) and
            fog_table_subdivision.
        bins: the frame's sub-area lists: per-sample depth (Background.inv_z) is needed only in
            the sub-areas that hold polygons to test against the terrain; elsewhere it is 0.
            None: everywhere (tests and tools that look at the background alone).
        counters: receives "terrain_voxels" (voxels visited), "terrain_columns",
            "terrain_rows", "terrain_eye_clamped", and with fog "fog_table_coarsened" (1 if
            the eye is so far from the strata that the table was coarsened).
    """
    terrain = database.terrain
    if terrain is None and database.haze is None and database.fog is None and database.clouds is None:
        return no_background()
    h, w, s = frame.height, frame.width, frame.offsets.shape[0]
    stats = {"terrain_voxels": 0, "terrain_columns": 0, "terrain_rows": 0,
             "terrain_eye_clamped": 0}
    air = air_params(database, view, options.fog_table_subdivision)
    if database.fog is not None:
        stats["fog_table_coarsened"] = int(air[F_COARSENED])
    if terrain is None and database.clouds is None:
        background = _sky_and_earth(frame, air)
        counters.update(stats)
        return background
    grid = preimage_grid(view)
    if terrain is None:
        pre = np.zeros((1, 1, PRE_CHANNELS), np.float32)
        full, phi_lo, dphi, theta0, dtheta = grid.full, grid.phi_lo, grid.span, grid.theta0, \
            grid.theta1 - grid.theta0
    else:
        pre = scan_terrain(database, view, grid, air, options.terrain_bias, stats)
        full, phi_lo, dphi, theta0, dtheta = grid.full, grid.phi_lo, grid.dphi, grid.theta0, \
            grid.dtheta
    if bins is None:
        tile, need = max(h, w), np.ones(1, np.bool_)
    else:
        tile, need = int(bins.size), np.ascontiguousarray(np.diff(bins.start) > 0, np.bool_)
    cloud_on = database.clouds is not None
    if cloud_on:
        cloud_pre, col_ratio, row_ratio = scan_clouds(database, view, grid, air)
        cloud = np.empty((h, w, 5), np.float32)
        if terrain is None:
            # The warp's coordinates are then those of the one-texel stand-in pre-image.
            col_ratio, row_ratio = col_ratio / grid.ncols, row_ratio / grid.nrows
    else:
        cloud_pre, col_ratio, row_ratio = np.zeros((1, 1, 5), np.float32), 1.0, 1.0
        cloud = no_cloud()
    rgb = np.empty((h, w, 3), np.float32)
    inv_z = np.empty((h, w, s), np.float32)
    range_m = np.empty((h, w), np.float32)
    warp_kernel(pre, full, phi_lo, dphi, theta0, dtheta, frame.world_to_eye, frame.mapping,
                frame.offsets, w, h, frame.horizon, frame.dz_row, frame.height_above, frame.sky,
                frame.earth, air, *_sky_haze(air, grid), float(database.terrain_margin_m),
                WARP_BLOCK, cloud_on, cloud_pre, col_ratio, row_ratio, tile, need, rgb, inv_z,
                range_m, cloud)
    counters.update(stats)
    return Background(True, rgb, inv_z, range_m, cloud_on, cloud, air)


def _sky_and_earth(frame: FrameConstants, air: np.ndarray) -> Background:
    """Haze or fog alone: only the sky and the earth plane are seen through it, per pixel, and
    neither ever hides a polygon (1/z 0 everywhere: a zeroed array, pages mapped on touch)."""
    h, w, s = frame.height, frame.width, frame.offsets.shape[0]
    rgb = np.empty((h, w, 3), np.float32)
    range_m = np.empty((h, w), np.float32)
    sky_earth_kernel(frame.mapping, frame.offsets, w, h, frame.horizon, frame.dz_row,
                     frame.height_above, frame.sky, frame.earth, air, rgb, range_m)
    return Background(True, rgb, np.zeros((h, w, s), np.float32), range_m, False, no_cloud(), air)


def _sky_haze(air: np.ndarray, grid: PreimageGrid) -> tuple[np.ndarray, float, float]:
    """Haze of the sky (range infinite) at the centre elevation of each of the view's
    pre-image rows: (table, elevation of row 0's lower edge, row height), radians."""
    if air[0] == 0.0:
        return np.zeros(1), grid.theta0, grid.theta1 - grid.theta0
    return sky_haze_table(air, grid.theta0, grid.dtheta, grid.nrows), grid.theta0, grid.dtheta
