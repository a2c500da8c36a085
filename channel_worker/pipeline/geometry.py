"""Orientation conventions and the world -> eye transform.

Body frame of the aircraft: x right, y forward, z up. World: x east, y north, z up. Heading turns
clockwise seen from above, pitch raises the nose, roll lowers the right wing; they are applied in
that order (intrinsic heading, pitch, roll), so body -> world is ``Rh @ Rp @ Rr``.
"""

from __future__ import annotations

import math

import numpy as np

from services.rig.frame import ChannelSpec, Eyepoint, check_channel, check_eyepoint

from ._geometry_kernels import transform_kernel
from .types import Database, DrawList, Polygons, View


def hpr_matrix(heading_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Body -> world rotation (3, 3) float64; columns are the body right, forward, up axes."""
    h, p, r = (math.radians(a) for a in (heading_deg, pitch_deg, roll_deg))
    ch, sh, cp, sp, cr, sr = math.cos(h), math.sin(h), math.cos(p), math.sin(p), math.cos(r), math.sin(r)
    rh = np.array([[ch, sh, 0.0], [-sh, ch, 0.0], [0.0, 0.0, 1.0]])
    rp = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    rr = np.array([[cr, 0.0, sr], [0.0, 1.0, 0.0], [-sr, 0.0, cr]])
    return rh @ rp @ rr


def make_view(channel: ChannelSpec, eyepoint: Eyepoint, *, near: float = 0.25,
              far: float = 100_000.0) -> View:
    """The view of one channel from one eyepoint.

    The channel's yaw/pitch/roll offset is applied in the aircraft body frame after the
    aircraft's own attitude, so every channel of a rig shares the eyepoint and turns with it.
    """
    check_eyepoint(eyepoint)
    check_channel(channel)
    body = hpr_matrix(eyepoint.heading_deg, eyepoint.pitch_deg, eyepoint.roll_deg)
    chan = body @ hpr_matrix(channel.yaw_deg, channel.pitch_deg, channel.roll_deg)
    # Eye axes: x = channel right, y = channel up, z = channel forward.
    world_to_eye = np.stack([chan[:, 0], chan[:, 2], chan[:, 1]])
    return View(
        eye=np.asarray(eyepoint.position, dtype=np.float64).copy(),
        world_to_eye=world_to_eye,
        tan_left=math.tan(math.radians(channel.left_deg)),
        tan_right=math.tan(math.radians(channel.right_deg)),
        tan_bottom=math.tan(math.radians(channel.bottom_deg)),
        tan_top=math.tan(math.radians(channel.top_deg)),
        width=int(channel.width),
        height=int(channel.height),
        near=near,
        far=far,
    )


def to_eye(database: Database, draws: DrawList, view: View) -> Polygons:
    """Transform every face of the drawn instances to eye coordinates and light it.

    Positions stay float64 throughout: the instance position is made eye-relative first (a
    difference of two large, nearly equal numbers that float64 holds exactly enough at 1000 km),
    and only then are the small model offsets rotated and added. All instances are transformed
    in one vectorised pass over a flat table of their face vertices.
    """
    n = draws.instance_index.shape[0]
    if n == 0:
        return empty_polygons(3)
    table = database.faces
    model = database.instance_model[draws.instance_index]
    corners = table.corner_count[model]  # face-vertex slots per drawn instance
    faces = table.face_count[model]
    face_inst = np.repeat(np.arange(n), faces)
    face_rows = index_ranges(table.face_base[model], faces)

    to_eye_rot = np.ascontiguousarray(view.world_to_eye @ draws.rotation)  # (n, 3, 3) model -> eye
    rel = (draws.position - view.eye) @ view.world_to_eye.T  # instance origins, eye frame
    n_corners = int(corners.sum())
    n_faces = int(faces.sum())
    eye_verts = np.empty((n_corners, 3))
    normal = np.empty((n_faces, 3))
    sun_dot = np.empty(n_faces)
    d = np.empty(n_faces)
    # The plane offset comes from the face's plane point (its own first vertex, or that of the
    # face it lies on), transformed exactly like the vertices, so coplanar faces of one
    # instance get bit-identical planes and their depth ties are decided by layer alone.
    transform_kernel(to_eye_rot, np.ascontiguousarray(draws.rotation), np.ascontiguousarray(rel),
                     table.corner_base[model], corners, table.face_base[model], faces,
                     table.corner_xyz, table.normal, table.plane_xyz, eye_verts, normal, sun_dot, d,
                     np.asarray(database.sun, np.float64))
    light = database.ambient + (1.0 - database.ambient) * np.clip(sun_dot, 0.0, 1.0)

    sizes = table.face_size[face_rows]
    start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    ids = database.instance_face_base[draws.instance_index][face_inst] + table.local_face[face_rows]
    return Polygons(
        verts=eye_verts,
        start=start,
        colour=(table.colour[face_rows] * light[:, None]).astype(np.float32),
        opacity=table.opacity[face_rows],
        feature_id=ids.astype(np.int32),
        plane=np.column_stack([normal, d]),
        layer=table.layer[face_rows],
    )


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
    )
