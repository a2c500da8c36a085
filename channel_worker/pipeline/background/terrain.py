"""Voxel terrain of JP H07-76990, the background the polygons are depth-tested against
(docs/terrain.md): cast straight to the screen.

One radial scan per line of the fan (fan.py: screen lines through the vertical vanishing point,
each the image of one vertical half-plane through the eye) walks the ground grid outward from
the line's start point one grid line at a time, at the level whose voxels are one to two
pixels wide at that range (coarser each time the range doubles), and integrates what rises
above the horizon of what it has seen into the pixels the line owns, by the share of each
pixel it covers (_cast_kernels.cast_kernel). Because each line is an exact vertical plane,
occlusion by elevation is exact at any roll and pitch, and every pixel is written once: no
intermediate image, no resample.

The haze (JP H07-76990) and the layered fog (US 5,535,374) are applied to every terrain pixel
here, with the one air array the polygon kernels use too (air.air_params).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from channel_worker.pipeline.contract import FrameConstants, View
from channel_worker.pipeline.fog.fog import average_floor
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase
from services.rig.colour import srgb_to_linear

from ._cast_kernels import cast_kernel
from ._groups import BackgroundArrays, CastPixels, ScanLimits, SkyTable, VoxelPages
from .fan import line_fan
from .haze import OPAQUE_TAU, beta_at

#: An eye closer than this above the terrain surface (or below it) is moved up to it for the
#: terrain scan (metres): the picture stays defined instead of turning inside out. Counted in
#: the counter "terrain_eye_clamped".
MIN_CLEARANCE_M = 0.01

#: sRGB-encoded byte -> linear, for the database's uint8 colours.
_SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def cast_terrain(database: Database, view: View, frame: FrameConstants, air: np.ndarray,
                 sky: SkyTable, level_bias: int, out: BackgroundArrays, aux: CastPixels,
                 counters: dict[str, int]) -> None:
    """Cast database.terrain into every pixel of the frame, over the sky and the earth plane:
    fills out.rgb, out.range_m and aux (the per-pixel coverage and 1/z the per-sample depth
    interpolates).

    Args:
        database: the scene; database.terrain is not None.
        view: the channel's view for this frame.
        frame: the frame's constants (the view's screen mapping and sample pattern).
        air: the frame's air array (air.air_params).
        sky: the sky and earth plane by elevation (air.sky_table).
        level_bias: voxels are kept 2**bias to 2**(bias + 1) pixels wide
            (RenderOptions.terrain_bias).
        out, aux: the arrays filled.
        counters: receives "terrain_voxels" (voxels visited), "terrain_lines" (lines cast),
            and "terrain_eye_clamped" 1 when the eye was moved up to MIN_CLEARANCE_M above
            the surface.

    Raises:
        ValueError: the scene has no terrain.
    """
    terrain = database.terrain
    if terrain is None:
        raise ValueError("cast_terrain: the scene has no terrain")
    eye = np.asarray(view.eye, np.float64) - terrain.origin  # float64 before anything else
    ground = surface_height(terrain, float(eye[0]), float(eye[1]))
    if ground is not None and eye[2] < ground + MIN_CLEARANCE_M:
        eye[2] = ground + MIN_CLEARANCE_M
        counters["terrain_eye_clamped"] = 1
    fan = line_fan(frame)
    visits = np.zeros(fan.aim.shape[0], np.int64)
    limits = ScanLimits(eye, _level_switch(terrain, view, eye, level_bias),
                        _far_range(database, terrain, view))
    cast_kernel(voxel_pages(terrain), fan, limits, air, frame, sky, out, aux, visits,
                numba.get_num_threads())
    counters["terrain_voxels"] = int(visits.sum())
    counters["terrain_lines"] = int(fan.aim.shape[0])


def voxel_pages(terrain: TerrainDatabase) -> VoxelPages:
    """The database's pages, page tables and patterns as the cast reads them."""
    level_nx = np.array([terrain.level_size(lv)[0] for lv in range(terrain.levels)], np.int64)
    level_ny = np.array([terrain.level_size(lv)[1] for lv in range(terrain.levels)], np.int64)
    log2_page = int(terrain.page_size).bit_length() - 1
    patterns = terrain.patterns
    n_pat = max(len(patterns), 1)
    n_band = max([len(p.top_m) for p in patterns], default=1)
    pat_top = np.zeros((n_pat, n_band), np.float32)
    pat_rgb = np.zeros((n_pat, n_band, 3), np.float32)
    pat_bands = np.ones(n_pat, np.int64)
    for k, p in enumerate(patterns):
        pat_top[k, :len(p.top_m)] = p.top_m
        pat_rgb[k, :len(p.top_m)] = _SRGB_LUT[np.asarray(p.rgb, np.uint8)]
        pat_bands[k] = len(p.top_m)
    nx, ny = terrain.extent_m
    return VoxelPages(terrain.z, terrain.rgb, terrain.pattern, terrain.page_table,
                      terrain.table_offset, terrain.pages_x, terrain.pages_y, log2_page, level_nx,
                      level_ny, float(terrain.spacing_m), float(nx), float(ny),
                      float(terrain.z_max), pat_top, pat_rgb, pat_bands, _SRGB_LUT)


def _level_switch(terrain: TerrainDatabase, view: View, eye: np.ndarray,
                  level_bias: int) -> np.ndarray:
    """(levels,) ground range (metres) where level L + 1 takes over from level L (inf for the
    coarsest); eye relative to the database origin."""
    # Level L + 1 takes over where a level-L voxel has shrunk to 2**bias pixels (a level-L + 1
    # voxel is then 2**(bias + 1) pixels wide), i.e. at slant range spacing 2**(L - bias) /
    # pixel angle: voxels stay 2**bias to 2**(bias + 1) pixels wide, one level coarser each
    # time the range doubles. The slant range is bounded below by the ground range and the
    # eye's height above or below the database's height range.
    pixel = (math.atan(view.tan_right) - math.atan(view.tan_left)) / view.width
    dz_min = max(float(eye[2]) - terrain.z_max, terrain.z_min - float(eye[2]), 0.0)
    r_switch = np.full(terrain.levels, np.inf)
    for lv in range(terrain.levels - 1):
        slant = terrain.spacing_m * 2.0 ** (lv - level_bias) / pixel  # guard: pixel > 0
        r_switch[lv] = math.sqrt(max(slant * slant - dz_min * dz_min, 0.0))
    return r_switch


def _far_range(database: Database, terrain: TerrainDatabase, view: View) -> float:
    """Ground range (metres) beyond which the scan of terrain (database.terrain) sees nothing:
    the far plane, or where all is haze or fog (optical depth OPAQUE_TAU)."""
    r_far = float(view.far)
    if database.haze is not None:
        # Beyond optical depth OPAQUE_TAU all is haze; the air along any path to the terrain
        # is at least as dense as at the higher of the eye and the highest terrain point.
        top = max(float(view.eye[2]), terrain.origin[2] + terrain.z_max)
        r_far = min(r_far, OPAQUE_TAU / beta_at(database.haze, top))
    if database.fog is not None:
        # Likewise all fog: a terrain point's axis distance from the eye lies between those of
        # the database box's corners, and its slant range is at least its ground range, so
        # its optical depth is at least ground range x the least average extinction there.
        fog = database.fog
        ex, ey = terrain.extent_m
        corners = np.array([[x, y, z] for x in (0.0, ex) for y in (0.0, ey)
                            for z in (terrain.z_min, terrain.z_max)]) + terrain.origin
        d = (corners - np.asarray(view.eye, np.float64)) @ fog.axis
        floor = average_floor(fog, view.eye, float(d.min()), float(d.max()))
        if floor > 0.0:
            r_far = min(r_far, OPAQUE_TAU / floor)  # guard: floor > 0
    return r_far


def surface_height(terrain: TerrainDatabase, x: float, y: float) -> float | None:
    """Terrain height (metres above terrain.origin[2]) at database-relative ground point (x, y),
    from the finest level that has it; None outside the database."""
    ex, ny_m = terrain.extent_m
    if not (0.0 <= x <= ex and 0.0 <= y <= ny_m):
        return None
    for level in range(terrain.levels):
        d = terrain.spacing_m * (1 << level)
        nx_l, ny_l = terrain.level_size(level)
        ix = min(int(x // d), nx_l - 1)
        iy = min(int(y // d), ny_l - 1)
        p = terrain.page_size
        page = terrain.page_index(level, ix // p, iy // p)
        if page < 0:
            continue
        u = min(max(x / d - ix, 0.0), 1.0)
        v = min(max(y / d - iy, 0.0), 1.0)
        z = terrain.z[page, iy % p, ix % p].astype(np.float64)
        return float((1 - v) * ((1 - u) * z[0] + u * z[1]) + v * ((1 - u) * z[2] + u * z[3]))
    return None
