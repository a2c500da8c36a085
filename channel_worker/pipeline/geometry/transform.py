"""World -> eye transform of the drawn instances, in float64, flat lighting, and the faces'
looks (textures, Gouraud light) in the eye frame."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import DrawList, Polygons, View
from channel_worker.pipeline.scene.database import Database

from ._transform_kernels import DrawnInstances, drawn_faces, face_kernel, transform_kernel
from .surface import eye_surfaces


def to_eye(database: Database, draws: DrawList, view: View) -> Polygons:
    """Transform every face of the drawn instances to eye coordinates and light it.

    Positions stay float64 throughout: the instance position is made eye-relative first (a
    difference of two large, nearly equal numbers that float64 holds exactly enough at 1000 km),
    and only then are the small model offsets rotated and added. All instances are transformed
    in compiled passes over a flat table of their faces (a serial stage: as numpy gathers and
    einsums it took 0.7 ms, 2.4 % of a 16-thread frame on a 16-core Xeon).
    """
    n = draws.instance_index.shape[0]
    if n == 0:
        return empty_polygons(3)
    table = database.faces
    model = database.instance_model[draws.instance_index]
    corners = table.corner_count[model]  # face-vertex slots per drawn instance
    faces = table.face_count[model]
    face_base = table.face_base[model]
    face_rows, face_inst = drawn_faces(face_base, faces)

    to_eye_rot = np.ascontiguousarray(view.world_to_eye @ draws.rotation)  # (n, 3, 3) model -> eye
    rel = (draws.position - view.eye) @ view.world_to_eye.T  # instance origins, eye frame
    n_corners = int(corners.sum())
    n_faces = face_rows.shape[0]
    eye_verts = np.empty((n_corners, 3))
    plane = np.empty((n_faces, 4))
    sun_dot = np.empty(n_faces)
    # The plane offset comes from the face's plane point (its own first vertex, or that of the
    # face it lies on), transformed exactly like the vertices, so coplanar faces of one
    # instance get bit-identical planes and their depth ties are decided by layer alone.
    drawn = DrawnInstances(to_eye_rot, np.ascontiguousarray(draws.rotation), np.ascontiguousarray(rel),
                           table.corner_base[model], corners, face_base, faces)
    transform_kernel(drawn, table, np.asarray(database.sun, np.float64),
                     (eye_verts, plane[:, :3], sun_dot, plane[:, 3]))
    look, surface, smooth = eye_surfaces(database, face_rows, face_inst, drawn)
    polys = Polygons(
        verts=eye_verts, start=np.empty(n_faces + 1, np.int64), colour=np.empty((n_faces, 3), np.float32),
        opacity=np.empty(n_faces, np.float32), feature_id=np.empty(n_faces, np.int32), plane=plane,
        layer=np.empty(n_faces, np.int16), look=look, surface=surface)
    # A Gouraud face's colour stays unlit: its light is surface row 2.
    face_kernel(face_rows, face_inst, database.instance_face_base[draws.instance_index], table, sun_dot,
                float(database.ambient), smooth if smooth is not None else np.zeros(n_faces, np.bool_),
                (polys.colour, polys.opacity, polys.feature_id, polys.layer, polys.start))
    return polys


def index_ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenation of arange(s, s + c) for each (s, c), without a Python loop."""
    total = int(counts.sum())
    base = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
    return base + np.arange(total)


def empty_polygons(dim: int) -> Polygons:
    """A Polygons with no polygon, vertices of dimension dim."""
    return Polygons(
        verts=np.zeros((0, dim), np.float64),
        start=np.zeros(1, np.int64),
        colour=np.zeros((0, 3), np.float32),
        opacity=np.zeros(0, np.float32),
        feature_id=np.zeros(0, np.int32),
        plane=np.zeros((0, 4), np.float64),
        layer=np.zeros(0, np.int16),
    )
