"""What the query kernels read of a database, prepared once per Database object and kept while
it lives: the terrain's arrays as a TerrainArrays, every instance's faces transformed to world
space with a uniform 2-D grid over their xy bounding boxes (a FaceGrid), so that a height
query tests the faces of one cell and a line of sight those of the cells its ground track
crosses (Amanatides & Woo's walk, _query_kernels.trace_faces).
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase, pattern_bands

from ._query_kernels import MATERIAL_GROUND, MATERIAL_POLYGON, FaceGrid, TerrainArrays

#: Cells of the face grid along its longer side, at most. The bundled scene (1859 faces over
#: 18 km, most within the 2.6 km airfield) gets 70 m cells: about one building per cell.
GRID_CELLS = 256

#: The grid's bounds are the faces' bounds widened by this (metres), so a segment that ends on
#: a face (its range computed two ways, rounded differently) is not clipped off it.
BOUNDS_PAD_M = 1e-3

#: Smallest face-grid cell, metres: a scene of a few small models gets no finer grid than this.
MIN_CELL_M = 1.0

_SRGB = np.arange(256, dtype=np.float64) / 255.0
#: sRGB uint8 -> linear, IEC 61966-2-1.
SRGB_TO_LINEAR = np.where(_SRGB <= 0.04045, _SRGB / 12.92, ((_SRGB + 0.055) / 1.055) ** 2.4)


class Prepared(NamedTuple):
    """A database as the query kernels read it."""

    terrain: TerrainArrays
    faces: FaceGrid


_CACHE: dict[int, tuple[weakref.ref, Prepared]] = {}
_LOCK = threading.RLock()  # re-entrant: a weakref callback may run while it is held


def prepared(database: Database) -> Prepared:
    """The query kernels' view of a database, built on first use and cached while the Database
    object lives (keyed on its identity: a Database is immutable, and its arrays are large).

    Raises:
        ValueError: a terrain the kernels cannot walk (named field and value).
    """
    key = id(database)
    with _LOCK:
        entry = _CACHE.get(key)
        if entry is not None and entry[0]() is database:
            return entry[1]
    value = Prepared(terrain=_terrain_arrays(database.terrain, database.terrain_margin_m),
                     faces=_face_grid(database))
    with _LOCK:
        _CACHE[key] = (weakref.ref(database, _forget(key)), value)
    return value


def _forget(key: int) -> Callable[[weakref.ref], None]:
    """The weakref callback that drops a dead database's entry (its id may be reused)."""
    def drop(_ref: weakref.ref) -> None:
        with _LOCK:
            entry = _CACHE.get(key)
            if entry is not None and entry[0] is _ref:
                del _CACHE[key]
    return drop


def _terrain_arrays(terrain: TerrainDatabase | None, margin: float) -> TerrainArrays:
    if terrain is None:
        return TerrainArrays(
            present=False, origin=np.zeros(3), spacing=1.0, nx=1, ny=1, levels=1, page_size=1,
            pages_x=np.ones(1, np.int64), pages_y=np.ones(1, np.int64), table_offset=np.zeros(1, np.int64),
            page_table=np.zeros(1, np.int64), z=np.zeros((1, 1, 1, 4), np.float32),
            rgb=np.zeros((1, 1, 1, 4, 3), np.uint8), pattern=np.zeros((1, 1, 1), np.uint8),
            band_top=np.zeros((1, 1)), band_count=np.ones(1, np.int64), band_rgb=np.zeros((1, 1, 3)),
            srgb=SRGB_TO_LINEAR, z_top=-np.inf, margin=float(margin))
    where = terrain.source or "terrain"
    if not (math.isfinite(terrain.spacing_m) and terrain.spacing_m > 0.0):
        raise ValueError(f"{where}: spacing_m: {terrain.spacing_m!r} is not a finite width > 0")
    if terrain.page_size < 1 or terrain.levels < 1:
        raise ValueError(f"{where}: page_size {terrain.page_size!r} and levels {terrain.levels!r} must be >= 1")
    if len(terrain.patterns) > MATERIAL_POLYGON - MATERIAL_GROUND - 1:
        raise ValueError(f"{where}: patterns: {len(terrain.patterns)} patterns, more than the "
                         f"{MATERIAL_POLYGON - MATERIAL_GROUND - 1} material codes 2..99 hold")
    try:
        bands = pattern_bands(terrain)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    z = np.asarray(terrain.z)
    return TerrainArrays(
        present=True, origin=np.asarray(terrain.origin, np.float64).reshape(3).copy(),
        spacing=float(terrain.spacing_m), nx=int(terrain.nx), ny=int(terrain.ny),
        levels=int(terrain.levels), page_size=int(terrain.page_size),
        pages_x=np.asarray(terrain.pages_x, np.int64), pages_y=np.asarray(terrain.pages_y, np.int64),
        table_offset=np.asarray(terrain.table_offset, np.int64),
        page_table=np.asarray(terrain.page_table, np.int64), z=z, rgb=np.asarray(terrain.rgb),
        pattern=np.asarray(terrain.pattern), band_top=bands.top_m, band_count=bands.count,
        band_rgb=bands.rgb, srgb=SRGB_TO_LINEAR, z_top=bands.z_top, margin=float(margin))


def _face_grid(database: Database) -> FaceGrid:
    table = database.faces
    corners, starts, normals, opacity, material, colour = [], [0], [], [], [], []
    for inst in range(database.instance_model.shape[0]):
        m = int(database.instance_model[inst])
        rot = np.asarray(database.instance_rotation[inst], np.float64)
        pos = np.asarray(database.instance_position[inst], np.float64)
        cb, cc = int(table.corner_base[m]), int(table.corner_count[m])
        fb, fc = int(table.face_base[m]), int(table.face_count[m])
        corners.append(table.corner_xyz[cb:cb + cc] @ rot.T + pos)  # model -> world, float64
        sizes = table.face_size[fb:fb + fc]
        starts.extend((starts[-1] + np.cumsum(sizes)).tolist())
        normals.append(table.normal[fb:fb + fc] @ rot.T)
        opacity.append(table.opacity[fb:fb + fc].astype(np.float64))
        material.append(np.full(fc, MATERIAL_POLYGON + m, np.int64))
        colour.append(table.colour[fb:fb + fc].astype(np.float64))
    corner_start = np.array(starts, np.int64)
    count = corner_start.shape[0] - 1
    if count == 0:
        return FaceGrid(corner_start=corner_start, corner=np.zeros((0, 3)), normal=np.zeros((0, 3)),
                        opacity=np.zeros(0), material=np.zeros(0, np.int64), colour=np.zeros((0, 3)),
                        x0=0.0, y0=0.0, cell=1.0, gx=1, gy=1, z_lo=0.0, z_hi=0.0,
                        cell_start=np.zeros(2, np.int64), cell_face=np.zeros(0, np.int64))
    corner = np.ascontiguousarray(np.concatenate(corners))
    # Each face's xy bounding box (reduceat over its corners) and the grid around them all.
    lo = np.minimum.reduceat(corner, corner_start[:-1], axis=0)
    hi = np.maximum.reduceat(corner, corner_start[:-1], axis=0)
    x0, y0 = float(lo[:, 0].min()) - BOUNDS_PAD_M, float(lo[:, 1].min()) - BOUNDS_PAD_M
    x1, y1 = float(hi[:, 0].max()) + BOUNDS_PAD_M, float(hi[:, 1].max()) + BOUNDS_PAD_M
    span = max(x1 - x0, y1 - y0)
    cell = max(span / GRID_CELLS, MIN_CELL_M)  # > 0: MIN_CELL_M > 0 guards every division by it
    gx = int((x1 - x0) // cell) + 1
    gy = int((y1 - y0) // cell) + 1
    i0 = np.clip(((lo[:, 0] - x0) // cell).astype(np.int64), 0, gx - 1)
    i1 = np.clip(((hi[:, 0] - x0) // cell).astype(np.int64), 0, gx - 1)
    j0 = np.clip(((lo[:, 1] - y0) // cell).astype(np.int64), 0, gy - 1)
    j1 = np.clip(((hi[:, 1] - y0) // cell).astype(np.int64), 0, gy - 1)
    cells, faces = [], []
    for face in range(count):
        jj, ii = np.mgrid[j0[face]:j1[face] + 1, i0[face]:i1[face] + 1]
        cells.append((jj * gx + ii).ravel())
        faces.append(np.full(jj.size, face, np.int64))
    cell_of = np.concatenate(cells)
    order = np.argsort(cell_of, kind="stable")
    cell_start = np.concatenate([[0], np.cumsum(np.bincount(cell_of, minlength=gx * gy))]).astype(np.int64)
    return FaceGrid(
        corner_start=corner_start, corner=corner, normal=np.ascontiguousarray(np.concatenate(normals)),
        opacity=np.concatenate(opacity), material=np.concatenate(material),
        colour=np.ascontiguousarray(np.concatenate(colour)), x0=x0, y0=y0, cell=cell, gx=gx, gy=gy,
        z_lo=float(lo[:, 2].min()) - BOUNDS_PAD_M, z_hi=float(hi[:, 2].max()) + BOUNDS_PAD_M,
        cell_start=cell_start, cell_face=np.concatenate(faces)[order])
