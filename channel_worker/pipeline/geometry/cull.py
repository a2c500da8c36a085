"""Cull whole instances against the view frustum by their bounding spheres."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import DrawList, View
from channel_worker.pipeline.scene.database import Database


def cull(database: Database, view: View) -> DrawList:
    """Keep the instances whose bounding sphere touches the view frustum.

    Conservative: a sphere that straddles a plane is kept; clipping deals with it.
    """
    if database.instance_model.shape[0] == 0:
        return DrawList(np.zeros(0, np.int64), np.zeros((0, 3, 3)), np.zeros((0, 3)))
    centres = np.array([m.centre for m in database.models])[database.instance_model]
    radii = np.array([m.radius for m in database.models])[database.instance_model]
    rot = database.instance_rotation
    world_rel = (database.instance_position - view.eye) + np.einsum("nij,nj->ni", rot, centres)
    c = world_rel @ view.world_to_eye.T  # sphere centres in eye coordinates
    x, y, z = c[:, 0], c[:, 1], c[:, 2]
    keep = (z >= view.near - radii) & (z <= view.far + radii)
    # Side planes pass through the eye; their unit normals point into the frustum.
    for tan, sign, coord in ((view.tan_left, 1.0, x), (view.tan_right, -1.0, x),
                             (view.tan_bottom, 1.0, y), (view.tan_top, -1.0, y)):
        dist = sign * (coord - tan * z) / np.sqrt(1.0 + tan * tan)
        keep &= dist >= -radii
    idx = np.nonzero(keep)[0].astype(np.int64)
    return DrawList(idx, rot[idx], database.instance_position[idx])
