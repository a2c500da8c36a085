"""Plant the near trees: the frame's polygon trees on the forest voxels near the eye
(scene/forest.py says why and how they cross-fade with the voxel blocks)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.scene.database import OPACITY_STEPS, Database
from channel_worker.pipeline.scene.forest import SINK_M, TREES_PER_SIDE, near_tree_ranges, tree_growth


def plant_trees(database: Database, view: View) -> Database:
    """The database with this frame's near trees added as instances (itself when it has none).

    Every forest voxel within the near-tree range of the eye gets TREES_PER_SIDE^2 trees at
    places, species, sizes and headings hashed from its index, standing on the voxel's
    bilinear surface, at the opacity step of 1 - tree_growth(its slant distance).
    """
    near, terrain = database.near_trees, database.terrain
    if near is None or terrain is None:
        return database
    start, end = near_tree_ranges(terrain, near, view_pixel(view))
    eye = np.asarray(view.eye, np.float64) - terrain.origin  # float64 before anything else
    s = terrain.spacing_m
    ix0, ix1 = max(math.floor((eye[0] - end) / s), 0), min(math.floor((eye[0] + end) / s), terrain.nx - 1)
    iy0, iy1 = max(math.floor((eye[1] - end) / s), 0), min(math.floor((eye[1] + end) / s), terrain.ny - 1)
    if ix0 > ix1 or iy0 > iy1:
        return database
    iy, ix = (a.ravel() for a in np.mgrid[iy0:iy1 + 1, ix0:ix1 + 1])
    log2 = int(terrain.page_size).bit_length() - 1
    mask = terrain.page_size - 1
    page = terrain.page_table[terrain.table_offset[0] + (iy >> log2) * terrain.pages_x[0] + (ix >> log2)]
    have = page >= 0  # level 0 may lack a page (a pruned database): no pattern is drawn there
    ix, iy, page = ix[have], iy[have], page[have]
    pattern = np.asarray(terrain.pattern[page, iy & mask, ix & mask]).astype(np.int64)
    forest = pattern > 0
    forest[forest] = near.canopy[pattern[forest] - 1]
    ix, iy, page = ix[forest], iy[forest], page[forest]
    if ix.size == 0:
        return database
    z4 = np.asarray(terrain.z[page, iy & mask, ix & mask], np.float64)  # (n, 4) corners SW SE NW NE
    # The voxel's slant distance exactly as the cast takes it (its centre, its corners' mean).
    dx = (ix + 0.5) * s - eye[0]
    dy = (iy + 0.5) * s - eye[1]
    dz = 0.25 * (z4[:, 0] + z4[:, 1] + z4[:, 2] + z4[:, 3]) - eye[2]
    opacity = 1.0 - tree_growth(np.sqrt(dx * dx + dy * dy + dz * dz), start, end)
    step = np.rint(opacity * OPACITY_STEPS).astype(np.int64)
    keep = step >= 1
    if not keep.any():
        return database
    ix, iy, z4, step = ix[keep], iy[keep], z4[keep], step[keep]

    # TREES_PER_SIDE^2 trees a voxel, each in its own sub-square, jittered within it.
    k = TREES_PER_SIDE
    sub = np.arange(k * k)
    h = _hash(ix[:, None] * np.int64(73856093) ^ iy[:, None] * np.int64(19349663) ^ sub[None, :] * np.int64(83492791))
    u = ((sub % k)[None, :] + 0.5 + 0.6 * (_unit(h, 0) - 0.5)) / k
    v = ((sub // k)[None, :] + 0.5 + 0.6 * (_unit(h, 1) - 0.5)) / k
    ground = ((1 - u) * (1 - v) * z4[:, None, 0] + u * (1 - v) * z4[:, None, 1]
              + (1 - u) * v * z4[:, None, 2] + u * v * z4[:, None, 3])
    species = (_unit(h, 2) < 0.45).astype(np.int64)  # 45 % broadleaves
    size = np.minimum((_unit(h, 3) * 3.0).astype(np.int64), 2)
    heading = _unit(h, 4) * (2.0 * math.pi)
    model = near.models[species, size, (step - 1)[:, None]].ravel()
    pos = np.stack([(ix[:, None] + u) * s, (iy[:, None] + v) * s, ground - SINK_M], axis=-1).reshape(-1, 3)
    pos += terrain.origin
    c, sn = np.cos(heading).ravel(), np.sin(heading).ravel()
    rot = np.zeros((c.size, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -sn, sn, c, 1.0

    faces = np.array([m.face_count for m in database.models], np.int64)[model]
    base = database.feature_count + np.concatenate([[0], np.cumsum(faces)[:-1]])
    return dataclasses.replace(
        database,
        instance_model=np.concatenate([database.instance_model, model]),
        instance_position=np.concatenate([database.instance_position, pos]),
        instance_rotation=np.concatenate([database.instance_rotation, rot]),
        instance_names=database.instance_names + ("near tree",) * model.size,
        instance_face_base=np.concatenate([database.instance_face_base, base]).astype(np.int64))


def view_pixel(view: View) -> float:
    """The channel's pixel angle across, radians (as the terrain's level switch takes it)."""
    return (math.atan(view.tan_right) - math.atan(view.tan_left)) / view.width


def _hash(x: np.ndarray) -> np.ndarray:
    """A 64-bit mix (splitmix64's finaliser) of integer keys, as uint64."""
    z = x.astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _unit(h: np.ndarray, k: int) -> np.ndarray:
    """The k-th 12-bit field of a hash, as a number in [0, 1)."""
    return ((h >> np.uint64(12 * k)) & np.uint64(4095)).astype(np.float64) / 4096.0
