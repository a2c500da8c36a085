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
from channel_worker.pipeline.geometry.trees import view_pixel
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.forest import near_tree_ranges
from channel_worker.pipeline.scene.surfaces import (
    LOOK_AMPLITUDE,
    LOOK_DETAIL,
    LOOK_PRIMARY,
    LOOK_TEXTURE,
    MAX_CODE_TEXTURES,
)
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase
from channel_worker.pipeline.scene.texture_sampling import FADE
from services.rig.colour import srgb_to_linear

from ._cast_kernels import cast_kernel
from ._groups import (
    FIELD,
    FOREST,
    GRASS,
    LAND_CLASSES,
    PAD,
    T_CLASS_N,
    T_CLASSES,
    T_FIELD_H,
    T_FIELD_SHARE,
    T_FIELD_SLOPE,
    T_FIELD_W,
    T_FIELDS,
    T_FIELDS_N,
    T_HEDGE,
    T_HEDGE_M,
    T_LUM_REF,
    T_ORIGIN,
    T_PAD_COVERED,
    T_PADS_AT,
    T_PADS_N,
    T_ROCK_SLOPE,
    BackgroundArrays,
    CastPixels,
    ScanLimits,
    SkyTable,
    TerrainDetail,
    VoxelPages,
)
from ._groups import ROCK as ROCK_CLASS
from .fan import line_fan
from .haze import OPAQUE_TAU, beta_at

#: An eye closer than this above the terrain surface (or below it) is moved up to it for the
#: terrain scan (metres): the picture stays defined instead of turning inside out. Counted in
#: the counter "terrain_eye_clamped".
MIN_CLEARANCE_M = 0.01

#: The land's detail (docs/terrain.md "Detail"). Rock where the ground is steeper than 31
#: degrees; fields in 55 % of the cells of a patchwork 210 m x 160 m (the size of the small
#: fields of a hill farm) whose corners lie within 8 degrees of their centre, with 4 m of
#: hedge along the inside of its edges.
ROCK_SLOPE = math.tan(math.radians(31.0))
FIELD_SLOPE = math.tan(math.radians(8.0))
FIELD_SHARE = 0.55
FIELD_M = (210.0, 160.0)
HEDGE_HALF_M = 4.0


def _srgb(*hexes: str) -> np.ndarray:
    return srgb_to_linear(np.array([[int(h[i:i + 2], 16) for i in (1, 3, 5)] for h in hexes]) / 255.0)


#: The classes' colours (sRGB, lit by the scene's light on level ground, as the pads' grass)
#: and the share of the relief colour's hue each takes: meadow, rock; the kinds of field (ripe
#: cereal, stubble, ploughed soil, young crop, hay meadow); a hedge's factor on its field.
MEADOW, MEADOW_MIX = _srgb("#6a8c40")[0], 0.8
ROCK, ROCK_MIX = _srgb("#8c8a84")[0], 0.85
FIELDS, FIELD_MIX = _srgb("#c2a85a", "#b5a77a", "#7d6347", "#88a648", "#a3a35c"), 0.9
HEDGE_FACTOR = np.array([0.36, 0.48, 0.3])

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
    tree_start, tree_end = 0.0, 0.0
    if database.near_trees is not None:
        tree_start, tree_end = near_tree_ranges(terrain, database.near_trees, view_pixel(view))
    limits = ScanLimits(eye, _level_switch(terrain, view, eye, level_bias),
                        _far_range(database, terrain, view), tree_start, tree_end)
    cast_kernel(voxel_pages(terrain), terrain_detail(database, frame), fan, limits, air, frame, sky, out,
                aux, visits, numba.get_num_threads())
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
    pat_canopy = np.array([p.name == "tree" for p in patterns] or [False], np.bool_)
    for k, p in enumerate(patterns):
        pat_top[k, :len(p.top_m)] = p.top_m
        pat_rgb[k, :len(p.top_m)] = _SRGB_LUT[np.asarray(p.rgb, np.uint8)]
        pat_bands[k] = len(p.top_m)
    nx, ny = terrain.extent_m
    return VoxelPages(terrain.z, terrain.rgb, terrain.pattern, terrain.page_table,
                      terrain.table_offset, terrain.pages_x, terrain.pages_y, log2_page, level_nx,
                      level_ny, float(terrain.spacing_m), float(nx), float(ny),
                      float(terrain.z_max), pat_top, pat_rgb, pat_bands, pat_canopy, _SRGB_LUT)


def terrain_detail(database: Database, frame: FrameConstants) -> TerrainDetail:
    """The land's detail as the cast reads it (TerrainDetail), from the scene's terrain.detail;
    off (and free) when the scene has none."""
    land = database.terrain_land
    terrain = database.terrain
    on = land is not None and terrain is not None
    # Lit as the airfield's grass faces are (geometry's face light: a horizontal face, normal
    # up), so that the land around the pads and the pads' grass agree.
    light = database.ambient + (1.0 - database.ambient) * min(max(float(database.sun[2]), 0.0), 1.0)
    fields = FIELDS * light if land is not None and on and land.field >= 0 else np.zeros((0, 3))
    pads = np.asarray(land.pads, np.float64).reshape(-1, 5) if land is not None and on else np.zeros((0, 5))
    t = np.zeros(T_FIELDS + fields.size + pads.size)
    if terrain is not None:
        t[T_ORIGIN:T_ORIGIN + 3] = terrain.origin[:3]
    t[T_ROCK_SLOPE], t[T_FIELD_SLOPE], t[T_FIELD_SHARE] = ROCK_SLOPE, FIELD_SLOPE, FIELD_SHARE
    t[T_FIELD_W], t[T_FIELD_H], t[T_HEDGE_M] = FIELD_M[0], FIELD_M[1], HEDGE_HALF_M
    t[T_LUM_REF] = 1.0
    t[T_HEDGE:T_HEDGE + 3] = HEDGE_FACTOR
    for k in range(LAND_CLASSES):
        t[T_CLASSES + k * T_CLASS_N] = -1.0
    if land is not None and on:
        rows = {GRASS: (land.grass, MEADOW * light, MEADOW_MIX), FIELD: (land.field, np.zeros(3), FIELD_MIX),
                ROCK_CLASS: (land.rock, ROCK * light, ROCK_MIX),
                PAD: (land.pad, np.asarray(land.pad_colour, np.float64) * light, 1.0),
                FOREST: (land.forest, np.zeros(3), 0.0)}
        for k, (look, colour, mix) in rows.items():
            c = T_CLASSES + k * T_CLASS_N
            t[c:c + T_CLASS_N] = (look, *colour, mix, *fade_outs(frame, look))
        t[T_LUM_REF] = land.relief_luminance
        t[T_PAD_COVERED] = 1.0 if land.pad_covered else 0.0
    t[T_FIELDS_N], t[T_PADS_N], t[T_PADS_AT] = len(fields), len(pads), T_FIELDS + fields.size
    t[T_FIELDS:T_FIELDS + fields.size] = fields.ravel()
    t[T_FIELDS + fields.size:] = pads.ravel()
    return TerrainDetail(on, frame.texels, frame.tex_level, frame.tex_levels, frame.tex_finest, frame.looks,
                         int(frame.texture_filter), t)


def fade_outs(frame: FrameConstants, look: int) -> list[float]:
    """For each texture of code `look` (MAX_CODE_TEXTURES, in order), the footprints from which
    it shows nothing under the fade filter, as (the pixel's larger side, its side across the
    line) in metres of the texture plane: past either, its finest frequency has reached the
    sampling's Nyquist frequency (texture_sampling.fade_amplitude: 2 finest rho >= 1, rho the
    larger side in texels). With texels per metre tw, th along the texture's axes and the
    pixel's sides along >= across (perpendicular): rho >= along min(tw, th), and rho^2 >=
    (side_x^2 + side_y^2) / 2 >= across^2 (tw^2 + th^2) / 2. inf where it never fades out: a
    missing or silent texture, one without contrast, a filter other than fade (its pyramid
    reads go on)."""
    out = [-1.0] * (2 * MAX_CODE_TEXTURES)  # no texture: never shows
    if look < 0:
        return out
    fade = int(frame.texture_filter) == FADE
    row = frame.looks[look]
    for k in range(MAX_CODE_TEXTURES):
        tex = int(row[LOOK_TEXTURE + k])
        if tex < 0:
            break
        if k > 0 and row[LOOK_AMPLITUDE + k - 1] == 0.0:
            continue  # silenced: texture_modulation reads nothing
        ru, rv = (row[LOOK_PRIMARY], row[LOOK_PRIMARY + 1]) if k == 0 else (row[LOOK_DETAIL], row[LOOK_DETAIL + 1])
        tw = ru * (1 << int(frame.tex_level[tex, 0, 1]))
        th = rv * (1 << int(frame.tex_level[tex, 0, 2]))
        finest = float(frame.tex_finest[tex])
        if not fade or finest <= 0.0 or min(tw, th) <= 0.0:
            out[2 * k:2 * k + 2] = [math.inf, math.inf]
            continue
        limit = 1.0 / (2.0 * finest)  # rho (texels) at which the fade reaches 0
        out[2 * k:2 * k + 2] = [limit / min(tw, th), limit * math.sqrt(2.0) / math.hypot(tw, th)]
    return out


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
