"""Height of terrain (CIGI HAT/HOT): the highest surface under a point, from the level-0 voxel
terrain and the scene's polygons (docs/cigi-queries.md).

What counts as a surface at world (x, y), at or below z_max:

- The terrain's level-0 surface exactly as the renderer draws level 0: bilinear in the voxel of
  its four float32 corner heights (JP H07-76990). In a pattern voxel (a tree, a building) the
  pattern's box top, ``max(corner heights) + top of the last band``, when it is at or below
  z_max; below it (a point inside the tree) the ground under it.
- Every instance's faces in world space where the vertical line through (x, y) meets them
  (the line against the face's fan of triangles; edges count). Vertical faces (|n_z| < 1e-6)
  have no height and are ignored. Translucent faces count when their opacity is at least
  HOT_MIN_OPACITY (0.5): a surface one can see through more than half is not one to stand on.
- A face within the scene's ``terrain.polygon_margin_m`` below the terrain surface is taken
  over the terrain, as the renderer draws it (a runway on its flattened pad, docs/terrain.md
  section 4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from channel_worker.pipeline.scene.database import Database

from ._index import prepared
from ._query_kernels import heights_kernel

#: Faces at least this opaque are surfaces for a height query.
HOT_MIN_OPACITY = 0.5


@dataclass(frozen=True)
class Heights:
    """The surface under each point.

    Attributes:
        valid: (n,) bool; False where no surface lies under the point at or below z_max
            (outside the databases).
        height_m: (n,) float64 world z of the surface, metres; nan where not valid.
        normal: (n, 3) float64 unit upward surface normal, world frame; 0 where not valid.
        material: (n,) uint32 material code (docs/cigi-queries.md; 0 where not valid).
    """

    valid: np.ndarray
    height_m: np.ndarray
    normal: np.ndarray
    material: np.ndarray


def height_of_terrain(database: Database, x: np.ndarray, y: np.ndarray, z_max: np.ndarray) -> Heights:
    """The highest surface at or below z_max under each world point (x, y).

    Args:
        database: the scene (terrain and polygons); its query index is built on first use.
        x, y: (n,) world metres, east and north, float64.
        z_max: (n,) world metres; only surfaces at or below count (+inf: height of terrain).

    Returns:
        Heights, one entry per point.

    Raises:
        ValueError: arrays of unequal length (named with their lengths), or non-finite x or y.
    """
    xs = np.ascontiguousarray(x, np.float64).reshape(-1)
    ys = np.ascontiguousarray(y, np.float64).reshape(-1)
    zs = np.ascontiguousarray(z_max, np.float64).reshape(-1)
    if not xs.shape == ys.shape == zs.shape:
        raise ValueError(f"x, y, z_max: lengths {xs.shape[0]}, {ys.shape[0]}, {zs.shape[0]} differ")
    for name, values in (("x", xs), ("y", ys)):
        bad = ~np.isfinite(values)
        if bad.any():
            n = int(np.argmax(bad))
            raise ValueError(f"{name}[{n}]: {values[n].tolist()!r} is not finite")
    if np.isnan(zs).any():
        n = int(np.argmax(np.isnan(zs)))
        raise ValueError(f"z_max[{n}]: {float(zs[n])!r} is not a number")
    ready = prepared(database)
    count = xs.shape[0]
    valid = np.zeros(count, np.bool_)
    height = np.empty(count)
    normal = np.zeros((count, 3))
    material = np.zeros(count, np.int64)
    heights_kernel(ready.terrain, ready.faces, xs, ys, zs, HOT_MIN_OPACITY, valid, height, normal, material)
    return Heights(valid=valid, height_m=height, normal=normal, material=material.astype(np.uint32))
