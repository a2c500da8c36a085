"""A lean Voxel Space renderer: the benchmark peer of the background stage's terrain.

Voxel Space is the terrain renderer of NovaLogic's Comanche (1992; NovaLogic's patents
US 5,550,959, "Technique and system for the real-time generation of perspective images", and
US 6,020,893, "System and method for realistic terrain simulation"), as S. Macke describes it
("Voxel Space", github.com/s-macke/VoxelSpace, "Terrain rendering algorithm in less than 20
lines of code"): a height map and a colour map, one height and one colour per map cell; for
every screen column, march front to back over the map along the column's ground ray, project
each sample's height onto the screen, and draw the part of the column between that row and
the highest row drawn so far (a y-buffer per column) in the sample's colour. The step grows
with the distance, so far terrain costs fewer samples. Pitch is a shift of the horizon row
(the picture is sheared, not rotated); there is no roll.

bench/bench_terrain.py times it beside our terrain stage (JP H07-76990: levels, elevation-angle
occlusion, coverage-weighted colour, cast at any roll) from the same eyes, with the same channel frustum
and the same database, and measures both against the exact ray-cast reference
(channel_worker/testing/terrain_reference.py). It is written for speed, not for looks: one
sample per pixel, nearest map cell, no level of detail, no filtering. It shares no kernel with
the pipeline.

The maps (voxel_maps) are the level-0 voxels of a TerrainDatabase: a cell's height is its
surface at the voxel's centre (the mean of the four corner heights), its colour the mean of
the four corner colours in linear light, stored sRGB 8-bit as the database stores them. A
pattern voxel (tree, building) is a column up to its box top (highest corner plus the
pattern's height: the reference's box) in the pattern's top colour. Where a database lacks a
level-0 page, the next coarser level that has the area supplies it (the database's own rule).

Geometry, for a channel of the View (make_view): column x (pixel centre x + 0.5) has the
horizontal tangent tx = (x + 0.5 - sx_offset) / sx_scale (geometry/view.py screen_mapping),
and its ground ray runs along forward + tx right, forward and right the channel's horizontal
axes; z is the depth along forward (the classic's z). A map sample of height h at depth z is
drawn from screen row

    y = horizon + k (eye_z - h) / z,   k = -sy_scale,   horizon = sy_offset - sy_scale tan(pitch)

down to the y-buffer: the unpitched projection shifted so that the horizon sits where the
pitched camera sees it. That is exact at zero pitch and on the horizon; elsewhere a pitched
picture is sheared instead of rotated, the classic's approximation (its error is in the
range error the bench measures). The range a pixel records is the distance from the eye to
the sample drawn in it, sqrt((z |forward + tx right|)^2 + (eye_z - h)^2).

Marching: depth z from where the lowest screen row could first see the highest cell (nothing
nearer reaches the screen) to where the ray leaves the map or passes view.far, step
dz = dz_min + growth z (dz_min: one cell, the classic's map unit; growth: the classic's
"dz *= 1.01": the step grows in proportion to the distance), ending a column early once
nothing on the map can rise above its y-buffer. Undrawn rows above the horizon row are sky,
below it earth; their range is infinite.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.geometry.view import screen_mapping
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase
from services.rig.colour import linear_to_srgb8, srgb_to_linear

#: The step's growth with distance: dz = dz_min + GROWTH z (the classic's dz *= 1.01).
GROWTH = 0.01
#: sRGB 8-bit -> linear, as float32 (IEC 61966-2-1).
SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


class VoxelMaps(NamedTuple):
    """The height and colour map of Voxel Space.

    Attributes:
        height: (ny, nx) float32 metres above origin[2]; [j, i] is the cell whose south-west
            corner is at origin + (i, j) * spacing_m (x east, y north).
        rgb: (ny, nx, 3) uint8 sRGB colour of each cell.
        origin: (3,) float64 world position of cell (0, 0)'s south-west corner at height 0.
        spacing_m: cell width, metres.
        z_max: highest cell, metres above origin[2].
    """

    height: np.ndarray
    rgb: np.ndarray
    origin: np.ndarray
    spacing_m: float
    z_max: float


class VoxelFrame(NamedTuple):
    """A frame of the peer.

    Attributes:
        rgb: (H, W, 3) float32 linear RGB.
        range_m: (H, W) float32 metres from the eye to the map sample drawn in the pixel
            (+inf for sky and earth).
        samples: map samples visited (the peer's analogue of voxels visited).
    """

    rgb: np.ndarray
    range_m: np.ndarray
    samples: int


class _Camera(NamedTuple):
    """What the column kernel needs of the view, in the map's frame (metres, origin-relative)."""

    ex: float            # eye x, y, z relative to the map origin
    ey: float
    ez: float
    fx: float            # forward: the channel's horizontal axis, unit
    fy: float
    rx: float            # right: horizontal, unit
    ry: float
    sx_scale: float      # screen x = tx * sx_scale + sx_offset (pixels)
    sx_offset: float
    horizon: float       # screen row of the horizon (pixels from the top edge)
    k: float             # pixels per unit of (eye_z - h) / z
    z_start: float       # first depth of the march, metres
    far: float           # largest range, metres (view.far)
    dz_min: float        # smallest step, metres
    growth: float        # step growth per metre of depth
    sky_r: float         # linear sky and earth colours
    sky_g: float
    sky_b: float
    earth_r: float
    earth_g: float
    earth_b: float


# --- the maps ---------------------------------------------------------------------------------

def voxel_maps(terrain: TerrainDatabase) -> VoxelMaps:
    """The level-0 height and colour map of a terrain database (module docstring).

    Reads the database page by page, so a memory-mapped one is read once, in order; a
    4096 x 4096-voxel database takes a few seconds and 112 MB.
    """
    nx, ny, p = int(terrain.nx), int(terrain.ny), int(terrain.page_size)
    height = np.empty((ny, nx), np.float32)
    rgb = np.empty((ny, nx, 3), np.uint8)
    top_m = np.array([float(np.float32(pt.top_m[-1])) for pt in terrain.patterns] or [0.0],
                     np.float32)
    top_rgb = np.array([np.asarray(pt.rgb, np.uint8)[-1] for pt in terrain.patterns]
                       or [[0, 0, 0]], np.uint8)
    for py in range(int(terrain.pages_y[0])):
        for px in range(int(terrain.pages_x[0])):
            j0, i0 = py * p, px * p
            h, w = min(p, ny - j0), min(p, nx - i0)
            page = terrain.page_index(0, px, py)
            if page >= 0:
                z = np.asarray(terrain.z[page, :h, :w], np.float32)       # (h, w, 4)
                corners = SRGB_LUT[np.asarray(terrain.rgb[page, :h, :w])]  # (h, w, 4, 3)
                pattern = np.asarray(terrain.pattern[page, :h, :w])
            else:
                z, corners = _from_coarser(terrain, i0, j0, w, h)
                pattern = np.zeros((h, w), np.uint8)  # coarser levels hold no patterns
            height[j0:j0 + h, i0:i0 + w] = z.mean(axis=2)
            rgb[j0:j0 + h, i0:i0 + w] = linear_to_srgb8(corners.mean(axis=2))
            marked = pattern > 0
            if marked.any():
                k = pattern[marked].astype(np.int64) - 1
                block_h = height[j0:j0 + h, i0:i0 + w]
                block_h[marked] = z[marked].max(axis=1) + top_m[k]
                rgb[j0:j0 + h, i0:i0 + w][marked] = top_rgb[k]
    return VoxelMaps(height=height, rgb=rgb, origin=np.asarray(terrain.origin, np.float64).copy(),
                     spacing_m=float(terrain.spacing_m), z_max=float(height.max()))


def _from_coarser(terrain: TerrainDatabase, i0: int, j0: int, w: int,
                  h: int) -> tuple[np.ndarray, np.ndarray]:
    """Corner heights (h, w, 4) and linear corner colours (h, w, 4, 3) of the level-0 cells
    [i0, i0 + w) x [j0, j0 + h), taken from the finest coarser level that has them: each
    cell is a sub-square of a coarse voxel, whose bilinear surface restricted to it is
    bilinear again (terrain_reference.py's rule)."""
    p = int(terrain.page_size)
    jj, ii = np.meshgrid(np.arange(j0, j0 + h), np.arange(i0, i0 + w), indexing="ij")
    z = np.zeros((h, w, 4), np.float32)
    c = np.zeros((h, w, 4, 3), np.float32)
    todo = np.ones((h, w), bool)
    for level in range(1, int(terrain.levels)):
        ci, cj = ii >> level, jj >> level
        px, py = ci // p, cj // p
        inside = (px < terrain.pages_x[level]) & (py < terrain.pages_y[level])
        page = np.full((h, w), -1, np.int64)
        page[inside] = terrain.page_table[terrain.table_offset[level]
                                          + py[inside] * terrain.pages_x[level] + px[inside]]
        take = todo & (page >= 0)
        if take.any():
            vx, vy, pg = (ci - px * p)[take], (cj - py * p)[take], page[take]
            cz = np.asarray(terrain.z[pg, vy, vx], np.float64)                # (n, 4)
            cc = SRGB_LUT[np.asarray(terrain.rgb[pg, vy, vx])].astype(np.float64)  # (n, 4, 3)
            scale = 1.0 / (1 << level)
            u0 = (ii - (ci << level))[take] * scale
            v0 = (jj - (cj << level))[take] * scale
            for n, (du, dv) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):  # CORNERS order
                u, v = u0 + du * scale, v0 + dv * scale
                wts = np.stack([(1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v], axis=1)
                z[take, n] = (cz * wts).sum(axis=1)
                c[take, n] = (cc * wts[:, :, None]).sum(axis=1)
            todo &= ~take
        if not todo.any():
            break
    if todo.any():
        raise ValueError(f"{terrain.source}: no level covers level-0 cell "
                         f"({int(ii[todo][0])}, {int(jj[todo][0])})")
    return z, c


# --- the renderer -----------------------------------------------------------------------------

def render_voxel_space(maps: VoxelMaps, view: View, *, sky: np.ndarray, earth: np.ndarray,
                       growth: float = GROWTH, dz_min: float | None = None,
                       out: VoxelFrame | None = None) -> VoxelFrame:
    """One frame of Voxel Space: the view's channel, one sample per pixel (its centre).

    Args:
        maps: voxel_maps of the database.
        view: the channel's view (make_view): eye (world metres), axes, frustum, raster size.
            Its right axis must be horizontal (no roll) and its forward axis not vertical.
        sky, earth: (3,) linear RGB of undrawn pixels above and below the horizon row.
        growth: the step's growth per metre of depth (dz = dz_min + growth z).
        dz_min: smallest step, metres (default: one cell).
        out: a previous frame of the same size whose arrays are reused.

    Returns:
        The frame (linear RGB, range per pixel, samples visited).

    Raises:
        ValueError: a rolled view, a vertical one, or a step that does not advance.
    """
    camera = _camera(maps, view, np.asarray(sky, np.float64), np.asarray(earth, np.float64),
                     growth, maps.spacing_m if dz_min is None else float(dz_min))
    if out is None or out.range_m.shape != (view.height, view.width):
        rgb = np.empty((view.height, view.width, 3), np.float32)
        range_m = np.empty((view.height, view.width), np.float32)
    else:
        rgb, range_m = out.rgb, out.range_m
    samples = _render_columns(maps, camera, SRGB_LUT, rgb, range_m)
    return VoxelFrame(rgb, range_m, int(samples))


def _camera(maps: VoxelMaps, view: View, sky: np.ndarray, earth: np.ndarray, growth: float,
            dz_min: float) -> _Camera:
    right, forward = np.asarray(view.world_to_eye[0]), np.asarray(view.world_to_eye[2])
    if abs(float(right[2])) > 1e-9:
        raise ValueError(f"view: the right axis rises {float(right[2]):.3g}: Voxel Space has "
                         "no roll (nor a yawed channel on a pitched eyepoint)")
    cos_pitch = math.hypot(float(forward[0]), float(forward[1]))
    if cos_pitch < 1e-6:
        raise ValueError("view: looking straight up or down, there is no horizon to shift")
    if not (dz_min > 0.0 and growth >= 0.0):
        raise ValueError(f"step: dz_min {dz_min} must be > 0 and growth {growth} >= 0")
    rx, ry = float(right[0]), float(right[1])  # unit: zero roll keeps right horizontal
    fx, fy = -ry, rx  # forward, horizontal: right turned a quarter anticlockwise
    tan_pitch = float(forward[2]) / cos_pitch
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    horizon = sy_off - sy_scale * tan_pitch
    k = -sy_scale
    rel = np.asarray(view.eye, np.float64) - maps.origin
    above = float(rel[2]) - maps.z_max
    z_start = float(view.near)
    bottom = view.height - 0.5  # the lowest row's centre
    if above > 0.0 and bottom > horizon:
        # Nearer than this even the highest cell projects below the lowest row: nothing to
        # draw (the 0.999 keeps the first sample on the safe side of rounding).
        z_start = max(z_start, 0.999 * k * above / (bottom - horizon))
    return _Camera(float(rel[0]), float(rel[1]), float(rel[2]), fx, fy, rx, ry, sx_scale, sx_off,
                   horizon, k, z_start, float(view.far), dz_min, float(growth),
                   float(sky[0]), float(sky[1]), float(sky[2]),
                   float(earth[0]), float(earth[1]), float(earth[2]))


@njit(cache=True)
def _slab(p: float, d: float, hi: float, t0: float, t1: float) -> tuple[float, float]:
    """[t0, t1] cut to the depths where 0 <= p + t d < hi."""
    if d == 0.0:
        if 0.0 <= p < hi:
            return t0, t1
        return 1.0, 0.0
    ta = -p / d  # guard: d != 0
    tb = (hi - p) / d
    if ta > tb:
        ta, tb = tb, ta
    return max(t0, ta), min(t1, tb)


@njit(cache=True)
def _render_columns(maps, cam, lut, rgb, range_m):
    """Draw every column front to back with a y-buffer; returns the map samples visited."""
    height = maps.height
    colour = maps.rgb
    ny, nx = height.shape
    rows, cols = range_m.shape
    s = maps.spacing_m
    inv_s = 1.0 / s  # guard: spacing_m > 0 (a database's)
    # Nothing on the map is higher than z_max: a sample can reach no higher than this many
    # pixels per unit of 1/z above the horizon (0 when the eye is above every cell).
    rise = cam.k * min(cam.ez - maps.z_max, 0.0)
    samples = 0
    for col in range(cols):
        tx = (col + 0.5 - cam.sx_offset) / cam.sx_scale  # guard: sx_scale != 0 (a channel's)
        dx = cam.fx + tx * cam.rx  # ground metres per metre of depth
        dy = cam.fy + tx * cam.ry
        lateral = math.sqrt(1.0 + tx * tx)  # |(dx, dy)|: forward and right are orthonormal
        z0, z1 = _slab(cam.ex, dx, nx * s, cam.z_start, cam.far / lateral)
        z0, z1 = _slab(cam.ey, dy, ny * s, z0, z1)
        ybuf = rows  # the highest row drawn so far (rows ybuf .. rows - 1 are done)
        z = z0
        while z < z1:
            i = min(max(int((cam.ex + z * dx) * inv_s), 0), nx - 1)
            j = min(max(int((cam.ey + z * dy) * inv_s), 0), ny - 1)
            samples += 1
            inv_z = 1.0 / z  # guard: z >= z_start >= view.near > 0
            drop = cam.ez - height[j, i]
            y = cam.horizon + cam.k * drop * inv_z
            if y <= ybuf - 0.5:
                # Rows whose centre is at or below y, up to the y-buffer: ceil(y - 0.5).
                top = int(math.ceil(y - 0.5)) if y > 0.5 else 0
                horizontal = z * lateral
                rng = math.sqrt(horizontal * horizontal + drop * drop)
                r = lut[colour[j, i, 0]]
                g = lut[colour[j, i, 1]]
                b = lut[colour[j, i, 2]]
                for row in range(top, ybuf):
                    rgb[row, col, 0] = r
                    rgb[row, col, 1] = g
                    rgb[row, col, 2] = b
                    range_m[row, col] = rng
                ybuf = top
                if ybuf == 0:
                    break
            # Farther on, no cell projects above horizon + rise / z: once that is below the
            # y-buffer's row the column is finished.
            if cam.horizon + rise * inv_z > ybuf - 0.5:
                break
            z += cam.dz_min + cam.growth * z
        for row in range(ybuf):
            if row + 0.5 < cam.horizon:
                rgb[row, col, 0] = cam.sky_r
                rgb[row, col, 1] = cam.sky_g
                rgb[row, col, 2] = cam.sky_b
            else:
                rgb[row, col, 0] = cam.earth_r
                rgb[row, col, 1] = cam.earth_g
                rgb[row, col, 2] = cam.earth_b
            range_m[row, col] = np.inf
    return samples
