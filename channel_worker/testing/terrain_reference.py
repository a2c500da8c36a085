"""Reference renderer for voxel terrain, for tests and benchmarks only: exact ray casting.

The production terrain (the background stage's radial scans cast along screen lines, after
JP H07-76990) approximates what every sample of a channel sees of a TerrainDatabase. This
module computes it exactly, one ray per sample, so the approximation can be measured. It is
written to be obviously right, not fast.

The surface (world frame: x east, y north, z up, metres)
---------------------------------------------------------
Only level 0 is rendered. Level-0 voxel (i, j), 0 <= i < nx, 0 <= j < ny, covers the footprint
``origin[:2] + [i s, (i + 1) s] x [j s, (j + 1) s]`` (s = spacing_m). A point of it has local
coordinates (u, v) in [0, 1]^2, u east, v north.

- Data of a voxel: its 4 corner heights (float32, metres above origin[2], read as float64) and 4
  corner colours (sRGB uint8 decoded per channel to LINEAR RGB with IEC 61966-2-1), in
  CORNERS order sw, se, nw, ne. If the level-0 page holding the voxel is missing from the page
  table, the finest coarser level L that has the area supplies it (the database's own rule):
  level-L voxel (i >> L, j >> L); the level-0 voxel is then the sub-square of it at local
  offset ((i mod 2^L) / 2^L, (j mod 2^L) / 2^L), width 1 / 2^L, and its surface is the coarse
  voxel's bilinear surface restricted to that square (which is exactly bilinear again).
- Ground height H(u, v) = bilinear interpolation of the 4 corner heights:
  ``h_sw (1-u)(1-v) + h_se u (1-v) + h_nw (1-u) v + h_ne u v``.
- Ground colour C(u, v) = the same bilinear interpolation of the 4 LINEAR corner colours.
- World position of the surface point: ``origin + ((i + u) s, (j + v) s, H(u, v))`` (float64).
- Pattern voxels (pattern entry k >= 1, pattern P = patterns[k - 1]): an opaque box over the
  voxel's footprint from the ground up to ``top = max(corner heights) + P.top_m[-1]`` (for a
  voxel taken from a coarser level: the coarse voxel's corners, so the box is the coarse box).
  Its side at height g above the ground under the point (g = z - H(u, v)) has the colour of
  band b, the band with ``top_m[b - 1] < g <= top_m[b]`` (band 0 for g <= top_m[0]; the last
  band where g > top_m[-1], which happens where the ground is below the voxel's highest
  corner). Its top has the last band's colour. Colours decoded to linear.
- The terrain is a SOLID: every point of the footprint of the database at or below the ground
  (or, in a pattern voxel, at or below the box top) is inside. A ray's hit is the first point
  along it that is inside. Consequences: where neighbouring voxels' heights disagree along
  their shared edge (a discontinuity) or at the edge of the database, the step is closed by a
  vertical wall on that edge, coloured by the voxel the ray enters at the point it enters
  (ground colour C if below that voxel's ground, band colour if inside its pattern box).
  Outside the footprint there is no terrain: the ray continues to the background (a miss).

The rays
--------
Sample s of pixel (x, y) is at screen point (x + offsets[s, 0], y + offsets[s, 1]) (pixels,
y down). Its eye-frame direction is (tx, ty, 1) with ``tx = (sx - sx_offset) / sx_scale`` and
``ty = (sy - sy_offset) / sy_scale`` (project.screen_mapping), its world direction
``view.world_to_eye.T @ (tx, ty, 1)``, normalised, so the ray parameter t is the Euclidean
range from the eye. No near or far plane applies; hits beyond max_range are misses.

Everything is float64 and relative to the database origin: the ray starts at
``eye - origin`` (a difference of two nearby float64 numbers, exact or nearly so), so a
database and eye 1000 km from the world origin give the same result as near the origin.

How each ray is traced (exactly, no step length)
------------------------------------------------
1. Clip t to [0, max_range], to the footprint's x and y slabs and to z <= z_top (the highest
   corner of any level plus the tallest pattern: nothing is inside above it).
2. Walk the level-0 cells the ground projection of the ray crosses (2-D DDA, Amanatides & Woo;
   every crossing time is computed from the ray origin and the boundary index, never
   accumulated, and ties step x then y through a zero-length segment, so no cell is skipped).
   A vertical ray (zero ground projection) stays in its one cell column.
3. In each cell, on the segment t = t_a + tau, tau in [0, L]:
   - ground cell: f(tau) = ray_z - H(u(tau), v(tau)) = f0 + f1 tau + f2 tau^2 exactly, since
     u and v are linear in tau and H is bilinear; if f0 <= 0 the ray enters the cell inside the
     solid (a wall: hit at tau = 0), else the hit is the smallest root in [0, L] (first_root).
   - pattern cell: hit at tau = 0 if ray_z <= box top at the entry (the box side, or the ground
     wall if below the ground there), else where ray_z reaches the box top, if within L.
4. The eye must be outside the solid: if the eye is over the footprint and at or below the
   ground (or inside a pattern box) reference_terrain raises ValueError naming both heights.

A tangent ray (a double root) counts as a hit; whether rounding reports an exact tangency as a
touch or a near miss is not specified.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.geometry.view import screen_mapping
from channel_worker.pipeline.scene.terrain.database import CORNERS, Pattern, TerrainDatabase, pattern_bands

#: sRGB uint8 -> linear, IEC 61966-2-1 (the 256-entry table the database docs name).
_SRGB = np.arange(256, dtype=np.float64) / 255.0
SRGB_TO_LINEAR = np.where(_SRGB <= 0.04045, _SRGB / 12.92, ((_SRGB + 0.055) / 1.055) ** 2.4)

# Kinds of hit, for the colour of the hit point.
_GROUND = 0
_BAND = 1

#: The database as the kernels read it (numba takes named tuples of arrays and scalars).
_Grid = namedtuple("_Grid", [
    "spacing",        # float64 level-0 voxel width, metres
    "nx", "ny",       # int64 level-0 voxels east, north
    "levels",         # int64
    "page_size",      # int64
    "pages_x", "pages_y", "table_offset",  # (levels,) int64
    "page_table",     # (T,) int64
    "z",              # (N, P, P, 4) float32 corner heights above origin[2]
    "rgb",            # (N, P, P, 4, 3) uint8 sRGB corner colours
    "pattern",        # (N, P, P) uint8
    "band_top",       # (K, B) float64 band tops above ground (padded with the last top)
    "band_count",     # (K,) int64
    "band_rgb",       # (K, B, 3) float64 linear band colours
    "srgb",           # (256,) float64 decode table
    "z_top",          # float64 nothing of the terrain is above this, metres above origin[2]
])


@dataclass(frozen=True)
class ReferenceTerrain:
    """What every sample of a channel sees of the terrain.

    Attributes:
        rgb: (H, W, S, 3) float64 linear RGB of the surface point hit; 0 where hit is False.
        range_m: (H, W, S) float64 Euclidean distance from the eye to the hit, metres; +inf
            where hit is False.
        hit: (H, W, S) bool the sample's ray meets the terrain within max_range.
    """

    rgb: np.ndarray
    range_m: np.ndarray
    hit: np.ndarray

    def pixel_rgb(self, background_rgb: np.ndarray) -> np.ndarray:
        """(H, W, 3) float64 box-filtered pixels: mean over samples, background_rgb for misses.

        Args:
            background_rgb: (3,) linear RGB seen by a sample that misses the terrain.
        """
        bg = np.asarray(background_rgb, np.float64).reshape(3)
        return np.where(self.hit[..., None], self.rgb, bg).mean(axis=2)

    def pixel_range(self) -> np.ndarray:
        """(H, W) float64 nearest range any sample of the pixel sees, metres (+inf: none)."""
        return self.range_m.min(axis=2)


def reference_terrain(terrain: TerrainDatabase, view: View, offsets: np.ndarray, *,
                      max_range: float = 200_000.0) -> ReferenceTerrain:
    """Trace one exact ray per sample of a channel against the level-0 terrain surface.

    Args:
        terrain: the database (level 0 rendered, coarser levels only where level 0 lacks a page).
        view: the channel's view (make_view); eye in world metres.
        offsets: (S, 2) sample positions, pixels from each pixel's top-left corner.
        max_range: hits farther than this (metres) are misses.

    Returns:
        Per-sample colour, range and hit mask (see the module docstring for the surface).

    Raises:
        ValueError: bad offsets or max_range, a database whose coarsest level lacks a page, or
            an eye inside the terrain (named with the eye and surface heights, world metres).
    """
    offsets = np.asarray(offsets, np.float64)
    if offsets.ndim != 2 or offsets.shape[1] != 2 or offsets.shape[0] < 1:
        raise ValueError(f"offsets: expected shape (S, 2), got {offsets.shape}")
    if not np.all(np.isfinite(offsets)):
        raise ValueError("offsets: not all finite")
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    height, width, count = view.height, view.width, offsets.shape[0]
    sx = np.arange(width)[None, :, None] + offsets[None, None, :, 0]
    sy = np.arange(height)[:, None, None] + offsets[None, None, :, 1]
    eye_dir = np.empty((height, width, count, 3))
    eye_dir[..., 0] = (sx - sx_off) / sx_scale  # guard: check_channel makes the scales nonzero
    eye_dir[..., 1] = (sy - sy_off) / sy_scale
    eye_dir[..., 2] = 1.0
    world_dir = eye_dir.reshape(-1, 3) @ np.asarray(view.world_to_eye, np.float64)
    rgb, range_m, hit = reference_rays(terrain, view.eye, world_dir, max_range=max_range)
    return ReferenceTerrain(rgb=rgb.reshape(height, width, count, 3),
                            range_m=range_m.reshape(height, width, count),
                            hit=hit.reshape(height, width, count))


def reference_rays(terrain: TerrainDatabase, eye: np.ndarray, directions: np.ndarray, *,
                   max_range: float = 200_000.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Trace rays from one eye in given world directions (reference_terrain without a view).

    Args:
        terrain: the database.
        eye: (3,) world position, metres, float64.
        directions: (N, 3) world directions, any nonzero length (normalised here).
        max_range: hits farther than this (metres) are misses.

    Returns:
        (rgb (N, 3) float64 linear, 0 for misses; range_m (N,) float64 metres, +inf for misses;
        hit (N,) bool).

    Raises:
        ValueError: as reference_terrain, or a zero or non-finite direction.
    """
    if not (math.isfinite(max_range) and max_range > 0.0):
        raise ValueError(f"max_range: expected a finite positive number of metres, got {max_range}")
    directions = np.asarray(directions, np.float64).reshape(-1, 3)
    length = np.sqrt((directions ** 2).sum(axis=1))
    bad = ~(np.isfinite(length) & (length > 0.0))
    if bad.any():
        raise ValueError(f"directions[{int(np.argmax(bad))}]: zero or not finite")
    unit = np.ascontiguousarray(directions / length[:, None])  # guard: length > 0 checked
    grid = _grid(terrain)
    # Eye-relative to the database: one float64 difference, before anything else.
    rel = np.asarray(eye, np.float64).reshape(3) - np.asarray(terrain.origin, np.float64)
    if not np.all(np.isfinite(rel)):
        raise ValueError(f"eye: {eye} is not finite")
    _check_eye_outside(grid, rel, terrain)
    n = unit.shape[0]
    rgb = np.zeros((n, 3))
    range_m = np.full(n, np.inf)
    hit = np.zeros(n, np.bool_)
    _trace_kernel(grid, rel[0], rel[1], rel[2], unit, float(max_range), rgb, range_m, hit)
    return rgb, range_m, hit


def single_level_database(heights_nodes: np.ndarray, colours_srgb_nodes: np.ndarray,
                          spacing: float, origin: np.ndarray, page_size: int = 8,
                          pattern_mask: np.ndarray | None = None,
                          patterns: tuple[Pattern, ...] = ()) -> TerrainDatabase:
    """A one-level TerrainDatabase from node grids (for tests; no build pipeline involved).

    Args:
        heights_nodes: (ny + 1, nx + 1) heights of the voxel corners, metres above origin[2];
            [j, i] is the node at origin + (i, j) * spacing. Stored as float32.
        colours_srgb_nodes: (ny + 1, nx + 1, 3) uint8 sRGB colour of each node.
        spacing: voxel width, metres.
        origin: (3,) world position of node (0, 0) at height 0, metres.
        page_size: voxels per page side.
        pattern_mask: (ny, nx) pattern entry of each voxel (0 plain ground, k >= 1 for
            patterns[k - 1]; a bool mask means pattern 1); None for none.
        patterns: the vertical patterns.

    Returns:
        The database: every voxel copies its corners from the node grid (no discontinuity);
        voxels of the last pages beyond nx, ny repeat the edge nodes.
    """
    hn = np.asarray(heights_nodes, np.float32)
    cn = np.asarray(colours_srgb_nodes)
    if hn.ndim != 2 or hn.shape[0] < 2 or hn.shape[1] < 2:
        raise ValueError(f"heights_nodes: expected shape (ny + 1, nx + 1) >= (2, 2), "
                         f"got {hn.shape}")
    if cn.shape != hn.shape + (3,) or cn.dtype != np.uint8:
        raise ValueError(f"colours_srgb_nodes: expected uint8 {hn.shape + (3,)}, "
                         f"got {cn.dtype} {cn.shape}")
    ny, nx = hn.shape[0] - 1, hn.shape[1] - 1
    if pattern_mask is None:
        pattern_mask = np.zeros((ny, nx), np.uint8)
    mask = np.asarray(pattern_mask).astype(np.uint8)
    if mask.shape != (ny, nx):
        raise ValueError(f"pattern_mask: expected shape {(ny, nx)}, got {mask.shape}")
    if mask.max(initial=0) > len(patterns):
        raise ValueError(f"pattern_mask: entry {mask.max()} but only {len(patterns)} patterns")
    p = int(page_size)
    pages_x, pages_y = -(-nx // p), -(-ny // p)
    # Voxel (i, j) for every voxel of every page, clamped to the real ones at the far edges.
    vi = np.minimum(np.arange(pages_x * p), nx - 1)
    vj = np.minimum(np.arange(pages_y * p), ny - 1)
    corner_z = np.stack([hn[vj[:, None] + dy, vi[None, :] + dx] for dx, dy in CORNERS], -1)
    corner_c = np.stack([cn[vj[:, None] + dy, vi[None, :] + dx] for dx, dy in CORNERS], -2)
    pat = mask[vj[:, None], vi[None, :]]

    def paged(a: np.ndarray) -> np.ndarray:  # (pages_y P, pages_x P, ...) -> (pages, P, P, ...)
        a = a.reshape((pages_y, p, pages_x, p) + a.shape[2:])
        a = np.moveaxis(a, 2, 1)
        return np.ascontiguousarray(a.reshape((pages_y * pages_x, p, p) + a.shape[4:]))

    z_max = float(hn.max())
    for k, pattern in enumerate(patterns, start=1):
        sel = mask == k
        if sel.any():
            vox_max = corner_z[:ny, :nx][sel].max(axis=-1)
            z_max = max(z_max, float((vox_max + np.float32(pattern.top_m[-1])).max()))
    return TerrainDatabase(
        spacing_m=float(spacing), origin=np.asarray(origin, np.float64).reshape(3).copy(),
        nx=nx, ny=ny, page_size=p, levels=1,
        pages_x=np.array([pages_x], np.int64), pages_y=np.array([pages_y], np.int64),
        table_offset=np.array([0], np.int64),
        page_table=np.arange(pages_x * pages_y, dtype=np.int32),
        z=paged(corner_z), rgb=paged(corner_c), pattern=paged(pat), patterns=tuple(patterns),
        z_min=float(hn.min()), z_max=z_max, info={"source": "single_level_database"},
        source="<single_level_database>")


# ----------------------------------------------------------------------------- preparation


def _grid(terrain: TerrainDatabase) -> _Grid:
    """The kernels' view of the database, after checking the coarsest level is complete."""
    if terrain.levels < 1:
        raise ValueError(f"{terrain.source}: levels {terrain.levels} < 1")
    if not (terrain.spacing_m > 0.0 and math.isfinite(terrain.spacing_m)):
        raise ValueError(f"{terrain.source}: spacing_m {terrain.spacing_m} is not positive")
    top = terrain.levels - 1
    start = int(terrain.table_offset[top])
    size = int(terrain.pages_x[top] * terrain.pages_y[top])
    coarsest = np.asarray(terrain.page_table[start:start + size])
    missing = np.flatnonzero(coarsest < 0)
    if missing.size:
        py, px = divmod(int(missing[0]), int(terrain.pages_x[top]))
        raise ValueError(f"{terrain.source}: coarsest level {top} lacks page ({px}, {py})")
    bands = pattern_bands(terrain)
    return _Grid(
        spacing=float(terrain.spacing_m), nx=int(terrain.nx), ny=int(terrain.ny),
        levels=int(terrain.levels), page_size=int(terrain.page_size),
        pages_x=np.asarray(terrain.pages_x, np.int64),
        pages_y=np.asarray(terrain.pages_y, np.int64),
        table_offset=np.asarray(terrain.table_offset, np.int64),
        page_table=np.asarray(terrain.page_table, np.int64),
        z=np.asarray(terrain.z), rgb=np.asarray(terrain.rgb), pattern=np.asarray(terrain.pattern),
        band_top=bands.top_m, band_count=bands.count, band_rgb=bands.rgb, srgb=SRGB_TO_LINEAR,
        z_top=bands.z_top)


def _check_eye_outside(grid: _Grid, rel: np.ndarray, terrain: TerrainDatabase) -> None:
    """Raise ValueError if the eye (rel = eye - origin) is inside the terrain solid."""
    ground, box_top, over = _eye_surface(grid, rel[0], rel[1])
    if not over:
        return
    base = float(terrain.origin[2])
    if rel[2] <= ground:
        raise ValueError(f"eye height {rel[2] + base} m is not above the terrain surface "
                         f"{ground + base} m under it")
    if rel[2] <= box_top:
        raise ValueError(f"eye height {rel[2] + base} m is inside a pattern box (ground "
                         f"{ground + base} m, box top {box_top + base} m)")


# ----------------------------------------------------------------------------- kernels


@njit(cache=True)
def bilinear(c00: float, c10: float, c01: float, c11: float, u: float, v: float) -> float:
    """Bilinear interpolation of corner values (sw, se, nw, ne) at local (u, v)."""
    return (c00 * (1.0 - u) * (1.0 - v) + c10 * u * (1.0 - v)
            + c01 * (1.0 - u) * v + c11 * u * v)


@njit(cache=True)
def first_root(f0: float, f1: float, f2: float, length: float) -> float:
    """Smallest tau in [0, length] with f0 + f1 tau + f2 tau^2 = 0, given f0 > 0; -1 if none.

    The quadratic is solved in the cancellation-free form: q = -(f1 + sign(f1) sqrt(D)) / 2
    (f1 and sign(f1) sqrt(D) have the same sign, so nothing cancels), roots q / f2 and f0 / q.
    When f2 is tiny (nearly linear) q / f2 is the far root and f0 / q -> -f0 / f1 stays exact.
    """
    if f2 == 0.0:
        # Linear: f reaches 0 from f0 > 0 only while decreasing. Guard: f1 < 0 so f1 != 0.
        if f1 < 0.0:
            tau = -f0 / f1
            if tau <= length:
                return tau
        return -1.0
    disc = f1 * f1 - 4.0 * f2 * f0
    if disc < 0.0:
        return -1.0  # no real root: f keeps the sign of f0 > 0
    root = math.sqrt(disc)
    q = -0.5 * (f1 + root) if f1 >= 0.0 else -0.5 * (f1 - root)
    if q == 0.0:
        # Only if f1 = 0 and disc = 0, i.e. f2 f0 = 0: impossible with f0 > 0, f2 != 0.
        # Kept as the guard of the division f0 / q.
        return -1.0
    best = -1.0
    for tau in (q / f2, f0 / q):  # guards: f2 != 0 in this branch, q != 0 above
        if 0.0 <= tau <= length and (best < 0.0 or tau < best):
            best = tau
    return best


@njit(cache=True)
def _locate(g, i, j):
    """The finest stored voxel covering level-0 cell (i, j), and where the cell sits in it.

    Returns (page, vx, vy, u0, v0, w): page index (-1 if no level has the area), the voxel's
    position in its page, and the cell as the sub-square [u0, u0 + w] x [v0, v0 + w] of the
    voxel's local coordinates (u0 = v0 = 0, w = 1 at level 0).
    """
    p = g.page_size
    for level in range(g.levels):
        ci = i >> level
        cj = j >> level
        px = ci // p
        py = cj // p
        if px < g.pages_x[level] and py < g.pages_y[level]:
            page = g.page_table[g.table_offset[level] + py * g.pages_x[level] + px]
            if page >= 0:
                w = 1.0 / (1 << level)
                u0 = (i - (ci << level)) * w
                v0 = (j - (cj << level)) * w
                return page, ci - px * p, cj - py * p, u0, v0, w
    return -1, 0, 0, 0.0, 0.0, 1.0


@njit(cache=True)
def _cell(g, i, j):
    """Level-0 cell (i, j) as the kernels use it.

    Returns (page, vx, vy, u0, v0, w, h00, h10, h01, h11, k, top): the _locate result, the
    cell's corner heights (sw, se, nw, ne; float64 metres above origin[2]) of the surface
    restricted to it, its pattern entry k (0 for none; -1 for a cell no level covers) and, for
    k >= 1, the box top (metres above origin[2]).
    """
    page, vx, vy, u0, v0, w = _locate(g, i, j)
    if page < 0:
        return page, vx, vy, u0, v0, w, 0.0, 0.0, 0.0, 0.0, -1, 0.0
    z00 = np.float64(g.z[page, vy, vx, 0])
    z10 = np.float64(g.z[page, vy, vx, 1])
    z01 = np.float64(g.z[page, vy, vx, 2])
    z11 = np.float64(g.z[page, vy, vx, 3])
    h00 = bilinear(z00, z10, z01, z11, u0, v0)
    h10 = bilinear(z00, z10, z01, z11, u0 + w, v0)
    h01 = bilinear(z00, z10, z01, z11, u0, v0 + w)
    h11 = bilinear(z00, z10, z01, z11, u0 + w, v0 + w)
    k = np.int64(g.pattern[page, vy, vx])
    top = 0.0
    if k >= 1:
        top = max(max(z00, z10), max(z01, z11)) + g.band_top[k - 1, g.band_count[k - 1] - 1]
    return page, vx, vy, u0, v0, w, h00, h10, h01, h11, k, top


@njit(cache=True)
def _ground_colour(g, page, vx, vy, u0, v0, w, u, v):
    """Linear RGB at local (u, v) of a level-0 cell: the stored voxel's corners, bilinear."""
    uu = u0 + u * w
    vv = v0 + v * w
    out = np.empty(3)
    for c in range(3):
        corner = g.rgb[page, vy, vx, :, c]
        out[c] = bilinear(g.srgb[corner[0]], g.srgb[corner[1]], g.srgb[corner[2]],
                          g.srgb[corner[3]], uu, vv)
    return out


@njit(cache=True)
def _band(g, k, above_ground):
    """Band of pattern k seen at a height above the ground: top_m[b-1] < h <= top_m[b]."""
    n = g.band_count[k - 1]
    for b in range(n):
        if above_ground <= g.band_top[k - 1, b]:
            return b
    return n - 1  # above the last band's top (ground below the voxel's highest corner)


@njit(cache=True)
def _eye_surface(g, x, y):
    """(ground, box top or -inf, over the footprint) under the point (x, y) (origin-relative)."""
    s = g.spacing
    if not (0.0 <= x <= g.nx * s and 0.0 <= y <= g.ny * s):
        return 0.0, -np.inf, False
    i = min(max(int(math.floor(x / s)), 0), g.nx - 1)
    j = min(max(int(math.floor(y / s)), 0), g.ny - 1)
    _page, _vx, _vy, _u0, _v0, _w, h00, h10, h01, h11, k, top = _cell(g, i, j)
    if k < 0:
        return 0.0, -np.inf, False
    ground = bilinear(h00, h10, h01, h11, (x - i * s) / s, (y - j * s) / s)
    return ground, top if k >= 1 else -np.inf, True


@njit(cache=True)
def _clip_slab(p, d, lo, hi, t0, t1):
    """[t0, t1] cut to the t where lo <= p + t d <= hi (empty: t0 > t1)."""
    if d == 0.0:
        if lo <= p <= hi:
            return t0, t1
        return 1.0, 0.0
    ta = (lo - p) / d  # guard: d != 0
    tb = (hi - p) / d
    if ta > tb:
        ta, tb = tb, ta
    return max(t0, ta), min(t1, tb)


@njit(cache=True)
def _crossing(p, d, i, s):
    """t at which p + t d leaves cell i (width s) along one axis; inf if d = 0."""
    if d > 0.0:
        return ((i + 1) * s - p) / d
    if d < 0.0:
        return (i * s - p) / d
    return np.inf


@njit(cache=True)
def _hit_in_cell(g, i, j, px, py, pz, dx, dy, dz, ta, length):
    """First point of the solid on the segment t = ta + tau, tau in [0, length], of cell (i, j).

    Returns (tau or -1, kind, band, cell...) where kind is _GROUND or _BAND.
    """
    s = g.spacing
    cell = _cell(g, i, j)
    h00, h10, h01, h11, k, top = cell[6], cell[7], cell[8], cell[9], cell[10], cell[11]
    if k < 0:
        return -1.0, _GROUND, 0  # no level covers the cell: a hole (impossible once checked)
    ua = (px + ta * dx - i * s) / s
    va = (py + ta * dy - j * s) / s
    za = pz + ta * dz
    ground = bilinear(h00, h10, h01, h11, ua, va)
    if k >= 1:
        if za <= ground:
            return 0.0, _GROUND, 0  # enters below the ground: the wall of a step
        if za <= top:
            return 0.0, _BAND, _band(g, k, za - ground)  # the box side
        if dz < 0.0:
            tau = (top - za) / dz  # guard: dz < 0; > 0 since za > top
            if tau <= length:
                return tau, _BAND, g.band_count[k - 1] - 1  # the box top
        return -1.0, _GROUND, 0
    f0 = za - ground
    if f0 <= 0.0:
        return 0.0, _GROUND, 0  # enters inside the solid: a wall at the cell edge
    # H(u, v) = h00 + a u + b v + c u v; along the ray u = ua + du tau, v = va + dv tau.
    a = h10 - h00
    b = h01 - h00
    c = h00 - h10 - h01 + h11
    du = dx / s
    dv = dy / s
    f1 = dz - (a + c * va) * du - (b + c * ua) * dv  # ray slope minus surface slope
    f2 = -c * du * dv
    return first_root(f0, f1, f2, length), _GROUND, 0


@njit(cache=True)
def _trace(g, px, py, pz, dx, dy, dz, t_max, out):
    """Trace one ray (origin p relative to the database origin, unit direction d).

    Writes the linear colour of the hit to out and returns its range t, or -1 for a miss.
    """
    s = g.spacing
    t0, t1 = _clip_slab(px, dx, 0.0, g.nx * s, 0.0, t_max)
    t0, t1 = _clip_slab(py, dy, 0.0, g.ny * s, t0, t1)
    t0, t1 = _clip_slab(pz, dz, -np.inf, g.z_top, t0, t1)
    if t0 > t1:
        return -1.0
    i = min(max(int(math.floor((px + t0 * dx) / s)), 0), g.nx - 1)
    j = min(max(int(math.floor((py + t0 * dy) / s)), 0), g.ny - 1)
    step_i = 1 if dx > 0.0 else -1
    step_j = 1 if dy > 0.0 else -1
    next_i = _crossing(px, dx, i, s)
    next_j = _crossing(py, dy, j, s)
    ta = t0
    while True:
        tb = min(min(next_i, next_j), t1)
        tau, kind, band = _hit_in_cell(g, i, j, px, py, pz, dx, dy, dz, ta, max(tb - ta, 0.0))
        if tau >= 0.0:
            t = ta + tau
            if kind == _BAND:
                k = np.int64(_cell(g, i, j)[10])
                for c in range(3):
                    out[c] = g.band_rgb[k - 1, band, c]
            else:
                page, vx, vy, u0, v0, w = _locate(g, i, j)
                u = min(max((px + t * dx - i * s) / s, 0.0), 1.0)
                v = min(max((py + t * dy - j * s) / s, 0.0), 1.0)
                rgb = _ground_colour(g, page, vx, vy, u0, v0, w, u, v)
                for c in range(3):
                    out[c] = rgb[c]
            return t
        if tb >= t1:
            return -1.0
        # Step into the neighbour across the nearer boundary (x first on a tie: the y
        # neighbour follows through a zero-length segment, so no cell is skipped).
        if next_i <= next_j:
            i += step_i
            ta = max(ta, next_i)
            if i < 0 or i >= g.nx:
                return -1.0  # left the footprint (only by rounding before t1)
            next_i = _crossing(px, dx, i, s)
        else:
            j += step_j
            ta = max(ta, next_j)
            if j < 0 or j >= g.ny:
                return -1.0
            next_j = _crossing(py, dy, j, s)


@njit(cache=True, parallel=True)
def _trace_kernel(g, px, py, pz, unit, t_max, rgb, range_m, hit):
    """Trace every ray (rows of unit); write colour, range and hit of each."""
    for n in prange(unit.shape[0]):
        out = np.zeros(3)
        t = _trace(g, px, py, pz, unit[n, 0], unit[n, 1], unit[n, 2], t_max, out)
        if t >= 0.0:
            hit[n] = True
            range_m[n] = t
            for c in range(3):
                rgb[n, c] = out[c]
