"""Backface elimination in eye space (float64, before anything is narrowed)."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import Polygons

from .transform import index_ranges


def eliminate_backfaces(polys: Polygons) -> Polygons:
    """Keep faces whose front side faces the eye.

    A face is front-facing when the eye (the origin) lies strictly on the side its outward
    normal points to: ``n . p0 < 0`` for any point p0 of the face. Edge-on faces (``n . p0``
    zero to rounding, relative to the distance) cover no area and are dropped too; this is
    also the guard that keeps the plane constant d = n . p0 away from zero for the depth
    interpolation in project.py.
    """
    d = polys.plane[:, 3]
    first = polys.verts[polys.start[:-1]]
    dist = np.sqrt(np.einsum("ij,ij->i", first, first))
    keep = d < -1e-12 * np.maximum(dist, 1.0)
    return select(polys, keep)


def select(polys: Polygons, keep: np.ndarray) -> Polygons:
    """The polygons where keep is true, in their original order."""
    idx = np.nonzero(keep)[0]
    counts = np.diff(polys.start)[idx]
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    vidx = index_ranges(polys.start[idx], counts)
    return polys.take(idx, polys.verts[vidx], start)

