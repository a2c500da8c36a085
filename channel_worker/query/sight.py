"""Line of sight (CIGI LOS segment): the nearest surface each segment meets, from the level-0
voxel terrain and the scene's polygons (docs/cigi-queries.md).

- Terrain: Amanatides & Woo's grid walk visits every level-0 voxel the segment's ground track
  crosses (crossing times from the start and the boundary index, never accumulated; a vertical
  segment stays in its one voxel column, nothing is divided by its zero ground speed); inside
  each voxel the bilinear surface along the segment is a quadratic in the range, solved
  exactly (the cancellation-free form). Pattern voxels are boxes up to the pattern's top; the
  terrain is a solid, so a step between voxels and the database's edge are vertical walls and
  a segment starting inside it hits at range 0.
- Polygons: Möller-Trumbore against each face's fan of triangles, over the faces of the
  uniform face-grid cells the ground track crosses (_index.py); faces less opaque than the
  segment's min_opacity are passed through. Both sides of a face stop the segment.
- The nearer of the two; a face behind the terrain hit by less than the renderer's push-back
  (``terrain.polygon_margin_m / max(sin(depression), 1e-3)``) that lies at most the margin
  below the terrain surface wins, as it is drawn (a runway on its pad).

Everything is float64; the segment and the terrain origin are subtracted before anything else,
so 1000 km from the world origin answers as near it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from channel_worker.pipeline.scene.database import Database
from services.rig.colour import linear_to_srgb8

from ._index import prepared
from ._query_kernels import sight_kernel


@dataclass(frozen=True)
class Sightings:
    """What each segment meets.

    Attributes:
        hit: (n,) bool whether the segment meets a surface.
        range_m: (n,) float64 distance from the segment's start to the hit, metres; nan on a miss.
        point: (n, 3) float64 world position of the hit, metres; nan on a miss.
        normal: (n, 3) float64 unit normal at the hit, world frame, facing the segment's start
            (terrain: the surface's upward normal, or a wall's horizontal one); 0 on a miss.
        material: (n,) uint32 material code (docs/cigi-queries.md); 0 on a miss.
        rgba: (n,) uint32 colour of the surface hit, sRGB 8-bit packed 0xRRGGBBAA (alpha:
            the face's opacity, 255 for terrain); 0 on a miss.
    """

    hit: np.ndarray
    range_m: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    material: np.ndarray
    rgba: np.ndarray


def line_of_sight(database: Database, p0: np.ndarray, p1: np.ndarray, min_opacity: np.ndarray) -> Sightings:
    """The nearest surface each segment p0 -> p1 meets.

    Args:
        database: the scene (terrain and polygons); its query index is built on first use.
        p0, p1: (n, 3) world metres, start and end of each segment, float64.
        min_opacity: (n,) faces less opaque than this (0..1) do not stop the segment.

    Returns:
        Sightings, one entry per segment.

    Raises:
        ValueError: shapes that are not (n, 3), (n, 3), (n,) (named), or non-finite values.
    """
    a = np.ascontiguousarray(p0, np.float64)
    b = np.ascontiguousarray(p1, np.float64)
    opacity = np.ascontiguousarray(min_opacity, np.float64).reshape(-1)
    if a.ndim != 2 or a.shape[1:] != (3,) or b.shape != a.shape or opacity.shape != a.shape[:1]:
        raise ValueError(f"p0, p1, min_opacity: shapes {a.shape}, {b.shape}, {opacity.shape} are not (n, 3), "
                         f"(n, 3), (n,)")
    for name, values in (("p0", a), ("p1", b), ("min_opacity", opacity)):
        bad = ~np.isfinite(values)
        if bad.any():
            n = int(np.argmax(bad.reshape(values.shape[0], -1).any(axis=1)))
            raise ValueError(f"{name}[{n}]: {values[n].tolist()!r} is not finite")
    ready = prepared(database)
    count = a.shape[0]
    hit = np.zeros(count, np.bool_)
    range_m = np.empty(count)
    point = np.empty((count, 3))
    normal = np.zeros((count, 3))
    material = np.zeros(count, np.int64)
    rgb = np.zeros((count, 3))
    alpha = np.zeros(count)
    sight_kernel(ready.terrain, ready.faces, a, b, opacity, hit, range_m, point, normal, material, rgb, alpha)
    srgb = linear_to_srgb8(rgb).astype(np.uint32)
    a8 = np.round(np.clip(alpha, 0.0, 1.0) * 255.0).astype(np.uint32)
    rgba = np.where(hit, (srgb[:, 0] << 24) | (srgb[:, 1] << 16) | (srgb[:, 2] << 8) | a8, 0).astype(np.uint32)
    return Sightings(hit=hit, range_m=range_m, point=point, normal=normal,
                     material=material.astype(np.uint32), rgba=rgba)
