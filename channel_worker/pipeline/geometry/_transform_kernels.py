"""numba kernel for the eye-relative transform (see geometry.to_eye)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class DrawnInstances(NamedTuple):
    """Per drawn instance: model -> eye and model -> world rotations (n, 3, 3), its origin in
    the eye frame (n, 3), and where its model's face vertices (corner_base, corner_count) and
    faces (face_base, face_count) lie in the FaceTable."""

    to_eye_rot: np.ndarray
    world_rot: np.ndarray
    rel: np.ndarray
    corner_base: np.ndarray
    corner_count: np.ndarray
    face_base: np.ndarray
    face_count: np.ndarray


@njit(cache=True)
def _apply(rot, k, v, rel):
    """rot[k] @ v + rel, component by component, always in the same order (so equal inputs give
    bit-identical outputs, whichever array they come from)."""
    x = rot[k, 0, 0] * v[0] + rot[k, 0, 1] * v[1] + rot[k, 0, 2] * v[2] + rel[0]
    y = rot[k, 1, 0] * v[0] + rot[k, 1, 1] * v[1] + rot[k, 1, 2] * v[2] + rel[1]
    z = rot[k, 2, 0] * v[0] + rot[k, 2, 1] * v[1] + rot[k, 2, 2] * v[2] + rel[2]
    return x, y, z


@njit(cache=True)
def transform_kernel(drawn, table, sun, out):
    """Per drawn instance k (DrawnInstances): its face vertices to eye coordinates, its face
    normals to eye and world frames (the world one dotted with the sun, a (3,) unit vector),
    and each face's plane offset d = n . p from its plane point transformed exactly like a
    vertex. table: the database's FaceTable. out: (vertices (C, 3), normals (F, 3), sun dot
    (F,), d (F,)), in drawn order."""
    to_eye_rot, world_rot, rel = drawn.to_eye_rot, drawn.world_rot, drawn.rel
    corner_base, corner_count = drawn.corner_base, drawn.corner_count
    face_base, face_count = drawn.face_base, drawn.face_count
    corner_xyz, normal, plane_xyz = table.corner_xyz, table.normal, table.plane_xyz
    out_verts, out_normal, out_world_z_dot, out_d = out
    zero = (0.0, 0.0, 0.0)
    v_out = 0
    f_out = 0
    for k in range(to_eye_rot.shape[0]):
        r = rel[k]
        for c in range(corner_base[k], corner_base[k] + corner_count[k]):
            x, y, z = _apply(to_eye_rot, k, corner_xyz[c], r)
            out_verts[v_out, 0] = x
            out_verts[v_out, 1] = y
            out_verts[v_out, 2] = z
            v_out += 1
        for f in range(face_base[k], face_base[k] + face_count[k]):
            nx, ny, nz = _apply(to_eye_rot, k, normal[f], zero)
            out_normal[f_out, 0] = nx
            out_normal[f_out, 1] = ny
            out_normal[f_out, 2] = nz
            wx, wy, wz = _apply(world_rot, k, normal[f], zero)
            out_world_z_dot[f_out] = wx * sun[0] + wy * sun[1] + wz * sun[2]
            px, py, pz = _apply(to_eye_rot, k, plane_xyz[f], r)
            out_d[f_out] = nx * px + ny * py + nz * pz
            f_out += 1
