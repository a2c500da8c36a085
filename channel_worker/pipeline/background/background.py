"""Background stage: what every sample sees behind the polygons (docs/terrain.md, docs/fog.md).

The voxel terrain (terrain.py), the sky and the earth plane, the coarse clouds (clouds.py), all
through the haze (haze.py) and the layered fog (fog/), in one Background that the visibility
stage starts every sample from. The frame's air (air.py) is built here, once, and handed on in
the Background to the stages that see polygons through it. A scene with none of terrain, haze,
fog or clouds does not run this stage (render.py).

In order: the air and its sky table (air.py); the terrain cast straight into the pixels over
the sky and the earth plane (terrain.py, fan.py, _cast_kernels.py), or without terrain the sky
and the earth plane alone (_sky_kernels.py); the per-sample terrain depth in the sub-areas
that hold polygons (_depth_kernels.py); then, with clouds, the coarse cloud scan and its
overlay (clouds.py, _cloud_kernels.py, _cloud_over_kernels.py).
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

from ._cloud_over_kernels import cloud_over_kernel
from ._depth_kernels import sample_depth_kernel
from ._groups import CLOUD_CHANNELS, BackgroundArrays, CastPixels, SampleDepth
from ._sky_kernels import sky_earth_kernel
from .air import air_params, sky_table
from .clouds import scan_clouds
from .terrain import cast_terrain

#: Pixels per side of the cloud overlay's blocks (exact mapping at block corners, interpolated
#: inside; a block under clear air is skipped whole).
CLOUD_BLOCK = 8


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
        bins: the frame's sub-area lists: per-sample depth (Background.inv_z) is computed only
            in the sub-areas that hold polygons to test against the terrain; elsewhere it is 0.
            None: everywhere (tests and tools that look at the background alone).
        counters: receives "terrain_voxels" (voxels visited), "terrain_lines" (lines cast),
            "terrain_eye_clamped", and with fog "fog_table_coarsened" (1 if the eye is so far
            from the strata that the table was coarsened).
        parts: if given, receives the seconds of "background.cast" (the terrain cast, or the
            sky and earth plane without terrain), "background.depth" (the per-sample depth)
            and "background.clouds" (the cloud scan and overlay).
    """
    terrain = database.terrain
    if terrain is None and database.haze is None and database.fog is None and database.clouds is None:
        return no_background()
    h, w, s = frame.height, frame.width, frame.offsets.shape[0]
    stats = {"terrain_voxels": 0, "terrain_lines": 0, "terrain_eye_clamped": 0}
    threads = numba.get_num_threads()
    t0 = time.perf_counter()
    air = air_params(database, view, options.fog_table_subdivision)
    if database.fog is not None:
        stats["fog_table_coarsened"] = int(air[F_COARSENED])
    sky = sky_table(frame, air)
    out = BackgroundArrays(np.empty((h, w, 3), np.float32), np.empty((h, w, s), np.float32),
                           np.empty((h, w), np.float32), no_cloud())
    if terrain is None:
        out.inv_z.fill(0.0)  # nothing hides a polygon
        sky_earth_kernel(frame, air, sky, out.rgb, out.range_m)
        t1 = t2 = time.perf_counter()
    else:
        aux = CastPixels(np.empty((h, w, 2), np.float32))
        cast_terrain(database, view, frame, air, sky, options.terrain_bias, out, aux, stats)
        t1 = time.perf_counter()
        if bins is None:
            depth = SampleDepth(float(database.terrain_margin_m), max(h, w), np.ones(1, np.bool_))
        else:
            depth = SampleDepth(float(database.terrain_margin_m), int(bins.size),
                                np.ascontiguousarray(np.diff(bins.start) > 0, np.bool_))
        sample_depth_kernel(frame, aux, depth, out.inv_z, threads)
        t2 = time.perf_counter()
    cloud = no_cloud()
    if database.clouds is not None:
        image = scan_clouds(database, view, air)
        cloud = np.empty((h, w, CLOUD_CHANNELS), np.float32)
        cloud_over_kernel(frame, image, CLOUD_BLOCK, out.range_m, out.rgb, cloud, threads)
    if parts is not None:
        parts["background.cast"] = t1 - t0
        parts["background.depth"] = t2 - t1
        parts["background.clouds"] = time.perf_counter() - t2
    counters.update(stats)
    return Background(True, out.rgb, out.inv_z, out.range_m, database.clouds is not None, cloud,
                      air)
