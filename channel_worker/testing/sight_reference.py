"""Reference line of sight and terrain height, for tests and benches only: written to be
obviously right, not fast, and independent of channel_worker/query (no grid walk, no face
index, no quadratic).

- The terrain: ``reference_ground`` reads the level-0 voxel under a point straight from the page
  table and page arrays (the next coarser level where level 0 lacks the page) and interpolates
  its four float32 corner heights bilinearly; a pattern voxel is solid up to ``max(corners) +
  the last band's top``. A point is inside the terrain when it is over the footprint and at or
  below that.
- A segment is marched in fixed steps (``step_m``, 0.05 m by default) from its start; the first
  step found inside is refined by bisection between it and the step before (60 halvings), so
  the range is exact to rounding unless the segment passes through less than a step of solid
  (a grazing touch), which the march misses: that is its tolerance.
- Polygons: every face of every instance, transformed to world space here, against the segment
  by Möller-Trumbore over the face's fan (no index); faces below the segment's min_opacity
  pass it.
- The nearer wins, with the documented rule (docs/cigi-queries.md): a face behind the terrain
  hit by less than ``margin / max(sin(depression), 1e-3)`` that lies at most the margin below
  the terrain surface wins.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase

#: Bisection halvings after the march: 10 km / 2^60 is far below float64 rounding.
_HALVINGS = 60


def reference_ground(terrain: TerrainDatabase, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ground, solid top) world z under world points (x, y): the bilinear level-0 surface and,
    in a pattern voxel, its box top (else the ground); nan outside the footprint."""
    xs = np.asarray(x, np.float64).reshape(-1) - float(terrain.origin[0])
    ys = np.asarray(y, np.float64).reshape(-1) - float(terrain.origin[1])
    ground = np.full(xs.shape, np.nan)
    top = np.full(xs.shape, np.nan)
    tops = np.array([float(p.top_m[-1]) for p in terrain.patterns] or [0.0])
    _ground_kernel(*_arrays(terrain), tops, xs, ys, ground, top)  # type: ignore[call-arg]
    return ground + float(terrain.origin[2]), top + float(terrain.origin[2])


def reference_sight(database: Database, p0: np.ndarray, p1: np.ndarray, min_opacity: np.ndarray, *,
                    step_m: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(hit (n,) bool, range_m (n,) metres or nan, from_face (n,) bool) of each segment p0 -> p1.

    Raises:
        ValueError: step_m not a finite length > 0.
    """
    if not (math.isfinite(step_m) and step_m > 0.0):
        raise ValueError(f"step_m: {step_m!r} is not a finite length > 0")
    a = np.asarray(p0, np.float64).reshape(-1, 3)
    b = np.asarray(p1, np.float64).reshape(-1, 3)
    opacity = np.asarray(min_opacity, np.float64).reshape(-1)
    terrain = database.terrain
    n = a.shape[0]
    t_hit = np.full(n, -1.0)
    if terrain is not None:
        tops = np.array([float(p.top_m[-1]) for p in terrain.patterns] or [0.0])
        origin = np.asarray(terrain.origin, np.float64)
        _march_kernel(*_arrays(terrain), tops, a - origin, b - origin, float(step_m), t_hit)  # type: ignore[call-arg]
    # Every face of every instance, in world space (no index).
    tris: list[np.ndarray] = []
    face_opacity: list[float] = []
    table = database.faces
    for inst, m in enumerate(database.instance_model):
        rot, pos = database.instance_rotation[inst], database.instance_position[inst]
        corner = int(table.corner_base[m])
        for f in range(int(table.face_base[m]), int(table.face_base[m] + table.face_count[m])):
            size = int(table.face_size[f])
            world = table.corner_xyz[corner:corner + size] @ rot.T + pos
            corner += size
            for k in range(1, size - 1):
                tris.append(np.stack([world[0], world[k], world[k + 1]]))
                face_opacity.append(float(table.opacity[f]))
    tri = np.array(tris).reshape(-1, 3, 3)
    tri_opacity = np.array(face_opacity)
    margin = float(database.terrain_margin_m)
    hit = np.zeros(n, np.bool_)
    range_m = np.full(n, np.nan)
    from_face = np.zeros(n, np.bool_)
    for s in range(n):
        d = b[s] - a[s]
        length = float(np.linalg.norm(d))
        unit = d / length if length > 0.0 else np.zeros(3)  # guard: a zero segment meets no face
        face_t = _nearest_triangle(tri[tri_opacity >= opacity[s]], a[s], unit, length)
        tt = t_hit[s]
        take_face = False
        if face_t >= 0.0:
            if tt < 0.0 or face_t <= tt:
                take_face = True
            elif face_t <= tt + margin / max(-unit[2], 1e-3):
                q = a[s] + face_t * unit
                ground = reference_ground(terrain, q[:1], q[1:2])[0][0] if terrain is not None else np.nan
                take_face = not np.isfinite(ground) or q[2] >= ground - margin
        if take_face:
            hit[s], range_m[s], from_face[s] = True, face_t, True
        elif tt >= 0.0:
            hit[s], range_m[s] = True, tt
    return hit, range_m, from_face


def _arrays(terrain: TerrainDatabase) -> tuple:
    return (float(terrain.spacing_m), int(terrain.nx), int(terrain.ny), int(terrain.levels),
            int(terrain.page_size), np.asarray(terrain.pages_x, np.int64), np.asarray(terrain.pages_y, np.int64),
            np.asarray(terrain.table_offset, np.int64), np.asarray(terrain.page_table, np.int64),
            np.asarray(terrain.z), np.asarray(terrain.pattern))


def _nearest_triangle(tri: np.ndarray, o: np.ndarray, d: np.ndarray, length: float) -> float:
    """Möller-Trumbore on every triangle at once: the nearest t in [0, length], or -1."""
    if tri.shape[0] == 0:
        return -1.0
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = det != 0.0
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)  # guard: det != 0 where used
    s = o - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    good = ok & (u >= 0) & (u <= 1) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= length)
    return float(t[good].min()) if good.any() else -1.0


@njit(cache=True)
def _solid_top(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern, tops, x, y):
    """(over, ground, solid top) at origin-relative (x, y), by direct look-up."""
    if not (0.0 <= x <= nx * spacing and 0.0 <= y <= ny * spacing):
        return False, 0.0, 0.0
    i = min(int(math.floor(x / spacing)), nx - 1)  # guard: spacing > 0 (a loaded database's)
    j = min(int(math.floor(y / spacing)), ny - 1)
    for level in range(levels):
        ci, cj = i >> level, j >> level
        px, py = ci // page, cj // page  # guard: page_size >= 1
        if px >= pages_x[level] or py >= pages_y[level]:
            continue
        index = table[offset[level] + py * pages_x[level] + px]
        if index < 0:
            continue
        vx, vy = ci - px * page, cj - py * page
        size = spacing * (1 << level)
        u = min(max((x - ci * size) / size, 0.0), 1.0)  # guard: size > 0
        v = min(max((y - cj * size) / size, 0.0), 1.0)
        c = z[index, vy, vx]
        ground = (np.float64(c[0]) * (1 - u) * (1 - v) + np.float64(c[1]) * u * (1 - v)
                  + np.float64(c[2]) * (1 - u) * v + np.float64(c[3]) * u * v)
        k = pattern[index, vy, vx]
        top = ground
        if k >= 1:
            top = max(ground, np.float64(c.max()) + tops[k - 1])
        return True, ground, top
    return False, 0.0, 0.0


@njit(cache=True)
def _ground_kernel(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern, tops,
                   xs, ys, ground, top):
    for n in range(xs.shape[0]):
        over, g, t = _solid_top(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern,
                                tops, xs[n], ys[n])
        if over:
            ground[n] = g
            top[n] = t


@njit(cache=True)
def _inside(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern, tops, a, d, t):
    over, _g, top = _solid_top(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern,
                               tops, a[0] + t * d[0], a[1] + t * d[1])
    return over and a[2] + t * d[2] <= top


@njit(cache=True)
def _march_kernel(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern, tops,
                  a, b, step, t_hit):
    for s in range(a.shape[0]):
        d = b[s] - a[s]
        length = math.sqrt((d * d).sum())
        if length > 0.0:
            d = d / length  # guard: length > 0
        steps = int(math.ceil(length / step))  # guard: step > 0 (checked by reference_sight)
        prev = 0.0
        for k in range(steps + 1):
            t = min(k * step, length)
            if _inside(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern, tops,
                       a[s], d, t):
                if k == 0:
                    t_hit[s] = 0.0
                    break
                lo, hi = prev, t
                for _ in range(_HALVINGS):
                    mid = 0.5 * (lo + hi)
                    if _inside(spacing, nx, ny, levels, page, pages_x, pages_y, offset, table, z, pattern,
                               tops, a[s], d, mid):
                        hi = mid
                    else:
                        lo = mid
                t_hit[s] = hi
                break
            prev = t
