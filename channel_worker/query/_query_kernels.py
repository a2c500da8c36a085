"""The numba kernels of the CIGI queries (heights.py, sight.py): the level-0 terrain surface and
the world-space faces, read through the groups _index.py prepares once per database.

Coordinates: terrain work is relative to the terrain's origin (``p - origin``, one float64
difference before anything else, so a database 1000 km from the world origin loses nothing);
face work is relative to the segment's start or the query point (differences of nearby float64
numbers again). The surface is docs/cigi-queries.md's: level 0 bilinear in each voxel (a
coarser level's voxel restricted to the cell where level 0 lacks the page, the database's own
rule), pattern voxels as boxes up to ``max(corner heights) + top of the last band``, the
terrain a solid with vertical walls at steps and at the database edge
(channel_worker/testing/terrain_reference.py describes the same surface).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

#: Material codes (docs/cigi-queries.md). A pattern k (1-based, patterns[k - 1]) is
#: MATERIAL_GROUND + k; a polygon of model m (scene-file order) is MATERIAL_POLYGON + m.
MATERIAL_NONE = 0
MATERIAL_GROUND = 1
MATERIAL_POLYGON = 100

#: A face whose unit normal's vertical component is below this is vertical for a height query
#: (a wall has no height at a point; its edge-on projection has no area to be inside).
VERTICAL_NZ = 1e-6

#: Floor of the sine of a segment's depression where the polygon margin is turned into range
#: (the renderer's terrain push-back, docs/terrain.md section 4: the same floor).
MIN_DEPRESSION_SINE = 1e-3

# Kinds of terrain hit.
_MISS = 0
_GROUND = 1
_BAND = 2


class TerrainArrays(NamedTuple):
    """The terrain as the kernels read it (an empty one when the scene has none)."""

    present: bool
    origin: np.ndarray  # (3,) float64 world position of voxel (0, 0) at height 0
    spacing: float  # level-0 voxel width, metres (> 0, checked by _index.py)
    nx: int
    ny: int
    levels: int
    page_size: int
    pages_x: np.ndarray  # (levels,) int64
    pages_y: np.ndarray
    table_offset: np.ndarray
    page_table: np.ndarray  # (T,) int64
    z: np.ndarray  # (N, P, P, 4) float32 corner heights above origin[2]
    rgb: np.ndarray  # (N, P, P, 4, 3) uint8 sRGB
    pattern: np.ndarray  # (N, P, P) uint8
    band_top: np.ndarray  # (K, B) float64 band tops above the ground, padded with the last
    band_count: np.ndarray  # (K,) int64
    band_rgb: np.ndarray  # (K, B, 3) float64 linear
    srgb: np.ndarray  # (256,) float64 sRGB -> linear
    z_top: float  # nothing of the terrain is above this, metres above origin[2]
    margin: float  # the scene's terrain.polygon_margin_m


class FaceGrid(NamedTuple):
    """Every instance's faces in world space, with a uniform 2-D grid of their xy bounding boxes."""

    corner_start: np.ndarray  # (F + 1,) int64 into corner
    corner: np.ndarray  # (C, 3) float64 world metres, each face's vertices in order
    normal: np.ndarray  # (F, 3) float64 world unit front normal
    opacity: np.ndarray  # (F,) float64
    material: np.ndarray  # (F,) int64
    colour: np.ndarray  # (F, 3) float64 linear
    x0: float  # world xy of the grid's south-west corner
    y0: float
    cell: float  # cell width, metres (> 0)
    gx: int  # cells east, north (>= 1)
    gy: int
    z_lo: float  # every face's z lies in [z_lo, z_hi]
    z_hi: float
    cell_start: np.ndarray  # (gx gy + 1,) int64 into cell_face; cell (i, j) is j gx + i
    cell_face: np.ndarray  # (E,) int64 face indices


# ----------------------------------------------------------------------------- terrain


@njit(cache=True)
def bilinear(c00, c10, c01, c11, u, v):
    """Bilinear interpolation of corner values (sw, se, nw, ne) at local (u, v) in [0, 1]^2."""
    return c00 * (1.0 - u) * (1.0 - v) + c10 * u * (1.0 - v) + c01 * (1.0 - u) * v + c11 * u * v


@njit(cache=True)
def _locate(t, i, j):
    """The finest stored voxel covering level-0 cell (i, j): (page or -1, vx, vy, u0, v0, w),
    the cell being the sub-square [u0, u0 + w] x [v0, v0 + w] of the voxel (w = 1 at level 0).
    A missing level-0 page falls back to the next coarser level (docs/terrain-database.md)."""
    p = t.page_size
    for level in range(t.levels):
        ci = i >> level
        cj = j >> level
        px = ci // p  # guard: page_size >= 1 (checked by _index.py)
        py = cj // p
        if px < t.pages_x[level] and py < t.pages_y[level]:
            page = t.page_table[t.table_offset[level] + py * t.pages_x[level] + px]
            if page >= 0:
                w = 1.0 / (1 << level)  # guard: 1 << level >= 1
                return page, ci - px * p, cj - py * p, (i - (ci << level)) * w, (j - (cj << level)) * w, w
    return -1, 0, 0, 0.0, 0.0, 1.0


@njit(cache=True)
def _cell(t, i, j):
    """Cell (i, j)'s corner heights restricted to it (sw, se, nw, ne, metres above origin[2]),
    its pattern entry k (0 none, -1 a cell no level covers) and, for k >= 1, its box top."""
    page, vx, vy, u0, v0, w = _locate(t, i, j)
    if page < 0:
        return 0.0, 0.0, 0.0, 0.0, -1, 0.0
    z00 = np.float64(t.z[page, vy, vx, 0])
    z10 = np.float64(t.z[page, vy, vx, 1])
    z01 = np.float64(t.z[page, vy, vx, 2])
    z11 = np.float64(t.z[page, vy, vx, 3])
    h00 = bilinear(z00, z10, z01, z11, u0, v0)
    h10 = bilinear(z00, z10, z01, z11, u0 + w, v0)
    h01 = bilinear(z00, z10, z01, z11, u0, v0 + w)
    h11 = bilinear(z00, z10, z01, z11, u0 + w, v0 + w)
    k = np.int64(t.pattern[page, vy, vx])
    top = 0.0
    if k >= 1:
        top = max(max(z00, z10), max(z01, z11)) + t.band_top[k - 1, t.band_count[k - 1] - 1]
    return h00, h10, h01, h11, k, top


@njit(cache=True)
def _ground_normal(t, h00, h10, h01, h11, u, v):
    """Unit upward normal of the bilinear surface at local (u, v): (-dH/dx, -dH/dy, 1), scaled.
    H = h00 + a u + b v + c u v, so dH/dx = (a + c v) / spacing and dH/dy = (b + c u) / spacing."""
    c = h00 - h10 - h01 + h11
    gx = (h10 - h00 + c * v) / t.spacing  # guard: spacing > 0 (checked by _index.py)
    gy = (h01 - h00 + c * u) / t.spacing
    norm = math.sqrt(gx * gx + gy * gy + 1.0)  # >= 1: no zero division below
    return -gx / norm, -gy / norm, 1.0 / norm


@njit(cache=True)
def _ground_colour(t, i, j, u, v, out):
    """Linear RGB at local (u, v) of level-0 cell (i, j): the stored voxel's corners, bilinear."""
    page, vx, vy, u0, v0, w = _locate(t, i, j)
    if page < 0:
        return
    for c in range(3):
        out[c] = bilinear(t.srgb[t.rgb[page, vy, vx, 0, c]], t.srgb[t.rgb[page, vy, vx, 1, c]],
                          t.srgb[t.rgb[page, vy, vx, 2, c]], t.srgb[t.rgb[page, vy, vx, 3, c]],
                          u0 + u * w, v0 + v * w)


@njit(cache=True)
def _band(t, k, above_ground):
    """Band of pattern k seen at a height above the ground: top_m[b - 1] < h <= top_m[b]."""
    n = t.band_count[k - 1]
    for b in range(n):
        if above_ground <= t.band_top[k - 1, b]:
            return b
    return n - 1  # above the last top: the ground is below the voxel's highest corner


@njit(cache=True)
def _terrain_point(t, rx, ry):
    """The terrain over origin-relative (rx, ry): (over, i, j, u, v, h00, h10, h01, h11, k, top).
    The footprint is closed: its north and east edges belong to the last voxels."""
    s = t.spacing
    if not (t.present and 0.0 <= rx <= t.nx * s and 0.0 <= ry <= t.ny * s):
        return False, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1, 0.0
    i = min(max(int(math.floor(rx / s)), 0), t.nx - 1)  # guard: s > 0
    j = min(max(int(math.floor(ry / s)), 0), t.ny - 1)
    h00, h10, h01, h11, k, top = _cell(t, i, j)
    u = min(max((rx - i * s) / s, 0.0), 1.0)
    v = min(max((ry - j * s) / s, 0.0), 1.0)
    return k >= 0, i, j, u, v, h00, h10, h01, h11, k, top


@njit(cache=True)
def first_root(f0, f1, f2, length):
    """Smallest tau in [0, length] with f0 + f1 tau + f2 tau^2 = 0, given f0 > 0; -1 if none.

    Cancellation-free: q = -(f1 + sign(f1) sqrt(D)) / 2, roots q / f2 and f0 / q (Numerical
    Recipes 5.6), so a nearly linear f (tiny f2) keeps its near root f0 / q exact.
    """
    if f2 == 0.0:
        if f1 < 0.0:
            tau = -f0 / f1  # guard: f1 < 0
            if tau <= length:
                return tau
        return -1.0
    disc = f1 * f1 - 4.0 * f2 * f0
    if disc < 0.0:
        return -1.0
    root = math.sqrt(disc)
    q = -0.5 * (f1 + root) if f1 >= 0.0 else -0.5 * (f1 - root)
    if q == 0.0:
        return -1.0  # guard of f0 / q: only if f1 = disc = 0, impossible with f0 > 0, f2 != 0
    best = -1.0
    for tau in (q / f2, f0 / q):  # guards: f2 != 0 in this branch, q != 0 above
        if 0.0 <= tau <= length and (best < 0.0 or tau < best):
            best = tau
    return best


@njit(cache=True)
def _clip_slab(p, d, lo, hi, t0, t1, axis, entry):
    """[t0, t1] cut to where lo <= p + t d <= hi; entry is the axis whose boundary set t0."""
    if d == 0.0:
        if lo <= p <= hi:
            return t0, t1, entry
        return 1.0, 0.0, entry
    ta = (lo - p) / d  # guard: d != 0
    tb = (hi - p) / d
    if ta > tb:
        ta, tb = tb, ta
    if ta > t0:
        t0 = ta
        entry = axis
    return t0, min(t1, tb), entry


@njit(cache=True)
def _crossing(p, d, i, s):
    """t at which p + t d leaves cell i (width s) along one axis; inf when d = 0 (no crossing)."""
    if d > 0.0:
        return ((i + 1) * s - p) / d  # guard: d > 0
    if d < 0.0:
        return (i * s - p) / d  # guard: d < 0
    return np.inf


@njit(cache=True)
def trace_terrain(t, px, py, pz, dx, dy, dz, length, normal, rgb):
    """The first point of the terrain solid on p + tau d, tau in [0, length] (p origin-relative,
    d unit or zero): Amanatides & Woo's grid walk over the level-0 cells the ground track
    crosses, the bilinear surface solved exactly (a quadratic in tau) in each.

    Returns (tau or -1, material); writes the unit normal and linear colour of the hit.
    """
    s = t.spacing
    if not t.present:
        return -1.0, MATERIAL_NONE
    t0, t1, entry = _clip_slab(px, dx, 0.0, t.nx * s, 0.0, length, 0, -1)
    t0, t1, entry = _clip_slab(py, dy, 0.0, t.ny * s, t0, t1, 1, entry)
    t0, t1, entry = _clip_slab(pz, dz, -np.inf, t.z_top, t0, t1, 2, entry)
    if t0 > t1:
        return -1.0, MATERIAL_NONE
    i = min(max(int(math.floor((px + t0 * dx) / s)), 0), t.nx - 1)  # guard: s > 0
    j = min(max(int(math.floor((py + t0 * dy) / s)), 0), t.ny - 1)
    step_i = 1 if dx > 0.0 else -1
    step_j = 1 if dy > 0.0 else -1
    next_i = _crossing(px, dx, i, s)
    next_j = _crossing(py, dy, j, s)
    ta = t0
    while True:
        tb = min(min(next_i, next_j), t1)
        seg = max(tb - ta, 0.0)
        h00, h10, h01, h11, k, top = _cell(t, i, j)
        ua = min(max((px + ta * dx - i * s) / s, 0.0), 1.0)
        va = min(max((py + ta * dy - j * s) / s, 0.0), 1.0)
        za = pz + ta * dz
        ground = bilinear(h00, h10, h01, h11, ua, va)
        tau = -1.0
        kind = _MISS
        if k >= 1:
            if za <= top:
                tau = 0.0  # enters inside the box (its side) or below its ground (a step)
                kind = _GROUND if za <= ground else _BAND
            elif dz < 0.0:
                reach = (top - za) / dz  # guard: dz < 0; > 0 since za > top
                if reach <= seg:
                    tau = reach
                    kind = _BAND
                    normal[0], normal[1], normal[2] = 0.0, 0.0, 1.0  # the box top
        elif k == 0:
            f0 = za - ground
            if f0 <= 0.0:
                tau = 0.0  # enters inside the solid: a wall (or the start is underground)
                kind = _GROUND
            else:
                # H(u, v) = h00 + a u + b v + c u v along u = ua + dx / s tau, v = va + dy / s tau.
                a = h10 - h00
                b = h01 - h00
                c = h00 - h10 - h01 + h11
                du = dx / s
                dv = dy / s
                f1 = dz - (a + c * va) * du - (b + c * ua) * dv
                f2 = -c * du * dv
                tau = first_root(f0, f1, f2, seg)
                if tau >= 0.0:
                    kind = _GROUND
                    u = min(max(ua + du * tau, 0.0), 1.0)
                    v = min(max(va + dv * tau, 0.0), 1.0)
                    normal[0], normal[1], normal[2] = _ground_normal(t, h00, h10, h01, h11, u, v)
                    _ground_colour(t, i, j, u, v, rgb)
                    return ta + tau, MATERIAL_GROUND
        if tau >= 0.0:
            if tau == 0.0:
                # Entered inside: a vertical wall on the side crossed, or the start itself.
                if entry == 0:
                    normal[0], normal[1], normal[2] = -float(step_i), 0.0, 0.0
                elif entry == 1:
                    normal[0], normal[1], normal[2] = 0.0, -float(step_j), 0.0
                elif kind == _GROUND:
                    normal[0], normal[1], normal[2] = _ground_normal(t, h00, h10, h01, h11, ua, va)
                else:
                    normal[0], normal[1], normal[2] = 0.0, 0.0, 1.0
            if kind == _BAND:
                b = _band(t, k, za + tau * dz - ground) if tau == 0.0 else t.band_count[k - 1] - 1
                for c3 in range(3):
                    rgb[c3] = t.band_rgb[k - 1, b, c3]
                return ta + tau, MATERIAL_GROUND + k
            _ground_colour(t, i, j, ua, va, rgb)
            return ta + tau, MATERIAL_GROUND
        if tb >= t1:
            return -1.0, MATERIAL_NONE
        # Across the nearer boundary (x first on a tie: y follows through a zero-length
        # segment, so no cell is skipped).
        if next_i <= next_j:
            i += step_i
            ta = max(ta, next_i)
            entry = 0
            if i < 0 or i >= t.nx:
                return -1.0, MATERIAL_NONE
            next_i = _crossing(px, dx, i, s)
        else:
            j += step_j
            ta = max(ta, next_j)
            entry = 1
            if j < 0 or j >= t.ny:
                return -1.0, MATERIAL_NONE
            next_j = _crossing(py, dy, j, s)


# ----------------------------------------------------------------------------- faces


@njit(cache=True)
def _vertical_hit(f, face, x, y):
    """World z where the vertical line through (x, y) meets a non-vertical face, or nan.
    The convex face as a fan of triangles from its first vertex; 2-D barycentrics, edges in."""
    a = f.corner_start[face]
    n = f.corner_start[face + 1] - a
    x0, y0, z0 = f.corner[a, 0], f.corner[a, 1], f.corner[a, 2]
    qx = x - x0
    qy = y - y0
    for m in range(1, n - 1):
        e1x, e1y, e1z = f.corner[a + m, 0] - x0, f.corner[a + m, 1] - y0, f.corner[a + m, 2] - z0
        e2x, e2y, e2z = f.corner[a + m + 1, 0] - x0, f.corner[a + m + 1, 1] - y0, f.corner[a + m + 1, 2] - z0
        det = e1x * e2y - e1y * e2x
        if det == 0.0:
            continue  # a sliver with no area seen from above
        b1 = (qx * e2y - qy * e2x) / det  # guard: det != 0
        b2 = (e1x * qy - e1y * qx) / det
        if b1 >= 0.0 and b2 >= 0.0 and b1 + b2 <= 1.0:
            return z0 + b1 * e1z + b2 * e2z
    return np.nan


@njit(cache=True)
def _ray_face(f, face, ox, oy, oz, dx, dy, dz, t_max):
    """Möller-Trumbore over the face's fan: the smallest t in [0, t_max] where o + t d meets it,
    or -1. Vertex positions are taken relative to o first (float64, nearby numbers)."""
    a = f.corner_start[face]
    n = f.corner_start[face + 1] - a
    vx, vy, vz = f.corner[a, 0] - ox, f.corner[a, 1] - oy, f.corner[a, 2] - oz
    best = -1.0
    for m in range(1, n - 1):
        e1x, e1y, e1z = f.corner[a + m, 0] - ox - vx, f.corner[a + m, 1] - oy - vy, f.corner[a + m, 2] - oz - vz
        e2x = f.corner[a + m + 1, 0] - ox - vx
        e2y = f.corner[a + m + 1, 1] - oy - vy
        e2z = f.corner[a + m + 1, 2] - oz - vz
        qx = dy * e2z - dz * e2y  # d x e2
        qy = dz * e2x - dx * e2z
        qz = dx * e2y - dy * e2x
        det = e1x * qx + e1y * qy + e1z * qz
        if det == 0.0:
            continue  # the segment lies in the triangle's plane (or d = 0): no single crossing
        inv = 1.0 / det  # guard: det != 0
        sx, sy, sz = -vx, -vy, -vz  # o - v0
        u = (sx * qx + sy * qy + sz * qz) * inv
        if u < 0.0 or u > 1.0:
            continue
        rx = sy * e1z - sz * e1y  # s x e1
        ry = sz * e1x - sx * e1z
        rz = sx * e1y - sy * e1x
        v = (dx * rx + dy * ry + dz * rz) * inv
        if v < 0.0 or u + v > 1.0:
            continue
        tt = (e2x * rx + e2y * ry + e2z * rz) * inv
        if 0.0 <= tt <= t_max and (best < 0.0 or tt < best):
            best = tt
    return best


@njit(cache=True)
def trace_faces(f, ox, oy, oz, dx, dy, dz, t_max, min_opacity, stamp, key):
    """The nearest face at least min_opacity opaque on o + t d, t in [0, t_max]: the face grid's
    cells along the ground track walked in order (Amanatides & Woo), each face tested once
    (stamp[face] = key marks it), stopping at the first cell whose exit lies beyond the best hit.

    Returns (t or -1, face or -1).
    """
    if f.cell_face.shape[0] == 0:
        return -1.0, -1
    c = f.cell
    px = ox - f.x0
    py = oy - f.y0
    t0, t1, entry = _clip_slab(px, dx, 0.0, f.gx * c, 0.0, t_max, 0, -1)
    t0, t1, entry = _clip_slab(py, dy, 0.0, f.gy * c, t0, t1, 1, entry)
    t0, t1, entry = _clip_slab(oz, dz, f.z_lo, f.z_hi, t0, t1, 2, entry)
    if t0 > t1:
        return -1.0, -1
    i = min(max(int(math.floor((px + t0 * dx) / c)), 0), f.gx - 1)  # guard: cell > 0
    j = min(max(int(math.floor((py + t0 * dy) / c)), 0), f.gy - 1)
    step_i = 1 if dx > 0.0 else -1
    step_j = 1 if dy > 0.0 else -1
    next_i = _crossing(px, dx, i, c)
    next_j = _crossing(py, dy, j, c)
    best = -1.0
    best_face = -1
    while True:
        cell = j * f.gx + i
        for e in range(f.cell_start[cell], f.cell_start[cell + 1]):
            face = f.cell_face[e]
            if stamp[face] == key:
                continue
            stamp[face] = key
            if f.opacity[face] < min_opacity:
                continue
            tt = _ray_face(f, face, ox, oy, oz, dx, dy, dz, t_max)
            if tt >= 0.0 and (best < 0.0 or tt < best):
                best = tt
                best_face = face
        exit_t = min(min(next_i, next_j), t1)
        if (best >= 0.0 and best <= exit_t) or exit_t >= t1:
            return best, best_face
        if next_i <= next_j:
            i += step_i
            if i < 0 or i >= f.gx:
                return best, best_face
            next_i = _crossing(px, dx, i, c)
        else:
            j += step_j
            if j < 0 or j >= f.gy:
                return best, best_face
            next_j = _crossing(py, dy, j, c)


# ----------------------------------------------------------------------------- the queries


@njit(cache=True)
def heights_kernel(t, f, x, y, z_max, min_opacity, valid, height, normal, material):
    """Height of terrain at every (x[n], y[n]) at or below z_max[n] (heights.py documents it)."""
    for n in range(x.shape[0]):
        zc = z_max[n]
        best = -np.inf
        found = False
        # The terrain: its pattern top, or else its ground, whichever is at or below z_max.
        rx = x[n] - t.origin[0]
        ry = y[n] - t.origin[1]
        over, _i, _j, u, v, h00, h10, h01, h11, k, top = _terrain_point(t, rx, ry)
        if over:
            ground = bilinear(h00, h10, h01, h11, u, v)
            if k >= 1 and top + t.origin[2] <= zc:
                best = top + t.origin[2]
                normal[n, 0], normal[n, 1], normal[n, 2] = 0.0, 0.0, 1.0
                material[n] = MATERIAL_GROUND + k
                found = True
            elif ground + t.origin[2] <= zc:
                best = ground + t.origin[2]
                normal[n, 0], normal[n, 1], normal[n, 2] = _ground_normal(t, h00, h10, h01, h11, u, v)
                material[n] = MATERIAL_GROUND
                found = True
        # The faces over the point's grid cell; one within the margin below the terrain wins
        # (the renderer draws a runway on its pad over the terrain, docs/terrain.md section 4).
        gi = int(math.floor((x[n] - f.x0) / f.cell))  # guard: cell > 0
        gj = int(math.floor((y[n] - f.y0) / f.cell))
        if f.cell_face.shape[0] > 0 and 0 <= gi <= f.gx and 0 <= gj <= f.gy:
            cell = min(gj, f.gy - 1) * f.gx + min(gi, f.gx - 1)
            floor_z = best - t.margin if found else -np.inf
            face_z = -np.inf
            face_id = -1
            for e in range(f.cell_start[cell], f.cell_start[cell + 1]):
                face = f.cell_face[e]
                if f.opacity[face] < min_opacity or abs(f.normal[face, 2]) < VERTICAL_NZ:
                    continue
                z = _vertical_hit(f, face, x[n], y[n])
                if z == z and z <= zc and z >= floor_z and z > face_z:  # z == z: not nan
                    face_z = z
                    face_id = face
            if face_id >= 0:
                best = face_z
                sign = 1.0 if f.normal[face_id, 2] > 0.0 else -1.0  # pointing up
                for c3 in range(3):
                    normal[n, c3] = sign * f.normal[face_id, c3]
                material[n] = f.material[face_id]
                found = True
        valid[n] = found
        height[n] = best if found else np.nan
        if not found:
            material[n] = MATERIAL_NONE
            normal[n, 0], normal[n, 1], normal[n, 2] = 0.0, 0.0, 0.0


@njit(cache=True)
def sight_kernel(t, f, p0, p1, min_opacity, hit, range_m, point, normal, material, rgb, alpha):
    """Line of sight of every segment p0[n] -> p1[n] (sight.py documents it)."""
    stamp = np.full(f.opacity.shape[0], -1, np.int64)
    tn = np.zeros(3)
    tc = np.zeros(3)
    for n in range(p0.shape[0]):
        # The segment, differences first (float64, before anything is added to them).
        ex = p1[n, 0] - p0[n, 0]
        ey = p1[n, 1] - p0[n, 1]
        ez = p1[n, 2] - p0[n, 2]
        length = math.sqrt(ex * ex + ey * ey + ez * ez)
        dx = dy = dz = 0.0
        if length > 0.0:
            dx, dy, dz = ex / length, ey / length, ez / length  # guard: length > 0
        rx = p0[n, 0] - t.origin[0]
        ry = p0[n, 1] - t.origin[1]
        rz = p0[n, 2] - t.origin[2]
        tt, tmat = trace_terrain(t, rx, ry, rz, dx, dy, dz, length, tn, tc)
        # Polygons up to the terrain hit pushed back by the margin (as the renderer does).
        reach = length
        if tt >= 0.0:
            reach = min(length, tt + t.margin / max(-dz, MIN_DEPRESSION_SINE))  # guard: floor > 0
        ft, face = trace_faces(f, p0[n, 0], p0[n, 1], p0[n, 2], dx, dy, dz, reach, min_opacity[n], stamp, n)
        take_face = False
        if face >= 0:
            if tt < 0.0 or ft <= tt:
                take_face = True
            else:
                # Behind the terrain hit but within the push-back: it wins only if it lies on
                # the terrain (at most the margin below the surface under it).
                over, _i, _j, u, v, h00, h10, h01, h11, _k, _top = _terrain_point(
                    t, rx + ft * dx, ry + ft * dy)
                take_face = (not over) or (rz + ft * dz >= bilinear(h00, h10, h01, h11, u, v) - t.margin)
        if take_face:
            hit[n] = True
            range_m[n] = ft
            sign = -1.0 if (f.normal[face, 0] * dx + f.normal[face, 1] * dy + f.normal[face, 2] * dz) > 0.0 else 1.0
            for c3 in range(3):
                normal[n, c3] = sign * f.normal[face, c3]  # facing the segment's start
                rgb[n, c3] = f.colour[face, c3]
            material[n] = f.material[face]
            alpha[n] = f.opacity[face]
            rng = ft
        elif tt >= 0.0:
            hit[n] = True
            range_m[n] = tt
            for c3 in range(3):
                normal[n, c3] = tn[c3]
                rgb[n, c3] = tc[c3]
            material[n] = tmat
            alpha[n] = 1.0
            rng = tt
        else:
            hit[n] = False
            range_m[n] = np.nan
            material[n] = MATERIAL_NONE
            alpha[n] = 0.0
            for c3 in range(3):
                normal[n, c3] = 0.0
                rgb[n, c3] = 0.0
            for c3 in range(3):
                point[n, c3] = np.nan
            continue
        point[n, 0] = p0[n, 0] + rng * dx
        point[n, 1] = p0[n, 1] + rng * dy
        point[n, 2] = p0[n, 2] + rng * dz
