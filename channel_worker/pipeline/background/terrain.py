"""Voxel terrain of JP H07-76990, the background the polygons are depth-tested against
(docs/terrain.md): the pre-image grid and the radial column scan.

1. A pre-image is computed for zero roll: its columns are vertical half-planes through the
   eye (one azimuth each) and its rows elevation angles. One radial scan per column walks the
   ground grid outward from the column's start point one grid line at a time, at the level
   whose voxels are one to two pixels wide at that range (coarser each time the range
   doubles), and integrates what rises above the horizon of what it has seen into the rows
   by the fraction of each row it covers (_scan_kernels.scan_kernel). Because each column is
   an exact vertical plane, occlusion by elevation angle is exact at any pitch.
2. Every output sample then takes its value from the pre-image at its exact azimuth and
   elevation, bilinearly (background.py, _warp_kernels.warp_kernel): this one inverse
   mapping is JP H07-76990's rotation by the roll angle with anti-aliased resampling and its
   vertical perspective correction, exact for wide and off-axis channels, so terrain seams
   between channels line up like polygon seams.

The haze (JP H07-76990) and the layered fog (US 5,535,374) are applied to every terrain
texel here, with the one air array the polygon kernels use too (air.air_params).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.fog.fog import average_floor
from channel_worker.pipeline.geometry.view import screen_mapping
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase
from services.rig.colour import srgb_to_linear

from ._groups import PRE_CHANNELS, ColumnGrid, Preimage, ScanLimits, VoxelPages
from ._scan_kernels import fill_skipped, scan_kernel
from .haze import OPAQUE_TAU, beta_at

#: Pre-image texels per output pixel along each axis, at the channel's centre of projection.
PREIMAGE_OVERSAMPLE = 1.0

#: Largest column stride (2^MAX_SKIP) towards the nadir.
MAX_SKIP = 5

#: Pixels per side of the warp's blocks (exact mapping at block corners, interpolated inside).
WARP_BLOCK = 8

#: An eye closer than this above the terrain surface (or below it) is moved up to it for the
#: terrain scan (metres): the picture stays defined instead of turning inside out. Counted in
#: the counter "terrain_eye_clamped".
MIN_CLEARANCE_M = 0.01

#: sRGB-encoded byte -> linear, for the database's uint8 colours.
_SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


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


def scan_terrain(database: Database, view: View, grid: PreimageGrid, air: np.ndarray,
                 level_bias: int, counters: dict[str, int]) -> Preimage:
    """Run the column scans of database.terrain over the view's pre-image grid.

    Args:
        database: the scene; database.terrain is not None.
        view: the channel's view for this frame.
        grid: the view's pre-image grid (preimage_grid).
        air: the frame's air array (air.air_params).
        level_bias: voxels are kept 2**bias to 2**(bias + 1) pixels wide
            (RenderOptions.terrain_bias).
        counters: receives "terrain_voxels" (voxels visited), "terrain_columns",
            "terrain_rows", and "terrain_eye_clamped" 1 when the eye was moved up to
            MIN_CLEARANCE_M above the surface.

    Returns:
        The pre-image, texels (grid.ncols, grid.nrows, PRE_CHANNELS) float32.

    Raises:
        ValueError: the scene has no terrain.
    """
    terrain = database.terrain
    if terrain is None:
        raise ValueError("scan_terrain: the scene has no terrain")
    eye = np.asarray(view.eye, np.float64) - terrain.origin  # float64 before anything else
    ground = surface_height(terrain, float(eye[0]), float(eye[1]))
    if ground is not None and eye[2] < ground + MIN_CLEARANCE_M:
        eye[2] = ground + MIN_CLEARANCE_M
        counters["terrain_eye_clamped"] = 1
    pre = np.empty((grid.ncols, grid.nrows, PRE_CHANNELS), np.float32)
    visits = np.zeros(grid.ncols, np.int64)
    limits = ScanLimits(grid.first_row, eye, _level_switch(terrain, view, eye, level_bias),
                        _far_range(database, terrain, view))
    scan_kernel(voxel_pages(terrain), column_grid(grid), limits, air, pre, visits,
                numba.get_num_threads())
    if grid.first_row[0] > 0:  # some columns skipped rows
        fill_skipped(pre, grid.first_row, grid.full)
    counters["terrain_voxels"] = int(visits.sum())
    counters["terrain_columns"] = grid.ncols
    counters["terrain_rows"] = grid.nrows
    return Preimage(pre, grid.full, grid.phi_lo, grid.dphi, grid.theta0, grid.dtheta,
                    pre.shape[0] * grid.dphi)


def voxel_pages(terrain: TerrainDatabase) -> VoxelPages:
    """The database's pages, page tables and patterns as the column scan reads them."""
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


def column_grid(grid: PreimageGrid) -> ColumnGrid:
    """The pre-image grid as the column scan walks it, with each row's centre and top
    elevation's cosine and sine."""
    centres = grid.theta0 + (np.arange(grid.nrows) + 0.5) * grid.dtheta
    row_cs = np.ascontiguousarray(np.stack([np.cos(centres), np.sin(centres)], 1))
    tops = grid.theta0 + (np.arange(grid.nrows) + 1.0) * grid.dtheta
    top_cs = np.ascontiguousarray(np.stack([np.cos(tops), np.sin(tops)], 1))
    return ColumnGrid(grid.phi_lo, grid.dphi, grid.ncols, grid.theta0, grid.dtheta, grid.nrows,
                      row_cs, top_cs)


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
