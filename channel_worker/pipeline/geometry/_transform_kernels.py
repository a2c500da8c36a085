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


@njit(cache=True)
def surface_kernel(face_rows, face_inst, drawn, tex_map, look, smooth_look, normals, basis, sun, ambient,
                   out_maps, out_gouraud):
    """Per drawn face f (geometry.surface.eye_surfaces): its texture-plane coordinates (rows
    0 and 1 of out_maps[f]) and, for a Gouraud face (smooth_look[look] set), its light (row 2)
    as linear functions of the eye point; out_gouraud[f] marks the Gouraud faces. A face
    without a look gets the constant 1 in row 2 and zeros elsewhere.

    drawn: DrawnInstances (to_eye_rot, world_rot, rel by instance); tex_map (F, 2, 4), look
    (F,), normals (F, 3, 3), basis (F, 3, 3): the FaceTable's surface rows; sun (3,).
    """
    rot, world_rot, rel = drawn.to_eye_rot, drawn.world_rot, drawn.rel
    for f in range(face_rows.shape[0]):
        row = face_rows[f]
        k = face_inst[f]
        for i in range(3):
            for j in range(4):
                out_maps[f, i, j] = 0.0
        out_maps[f, 2, 3] = 1.0
        out_gouraud[f] = False
        lk = look[row]
        if lk < 0:
            continue
        for m in range(2):
            gx, gy, gz = _apply(rot, k, tex_map[row, m], (0.0, 0.0, 0.0))
            out_maps[f, m, 0] = gx
            out_maps[f, m, 1] = gy
            out_maps[f, m, 2] = gz
            out_maps[f, m, 3] = tex_map[row, m, 3] - (gx * rel[k, 0] + gy * rel[k, 1] + gz * rel[k, 2])
        if not smooth_look[lk]:
            continue
        # Lambert at the three corners, from the vertex normals in the world frame, made
        # linear over the triangle by the dual basis of its edges (model frame), then carried
        # into the eye frame like the texture planes.
        light = np.empty(3)
        for c in range(3):
            wx, wy, wz = _apply(world_rot, k, normals[row, c], (0.0, 0.0, 0.0))
            lam = min(max(wx * sun[0] + wy * sun[1] + wz * sun[2], 0.0), 1.0)
            light[c] = ambient + (1.0 - ambient) * lam
        d1 = light[1] - light[0]
        d2 = light[2] - light[0]
        grad = (d1 * basis[row, 0, 0] + d2 * basis[row, 1, 0],
                d1 * basis[row, 0, 1] + d2 * basis[row, 1, 1],
                d1 * basis[row, 0, 2] + d2 * basis[row, 1, 2])
        const = light[0] - (grad[0] * basis[row, 2, 0] + grad[1] * basis[row, 2, 1] + grad[2] * basis[row, 2, 2])
        ex, ey, ez = _apply(rot, k, grad, (0.0, 0.0, 0.0))
        out_maps[f, 2, 0] = ex
        out_maps[f, 2, 1] = ey
        out_maps[f, 2, 2] = ez
        out_maps[f, 2, 3] = const - (ex * rel[k, 0] + ey * rel[k, 1] + ez * rel[k, 2])
        out_gouraud[f] = True


@njit(cache=True)
def drawn_faces(face_base, face_count):
    """(face rows (N,), drawn instance of each (N,)): the FaceTable rows of each drawn
    instance's model, instance by instance."""
    n = 0
    for k in range(face_count.shape[0]):
        n += face_count[k]
    rows = np.empty(n, np.int64)
    inst = np.empty(n, np.int64)
    f = 0
    for k in range(face_count.shape[0]):
        for r in range(face_base[k], face_base[k] + face_count[k]):
            rows[f] = r
            inst[f] = k
            f += 1
    return rows, inst


@njit(cache=True)
def face_kernel(face_rows, face_inst, id_base, table, sun_dot, ambient, gouraud, out):
    """Per drawn face f: its colour lit by Lambert's flat light from sun_dot (1 for a Gouraud
    face, gouraud[f], whose light is its surface's row 2), opacity, feature id (id_base of its
    instance plus its model-local face), layer, and the start of its vertices (out: colour
    (N, 3) float32, opacity (N,) float32, feature_id (N,) int32, layer (N,) int16, start
    (N + 1,) int64)."""
    colour, opacity, feature_id, layer, start = out
    start[0] = 0
    for f in range(face_rows.shape[0]):
        row = face_rows[f]
        light = 1.0
        if not gouraud[f]:
            light = ambient + (1.0 - ambient) * min(max(sun_dot[f], 0.0), 1.0)
        for c in range(3):
            colour[f, c] = np.float32(table.colour[row, c] * light)
        opacity[f] = table.opacity[row]
        feature_id[f] = np.int32(id_base[face_inst[f]] + table.local_face[row])
        layer[f] = table.layer[row]
        start[f + 1] = start[f] + table.face_size[row]
