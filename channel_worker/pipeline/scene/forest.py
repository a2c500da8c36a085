"""Trees that hold up close: the polygon trees a forest voxel turns into near the eye.

A forest of the voxel terrain is a level-0 voxel calling the "tree" pattern: a 30 m block with
a trunk band and a canopy top (JP H07-76990's pattern insertion). Far away that is right, a
stand of trees a few pixels wide; near the eye it is a cube. Within a range set by the voxel's
size on the screen (`near_tree_px`: the voxel is drawn as trees while it spans more pixels than
that), each forest voxel is planted with nine polygon trees, cone-and-trunk firs and round
broadleaves, placed, sized and turned by a hash of the voxel (the same trees every frame, on
every channel). Between `NEAR_SHARE` of that range and the range itself the two cross-fade: the
trees' opacity falls from 1 to 0 while the voxel's block rises from the ground to its full
height (`tree_growth`: the cast and the planting compute it alike, from the eye's slant
distance to the voxel's centre), so neither appears or vanishes at once.

The models are built here, once per scene, one per species, size class and opacity step
(`OPACITY_STEPS`: opacity is a property of a model's faces, so the fade takes it in steps of
1/8).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .database import OPACITY_STEPS, Database, FaceTable, Model, NearTrees
from .terrain.database import TerrainDatabase

#: Where the cross-fade starts, as a share of the near-tree range.
NEAR_SHARE = 0.7
#: Trees per voxel side (3: nine trees a voxel, 10 m apart, their crowns touching).
TREES_PER_SIDE = 3
#: (height, crown radius) metres of the size classes, firs then broadleaves.
FIR_SIZES = ((13.5, 3.6), (16.0, 4.1), (18.5, 4.6))
BROADLEAF_SIZES = ((12.0, 4.4), (14.5, 5.0), (16.5, 5.6))
#: Bases sink this far into the ground, so a tree on a slope never floats (metres).
SINK_M = 0.4


def near_tree_ranges(terrain: TerrainDatabase, near: NearTrees, pixel_rad: float) -> tuple[float, float]:
    """(start, end) of the cross-fade, slant metres from the eye: trees alone nearer than start,
    the voxel block alone beyond end. pixel_rad: the channel's pixel angle, radians (> 0)."""
    end = terrain.spacing_m / (near.px * max(pixel_rad, 1e-9))  # guard: px > 0 at load, pixel > 0
    return NEAR_SHARE * end, end


def tree_growth(distance: np.ndarray | float, start: float, end: float) -> np.ndarray | float:
    """The voxel block's share of its height at a slant distance (smoothstep from 0 at start to
    1 at end); the trees' opacity is 1 minus it. Written as the cast's kernel writes it."""
    t = np.clip((np.asarray(distance, np.float64) - start) / (end - start), 0.0, 1.0)  # end > start
    return t * t * (3.0 - 2.0 * t)


def with_near_trees(database: Database, px: float) -> Database:
    """The database with the near trees' models added (none when its terrain has no forest)."""
    terrain = database.terrain
    if terrain is None or px <= 0.0:
        return database
    canopy = np.array([p.name == "tree" for p in terrain.patterns] or [False], np.bool_)
    if not canopy.any():
        return database
    forest = terrain.patterns[int(np.argmax(canopy))]
    from services.rig.colour import srgb_to_linear

    rgb = srgb_to_linear(np.asarray(forest.rgb, np.float64) / 255.0).astype(np.float32)
    trunk, crown = rgb[0], rgb[-1]
    models = list(database.models)
    index = np.zeros((2, 3, OPACITY_STEPS), np.int64)
    for species, sizes in enumerate((FIR_SIZES, BROADLEAF_SIZES)):
        # Broadleaves a lighter, yellower green than the firs' (the pattern's canopy colour).
        leaf = crown if species == 0 else np.minimum(crown * np.array([1.5, 1.45, 1.1], np.float32), 1.0)
        for size, (height, radius) in enumerate(sizes):
            for step in range(OPACITY_STEPS):
                opacity = (step + 1) / OPACITY_STEPS
                name = f"near-{'fir' if species == 0 else 'broadleaf'}-{size}-{step + 1}"
                build = _fir if species == 0 else _broadleaf
                index[species, size, step] = len(models)
                models.append(build(name, height, radius, trunk, leaf, opacity))
    return dataclasses.replace(database, models=tuple(models), faces=FaceTable.of(tuple(models)),
                               near_trees=NearTrees(float(px), index, canopy))


def _ring(radius: float, z: float, sides: int, turn: float = 0.0) -> list[tuple[float, float, float]]:
    angles = [turn + 2.0 * math.pi * k / sides for k in range(sides)]
    return [(radius * math.cos(a), radius * math.sin(a), z) for a in angles]


def _fir(name: str, height: float, radius: float, trunk: np.ndarray, leaf: np.ndarray, opacity: float) -> Model:
    """A trunk (square prism) under a seven-sided cone."""
    w = 0.3
    base = 0.22 * height
    verts = _ring(w * math.sqrt(2.0), 0.0, 4, math.pi / 4) + _ring(w * math.sqrt(2.0), base + 0.5, 4, math.pi / 4)
    faces: list[tuple[list[int], np.ndarray]] = [([k, (k + 1) % 4, 4 + (k + 1) % 4, 4 + k], trunk) for k in range(4)]
    ring = len(verts)
    verts += _ring(radius, base, 7)
    apex = len(verts)
    verts.append((0.0, 0.0, height))
    faces += [([ring + k, ring + (k + 1) % 7, apex], leaf) for k in range(7)]
    faces.append(([ring + k for k in reversed(range(7))], leaf * 0.6))
    return _model(name, verts, faces, opacity)


def _broadleaf(name: str, height: float, radius: float, trunk: np.ndarray, leaf: np.ndarray,
               opacity: float) -> Model:
    """A trunk under a round crown: a widening six-sided frustum, then a cone."""
    w = 0.35
    low, mid = 0.32 * height, 0.62 * height
    verts = _ring(w * math.sqrt(2.0), 0.0, 4, math.pi / 4) + _ring(w * math.sqrt(2.0), low + 0.5, 4, math.pi / 4)
    faces: list[tuple[list[int], np.ndarray]] = [([k, (k + 1) % 4, 4 + (k + 1) % 4, 4 + k], trunk) for k in range(4)]
    bottom = len(verts)
    verts += _ring(0.55 * radius, low, 6)
    middle = len(verts)
    verts += _ring(radius, mid, 6, math.pi / 6)
    apex = len(verts)
    verts.append((0.0, 0.0, height))
    for k in range(6):
        # The frustum's sides are triangles: its rings are turned against each other.
        faces.append(([bottom + k, bottom + (k + 1) % 6, middle + k], leaf * 0.8))
        faces.append(([bottom + (k + 1) % 6, middle + (k + 1) % 6, middle + k], leaf * 0.8))
        faces.append(([middle + k, middle + (k + 1) % 6, apex], leaf))
    faces.append(([bottom + k for k in reversed(range(6))], leaf * 0.5))
    return _model(name, verts, faces, opacity)


def _model(name: str, verts: list[tuple[float, float, float]], faces: list[tuple[list[int], np.ndarray]],
           opacity: float) -> Model:
    """A Model of convex faces, each wound counter-clockwise seen from outside (the winding is
    checked against the direction from the tree's axis, and turned where it disagrees)."""
    vertices = np.array(verts, np.float64)
    start, flat, normals, colours = [0], [], [], []
    for idx, colour in faces:
        pts = vertices[idx]
        nxt = np.roll(pts, -1, axis=0)
        newell = np.array([np.sum((pts[:, 1] - nxt[:, 1]) * (pts[:, 2] + nxt[:, 2])),
                           np.sum((pts[:, 2] - nxt[:, 2]) * (pts[:, 0] + nxt[:, 0])),
                           np.sum((pts[:, 0] - nxt[:, 0]) * (pts[:, 1] + nxt[:, 1]))])
        n = newell / np.linalg.norm(newell)  # guard: every face above has area
        centre = pts.mean(axis=0)
        outward = centre - np.array([0.0, 0.0, centre[2]]) if abs(n[2]) < 0.999 else np.array([0.0, 0.0, -1.0])
        if n @ outward < 0.0:
            idx, n = list(reversed(idx)), -n
        flat.extend(idx)
        start.append(len(flat))
        normals.append(n)
        colours.append(np.asarray(colour, np.float32))
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = float(np.sqrt(((vertices - centre) ** 2).sum(axis=1)).max())
    count = len(faces)
    return Model(name, vertices, np.array(start, np.int64), np.array(flat, np.int64),
                 np.array(colours, np.float32), np.full(count, opacity, np.float32), np.array(normals),
                 centre, radius)
