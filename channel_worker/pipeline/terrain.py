"""Terrain stage: the voxel terrain of seed 002 (JP H07-76990), with haze, as the background
the polygons are depth-tested against (docs/terrain.md).

1. A pre-image is computed for zero roll: its columns are vertical half-planes through the
   eye (one azimuth each) and its rows elevation angles. One radial scan per column walks the
   ground grid outward from the column's start point one grid line at a time, at the level
   whose voxels are one to two pixels wide at that range (coarser each time the range
   doubles), and integrates what rises above the horizon of what it has seen into the rows
   by the fraction of each row it covers (_terrain_kernels.scan_kernel). Because each column
   is an exact vertical plane, occlusion by elevation angle is exact at any pitch.
2. Every output sample then takes its value from the pre-image at its exact azimuth and
   elevation, bilinearly: this one inverse mapping is seed 002's rotation by the roll angle
   with anti-aliased resampling and its vertical perspective correction, exact for wide and
   off-axis channels, so terrain seams between channels line up like polygon seams
   (_terrain_kernels.warp_kernel).

Haze (seed 002) and fog (seed 004) are applied to every terrain texel, the sky, the earth
and the clouds here, with the one air array the polygon kernels use too (air.air_params).
A scene without terrain, haze, fog or clouds skips the stage (render_terrain returns None).
"""

from __future__ import annotations

import math

import numpy as np

from services.rig.colour import srgb_to_linear

from ._cloud_kernels import scan_clouds_kernel
from ._terrain_kernels import (
    PRE_CHANNELS,
    fill_skipped,
    scan_kernel,
    sky_earth_kernel,
    warp_kernel,
)
from .air import air_params
from .clouds import BASE_SHADE, CLOUD_FACTOR
from .fog import F_COARSENED, average_floor
from .haze import OPAQUE_TAU, beta_at, sky_haze_table
from .horizon import earth_dz_row, earth_dz_screen, height_above_earth
from .project import screen_mapping
from .types import Background, Database, View

#: Level bias: voxels are kept between 2**bias and 2**(bias + 1) projected pixels wide.
DEFAULT_LEVEL_BIAS = 0

#: Pre-image texels per output pixel along each axis, at the channel's centre of projection.
PREIMAGE_OVERSAMPLE = 1.0

#: Largest column stride (2^MAX_SKIP) towards the nadir.
MAX_SKIP = 5

#: Pixels per side of the warp's blocks (exact mapping at block corners, interpolated inside).
WARP_BLOCK = 8

#: An eye closer than this above the terrain surface (or below it) is moved up to it for the
#: terrain scan (metres): the picture stays defined instead of turning inside out. Counted in
#: stats["terrain_eye_clamped"].
MIN_CLEARANCE_M = 0.01

#: sRGB-encoded byte -> linear, for the database's uint8 colours.
_SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def render_terrain(database: Database, view: View, offsets: np.ndarray, *,
                   level_bias: int = DEFAULT_LEVEL_BIAS,
                   depth_tiles: tuple[int, np.ndarray] | None = None) -> Background | None:
    """The terrain (and the sky and earth through haze and fog, the clouds) every sample sees,
    or None if the scene has none of terrain, haze, fog and clouds.

    Args:
        database: the scene (database.terrain, .haze, .fog, .clouds, sky, earth).
        view: the channel's view for this frame.
        offsets: (S, 2) sample positions inside the pixel (samples.sample_pattern).
        level_bias: resolution level bias (voxel width 2**bias to 2**(bias + 1) pixels; -1 is
            finer and slower, +1 coarser and faster).
        depth_tiles: (size, mask): per-sample depth (Background.inv_z) is needed only in the
            size x size pixel sub-areas whose mask entry (row-major) is set, those holding
            polygons to test against the terrain; elsewhere it is left 0. None: everywhere.

    Returns:
        Background with per-sample colour and depth-test 1/z and per-pixel range; its stats
        hold "terrain_voxels" (voxels visited), "terrain_columns", "terrain_rows" and
        "terrain_eye_clamped", and with fog "fog_table_coarsened" (1 if the eye is so far
        from the strata that the table was coarsened to MAX_TABLE entries).
    """
    terrain = database.terrain
    if (terrain is None and database.haze is None and database.clouds is None
            and database.fog is None):
        return None
    check_level_bias(level_bias)
    h, w, s = view.height, view.width, offsets.shape[0]
    stats = {"terrain_voxels": 0, "terrain_columns": 0, "terrain_rows": 0,
             "terrain_eye_clamped": 0}
    air = air_params(database, view)
    if database.fog is not None:
        stats["fog_table_coarsened"] = int(air[F_COARSENED])
    if terrain is None and database.clouds is None:
        return _sky_and_earth(database, view, offsets, air, stats)
    grid = preimage_grid(view)
    if terrain is None:
        pre = np.zeros((1, 1, PRE_CHANNELS), np.float32)
        full, phi_lo, dphi, theta0, dtheta = grid.full, grid.phi_lo, grid.span, grid.theta0, \
            grid.theta1 - grid.theta0
    else:
        pre = _scan(database, view, grid, air, level_bias, stats)
        full, phi_lo, dphi, theta0, dtheta = grid.full, grid.phi_lo, grid.dphi, grid.theta0, \
            grid.dtheta
    if depth_tiles is None:
        tile, need = max(h, w), np.ones(1, np.bool_)
    else:
        tile, need = int(depth_tiles[0]), np.ascontiguousarray(depth_tiles[1], np.bool_)
    cloud_on = database.clouds is not None
    if cloud_on:
        cloud_pre, col_ratio, row_ratio = _scan_clouds(database, view, grid, air)
        cloud = np.empty((h, w, 5), np.float32)
        if terrain is None:
            # The warp's coordinates are then those of the one-texel stand-in pre-image.
            col_ratio, row_ratio = col_ratio / grid.ncols, row_ratio / grid.nrows
    else:
        cloud_pre, col_ratio, row_ratio = np.zeros((1, 1, 5), np.float32), 1.0, 1.0
        cloud = np.empty((1, 1, 5), np.float32)
    rgb = np.empty((h, w, 3), np.float32)
    inv_z = np.empty((h, w, s), np.float32)
    range_m = np.empty((h, w), np.float32)
    warp_kernel(pre, full, phi_lo, dphi, theta0, dtheta, np.ascontiguousarray(view.world_to_eye),
                np.array(screen_mapping(view)), np.ascontiguousarray(offsets, np.float64), w, h,
                np.array(earth_dz_screen(view)), earth_dz_row(view),
                height_above_earth(database, view), database.sky_colour.astype(np.float32),
                database.earth_colour.astype(np.float32), air,
                *_sky_haze(air, grid), float(database.terrain_margin_m), WARP_BLOCK, cloud_on, cloud_pre, col_ratio,
                row_ratio, tile, need, rgb, inv_z, range_m, cloud)
    return Background(rgb=rgb, inv_z=inv_z, range_m=range_m, stats=stats,
                      cloud=cloud if cloud_on else None, air=air)


def _sky_and_earth(database: Database, view: View, offsets: np.ndarray, air: np.ndarray,
                   stats: dict) -> Background:
    """Haze or fog alone: only the sky and the earth plane are seen through it, per pixel, and
    neither ever hides a polygon (1/z 0 everywhere: a zeroed array, pages mapped on touch)."""
    h, w, s = view.height, view.width, offsets.shape[0]
    rgb = np.empty((h, w, 3), np.float32)
    range_m = np.empty((h, w), np.float32)
    sky_earth_kernel(np.array(screen_mapping(view)), np.ascontiguousarray(offsets, np.float64), w,
                     h, np.array(earth_dz_screen(view)), earth_dz_row(view),
                     height_above_earth(database, view), database.sky_colour.astype(np.float32),
                     database.earth_colour.astype(np.float32), air, rgb, range_m)
    return Background(rgb=rgb, inv_z=np.zeros((h, w, s), np.float32), range_m=range_m,
                      stats=stats, cloud=None, air=air)


def check_level_bias(bias: int) -> int:
    """The bias as an int, or ValueError naming the value."""
    if isinstance(bias, bool) or not isinstance(bias, (int, np.integer)) or not -4 <= bias <= 4:
        raise ValueError(f"terrain_bias: expected an integer in -4..4, got {bias!r}")
    return int(bias)


class PreimageGrid:
    """The zero-roll pre-image of one view: azimuth columns and elevation rows (radians).

    Column j is centred on azimuth phi_lo + (j + 1/2) dphi (clockwise from north); row i
    spans elevations theta0 + i dtheta .. theta0 + (i + 1) dtheta. full: the view holds the
    nadir or the zenith, so every azimuth is seen and columns wrap around.
    """

    def __init__(self, phi_lo: float, span: float, full: bool, theta0: float, theta1: float,
                 pixel_angle: float, cos_max: float, oversample: float) -> None:
        self.phi_lo, self.span, self.full = phi_lo, span, full
        self.theta0, self.theta1 = theta0, theta1
        self.pixel_angle = pixel_angle
        # Rows as fine as the finest output pixel; columns too, where azimuth is densest on
        # the screen (nearest the horizon: a pixel of angle a spans a / cos(elevation) of
        # azimuth). Guards: pixel_angle > 0 (finite frustum), cos_max > 0 (clamped below).
        d = pixel_angle / oversample
        self.nrows = max(1, math.ceil((theta1 - theta0) / d))
        self.ncols = max(1, math.ceil(span / (d / cos_max)))
        if full:
            # Every column stride divides a full circle of columns (scan_kernel's first_row).
            self.ncols = -(-self.ncols // (1 << MAX_SKIP)) * (1 << MAX_SKIP)
        self.dtheta = (theta1 - theta0) / self.nrows
        self.dphi = span / self.ncols
        # Towards the nadir a pixel spans d / cos(elevation) of azimuth: there only every
        # 2^k-th column is needed. first_row[k]: the lowest row columns with k trailing zero
        # bits scan (rows nearer the horizon need every column).
        centres = theta0 + (np.arange(self.nrows) + 0.5) * self.dtheta
        need = (d / np.maximum(np.cos(centres), 1e-9)) / self.dphi  # columns a pixel spans
        stride_log = np.clip(np.floor(np.log2(np.maximum(need, 1.0))), 0, MAX_SKIP).astype(int)
        stride_log[centres > 0.0] = 0  # skipping is for rows below the horizon only
        self.first_row = np.zeros(MAX_SKIP + 1, np.int64)
        for k in range(MAX_SKIP + 1):
            # Rows (from the bottom) whose stride is coarser than 2^k are skipped by such
            # columns: only the contiguous run from row 0 (strides shrink going up).
            ok = stride_log <= k
            self.first_row[k] = int(np.argmax(ok)) if ok.any() else self.nrows


def preimage_grid(view: View, oversample: float | None = None) -> PreimageGrid:
    """The azimuth and elevation range a view covers and the pre-image resolution it needs.

    Azimuth and elevation have no extremum inside the frustum except at the poles, so the
    frustum's border (sampled densely) and whether it holds the nadir or zenith give both
    ranges; the border's winding about the vertical tells if a pole is inside. oversample:
    texels per pixel at the centre of projection (None: PREIMAGE_OVERSAMPLE, read at the call).
    """
    if oversample is None:
        oversample = PREIMAGE_OVERSAMPLE
    n = 257
    t = np.linspace(0.0, 1.0, n)
    tl, tr, tb, tt = view.tan_left, view.tan_right, view.tan_bottom, view.tan_top
    xs = np.concatenate([tl + (tr - tl) * t, np.full(n, tr), tr - (tr - tl) * t, np.full(n, tl)])
    ys = np.concatenate([np.full(n, tb), tb + (tt - tb) * t, np.full(n, tt), tt - (tt - tb) * t])
    dirs = np.stack([xs, ys, np.ones_like(xs)], axis=1) @ view.world_to_eye  # world directions
    horiz = np.hypot(dirs[:, 0], dirs[:, 1])
    theta = np.arctan2(dirs[:, 2], horiz)
    phi = np.arctan2(dirs[:, 0], dirs[:, 1])
    loop = np.unwrap(np.append(phi, phi[0]))
    winding = loop[-1] - loop[0]
    sx_scale, _, sy_scale, _ = screen_mapping(view)
    # Texels as fine as the output pixels at the centre of projection (1 / scale radians);
    # wide channels' edge pixels are smaller (cos^2 of the angle off axis): PREIMAGE_OVERSAMPLE
    # trades that blur against time (bench/bench_terrain.py). Guard: scales are nonzero.
    pixel_angle = min(1.0 / abs(sx_scale), 1.0 / abs(sy_scale))
    margin = 2.0 * pixel_angle
    nadir = _pole_inside(view, -1.0, margin)
    zenith = _pole_inside(view, 1.0, margin)
    full = nadir or zenith or abs(winding) > math.pi
    theta0 = -0.5 * math.pi if nadir else max(float(theta.min()) - margin, -0.5 * math.pi)
    theta1 = 0.5 * math.pi if zenith else min(float(theta.max()) + margin, 0.5 * math.pi)
    if full:
        phi_lo, span = float(phi[0]) - math.pi, 2.0 * math.pi
    else:
        lo, hi = float(loop.min()), float(loop.max())
        col_margin = margin / max(math.cos(max(abs(theta0), abs(theta1))), 1e-3)
        phi_lo, span = lo - col_margin, min(hi - lo + 2.0 * col_margin, 2.0 * math.pi)
    if theta0 <= 0.0 <= theta1:
        cos_max = 1.0
    else:
        cos_max = max(math.cos(min(abs(theta0), abs(theta1))), 1e-3)
    return PreimageGrid(phi_lo, span, full, theta0, theta1, pixel_angle, cos_max, oversample)


def _pole_inside(view: View, sign: float, margin: float) -> bool:
    """Whether the straight-down (sign -1) or straight-up (+1) direction is in the frustum,
    widened by margin radians."""
    e = view.world_to_eye @ np.array([0.0, 0.0, sign])
    if e[2] <= 0.0:
        return False
    pad = math.tan(margin) * 2.0
    tx, ty = e[0] / e[2], e[1] / e[2]  # guard: e[2] > 0
    return (view.tan_left - pad <= tx <= view.tan_right + pad
            and view.tan_bottom - pad <= ty <= view.tan_top + pad)


def _scan(database: Database, view: View, grid: PreimageGrid, air: np.ndarray, level_bias: int,
          stats: dict) -> np.ndarray:
    """Run the column scans; the pre-image (ncols, nrows, PRE_CHANNELS) float32."""
    terrain = database.terrain
    eye = np.asarray(view.eye, np.float64) - terrain.origin  # float64 before anything else
    ground = surface_height(terrain, float(eye[0]), float(eye[1]))
    if ground is not None and eye[2] < ground + MIN_CLEARANCE_M:
        eye[2] = ground + MIN_CLEARANCE_M
        stats["terrain_eye_clamped"] = 1
    level_nx = np.array([terrain.level_size(lv)[0] for lv in range(terrain.levels)], np.int64)
    level_ny = np.array([terrain.level_size(lv)[1] for lv in range(terrain.levels)], np.int64)
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
    centres = grid.theta0 + (np.arange(grid.nrows) + 0.5) * grid.dtheta
    row_cs = np.ascontiguousarray(np.stack([np.cos(centres), np.sin(centres)], 1))
    tops = grid.theta0 + (np.arange(grid.nrows) + 1.0) * grid.dtheta
    top_cs = np.ascontiguousarray(np.stack([np.cos(tops), np.sin(tops)], 1))
    pre = np.empty((grid.ncols, grid.nrows, PRE_CHANNELS), np.float32)
    visits = np.zeros(grid.ncols, np.int64)
    nx, ny = terrain.extent_m
    scan_kernel(terrain.z, terrain.rgb, terrain.pattern, terrain.page_table, terrain.table_offset,
                terrain.pages_x, terrain.pages_y, log2_page, level_nx, level_ny,
                float(terrain.spacing_m), float(nx), float(ny), float(terrain.z_max), pat_top,
                pat_rgb, pat_bands, _SRGB_LUT, eye, grid.phi_lo, grid.dphi, grid.ncols,
                grid.theta0, grid.dtheta, grid.nrows, r_switch, r_far, air, row_cs, top_cs,
                grid.first_row, pre, visits)
    if grid.first_row[0] > 0:  # some columns skipped rows
        fill_skipped(pre, grid.first_row, grid.full)
    stats["terrain_voxels"] = int(visits.sum())
    stats["terrain_columns"] = grid.ncols
    stats["terrain_rows"] = grid.nrows
    return pre


def _sky_haze(air: np.ndarray, grid: PreimageGrid) -> tuple[np.ndarray, float, float]:
    """Haze of the sky (range infinite) at the centre elevation of each of the view's
    pre-image rows: (table, elevation of row 0's lower edge, row height), radians."""
    if air[0] == 0.0:
        return np.zeros(1), grid.theta0, grid.theta1 - grid.theta0
    return sky_haze_table(air, grid.theta0, grid.dtheta, grid.nrows), grid.theta0, grid.dtheta


def _scan_clouds(database: Database, view: View, grid: PreimageGrid,
                 air: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The coarse cloud image: one cloud texel per CLOUD_FACTOR x CLOUD_FACTOR pre-image
    texels (seed 002: one eighth of the linear resolution), and those two ratios."""
    clouds = database.clouds
    ncols = max(1, math.ceil(grid.ncols / CLOUD_FACTOR))
    nrows = max(1, math.ceil(grid.nrows / CLOUD_FACTOR))
    dphi = grid.span / ncols
    dtheta = (grid.theta1 - grid.theta0) / nrows
    # Texel centres stop short of +-90 deg, so 1 / cos stays finite.
    centres = np.clip(grid.theta0 + (np.arange(nrows) + 0.5) * dtheta,
                      -0.5 * math.pi + 1e-6, 0.5 * math.pi - 1e-6)
    eye = np.array([view.eye[0] - clouds.origin[0], view.eye[1] - clouds.origin[1], view.eye[2]])
    out = np.empty((ncols, nrows, 5), np.float32)
    scan_clouds_kernel(clouds.base_m, clouds.top_m, clouds.density, clouds.cell_m, eye,
                       clouds.colour, BASE_SHADE, grid.phi_lo, dphi, ncols, np.tan(centres),
                       1.0 / np.cos(centres), np.sin(centres), float(view.far), air, out)
    return out, dphi / grid.dphi, dtheta / grid.dtheta


def surface_height(terrain, x: float, y: float) -> float | None:
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
