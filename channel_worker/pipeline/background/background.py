"""Background stage: what every sample sees behind the polygons (docs/terrain.md, docs/fog.md).

The voxel terrain (terrain.py), the sky and the earth plane, the coarse clouds (clouds.py), all
through the haze (haze.py) and the layered fog (fog/), in one Background that the visibility
stage starts every sample from. The frame's air (air.py) is built here, once, and handed on in
the Background to the stages that see polygons through it. A scene with none of terrain, haze,
fog or clouds does not run this stage (render.py).

In order: the air; the terrain's column scan into the zero-roll pre-image (terrain.py,
_scan_kernels.py); the coarse cloud scan (clouds.py, _cloud_kernels.py); then the warp
(_warp_kernels.py), which resamples both for every pixel and sample over the sky and the earth
plane (_sky_kernels.py). Haze or fog alone skips the pre-image: the sky and the earth plane are
painted per pixel (_sky_kernels.sky_earth_kernel).
"""

from __future__ import annotations

import time

import numba
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

from ._groups import (
    CLOUD_CHANNELS,
    PRE_CHANNELS,
    BackgroundArrays,
    CloudImage,
    Preimage,
    SampleDepth,
    SkyHaze,
)
from ._sky_kernels import sky_earth_kernel
from ._warp_kernels import warp_kernel
from .air import air_params
from .clouds import scan_clouds
from .haze import sky_haze_table
from .terrain import PreimageGrid, preimage_grid, scan_terrain

#: Pixels per side of the warp's blocks (exact mapping at block corners, interpolated inside).
WARP_BLOCK = 8


def render_background(database: Database, view: View, frame: FrameConstants,
                      options: RenderOptions, bins: Bins | None, counters: dict[str, int], *,
                      parts: dict[str, float] | None = None) -> Background:
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
        parts: if given, receives the seconds of "background.scan" (the terrain's column
            scan), "background.clouds" (the cloud scan) and "background.warp" (the warp and
            the sky's haze table) where a pre-image is warped.
    """
    return _render(database, view, frame, options, bins, counters, parts, scan=True)


def warp_alone(database: Database, view: View, frame: FrameConstants,
               options: RenderOptions) -> Background:
    """render_background without the terrain's column scan: the cloud scan and the warp over
    the empty stand-in pre-image, per-sample depth everywhere.

    For the compile processes (channel_worker/compile_jobs.py): one builds the scan's kernels
    while another builds these, with a frame's argument types (the stand-in pre-image has the
    types of a scanned one). In one process the warp took 14 s and the scan 9 s of 32 s.

    Args:
        database: a scene with terrain or clouds.
        view, frame, options: as render_background's.
    """
    if database.terrain is None and database.clouds is None:
        raise ValueError("warp_alone: the scene has neither terrain nor clouds (no warp)")
    return _render(database, view, frame, options, None, {}, None, scan=False)


def scan_alone(database: Database, view: View, options: RenderOptions) -> Preimage:
    """The terrain's column scan alone, as render_background runs it: warp_alone's other half,
    for the compile process that builds the scan's kernels.

    Args:
        database: a scene with terrain.
        view, options: as render_background's.
    """
    if database.terrain is None:
        raise ValueError("scan_alone: the scene has no terrain")
    return scan_terrain(database, view, preimage_grid(view),
                        air_params(database, view, options.fog_table_subdivision),
                        options.terrain_bias, {})


def _render(database: Database, view: View, frame: FrameConstants, options: RenderOptions,
            bins: Bins | None, counters: dict[str, int], parts: dict[str, float] | None, *,
            scan: bool) -> Background:
    """render_background, the terrain's column scan left out unless scan."""
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
    t0 = time.perf_counter()
    stand_in = terrain is None or not scan
    if stand_in:
        pre = _no_terrain(grid)
    else:
        pre = scan_terrain(database, view, grid, air, options.terrain_bias, stats)
    t1 = time.perf_counter()
    if bins is None:
        depth = SampleDepth(float(database.terrain_margin_m), max(h, w), np.ones(1, np.bool_))
    else:
        depth = SampleDepth(float(database.terrain_margin_m), int(bins.size),
                            np.ascontiguousarray(np.diff(bins.start) > 0, np.bool_))
    if database.clouds is not None:
        clouds = scan_clouds(database, view, grid, air)
        cloud = np.empty((h, w, CLOUD_CHANNELS), np.float32)
        if stand_in:
            # The warp's coordinates are then those of the one-texel stand-in pre-image.
            clouds = clouds._replace(col_ratio=clouds.col_ratio / grid.ncols,
                                     row_ratio=clouds.row_ratio / grid.nrows)
    else:
        cloud = no_cloud()
        clouds = CloudImage(False, cloud, 1.0, 1.0)
    t2 = time.perf_counter()
    out = BackgroundArrays(np.empty((h, w, 3), np.float32), np.empty((h, w, s), np.float32),
                           np.empty((h, w), np.float32), cloud)
    warp_kernel(frame, pre, air, _sky_haze(air, grid), clouds, depth, WARP_BLOCK, out,
                numba.get_num_threads())
    if parts is not None:
        parts["background.scan"] = t1 - t0
        parts["background.clouds"] = t2 - t1
        parts["background.warp"] = time.perf_counter() - t2
    counters.update(stats)
    return Background(True, out.rgb, out.inv_z, out.range_m, clouds.on, out.cloud, air)


def _no_terrain(grid: PreimageGrid) -> Preimage:
    """The pre-image of a view without terrain: one empty texel spanning the whole grid, so the
    warp paints the sky and the earth plane (and lays the clouds over them) alone."""
    texels = np.zeros((1, 1, PRE_CHANNELS), np.float32)
    return Preimage(texels, grid.full, grid.phi_lo, grid.span, grid.theta0,
                    grid.theta1 - grid.theta0, texels.shape[0] * grid.span)


def _sky_and_earth(frame: FrameConstants, air: np.ndarray) -> Background:
    """Haze or fog alone: only the sky and the earth plane are seen through it, per pixel, and
    neither ever hides a polygon (1/z 0 everywhere: a zeroed array, pages mapped on touch)."""
    h, w, s = frame.height, frame.width, frame.offsets.shape[0]
    rgb = np.empty((h, w, 3), np.float32)
    range_m = np.empty((h, w), np.float32)
    sky_earth_kernel(frame, air, rgb, range_m)
    return Background(True, rgb, np.zeros((h, w, s), np.float32), range_m, False, no_cloud(), air)


def _sky_haze(air: np.ndarray, grid: PreimageGrid) -> SkyHaze:
    """Haze of the sky (range infinite) at the centre elevation of each of the view's
    pre-image rows (a zero stand-in without haze)."""
    if air[0] == 0.0:
        return SkyHaze(np.zeros(1), grid.theta0, grid.theta1 - grid.theta0)
    return SkyHaze(sky_haze_table(air, grid.theta0, grid.dtheta, grid.nrows), grid.theta0,
                   grid.dtheta)
