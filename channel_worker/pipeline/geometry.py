"""Orientation conventions and the world -> eye transform.

Body frame of the aircraft: x right, y forward, z up. World: x east, y north, z up. Heading turns
clockwise seen from above, pitch raises the nose, roll lowers the right wing; they are applied in
that order (intrinsic heading, pitch, roll), so body -> world is ``Rh @ Rp @ Rr``.
"""

from __future__ import annotations

import math

import numpy as np

from .types import ChannelSpec, Database, DrawList, Eyepoint, Polygons, View


def hpr_matrix(heading_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Body -> world rotation (3, 3) float64; columns are the body right, forward, up axes."""
    h, p, r = (math.radians(a) for a in (heading_deg, pitch_deg, roll_deg))
    ch, sh, cp, sp, cr, sr = math.cos(h), math.sin(h), math.cos(p), math.sin(p), math.cos(r), math.sin(r)
    rh = np.array([[ch, sh, 0.0], [-sh, ch, 0.0], [0.0, 0.0, 1.0]])
    rp = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    rr = np.array([[cr, 0.0, sr], [0.0, 1.0, 0.0], [-sr, 0.0, cr]])
    return rh @ rp @ rr


def check_eyepoint(eyepoint: Eyepoint) -> None:
    """Raise ValueError naming the first non-finite field of the eyepoint."""
    pos = np.asarray(eyepoint.position)
    if pos.shape != (3,):
        raise ValueError(f"eyepoint.position: shape {pos.shape} is not (3,)")
    for i in range(3):
        if not math.isfinite(float(pos[i])):
            raise ValueError(f"eyepoint.position[{i}]: {pos[i]} is not finite")
    for name in ("heading_deg", "pitch_deg", "roll_deg"):
        value = getattr(eyepoint, name)
        if not math.isfinite(float(value)):
            raise ValueError(f"eyepoint.{name}: {value} is not finite")


def check_channel(channel: ChannelSpec) -> None:
    """Raise ValueError naming the first field of the channel that cannot make a frustum."""
    if channel.width < 1 or channel.height < 1:
        raise ValueError(f"channel {channel.name!r}: size {channel.width} x {channel.height} is empty")
    for name in ("left_deg", "right_deg", "bottom_deg", "top_deg", "yaw_deg", "pitch_deg", "roll_deg"):
        value = float(getattr(channel, name))
        if not math.isfinite(value):
            raise ValueError(f"channel {channel.name!r}: {name} {value} is not finite")
    for name in ("left_deg", "right_deg", "bottom_deg", "top_deg"):
        value = float(getattr(channel, name))
        if not -89.0 <= value <= 89.0:
            raise ValueError(f"channel {channel.name!r}: {name} {value} is outside [-89, 89]")
    if not channel.left_deg < channel.right_deg:
        raise ValueError(f"channel {channel.name!r}: left_deg {channel.left_deg} is not < right_deg {channel.right_deg}")
    if not channel.bottom_deg < channel.top_deg:
        raise ValueError(f"channel {channel.name!r}: bottom_deg {channel.bottom_deg} is not < top_deg {channel.top_deg}")


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
    and only then are the small model offsets rotated and added.
    """
    verts, starts, colours, opacities, ids, normals = [], [0], [], [], [], []
    offset = 0
    for k in range(draws.instance_index.shape[0]):
        inst = int(draws.instance_index[k])
        model = database.models[int(database.instance_model[inst])]
        rel = draws.position[k] - view.eye
        to_eye_rot = view.world_to_eye @ draws.rotation[k]
        model_eye = (model.vertices @ to_eye_rot.T) + view.world_to_eye @ rel
        verts.append(model_eye[model.face_index])
        starts.append(model.face_start[1:] + offset)
        offset += model.face_index.shape[0]
        world_n = model.normal @ draws.rotation[k].T
        lambert = np.clip(world_n @ database.sun, 0.0, 1.0)
        light = database.ambient + (1.0 - database.ambient) * lambert
        colours.append(model.colour * light[:, None].astype(np.float32))
        opacities.append(model.opacity)
        ids.append(database.instance_face_base[inst] + np.arange(model.face_count))
        normals.append(model.normal @ to_eye_rot.T)
    if not ids:
        return empty_polygons(3)
    eye_verts = np.concatenate(verts)
    start = np.concatenate([np.asarray(s, dtype=np.int64).ravel() for s in starts])
    normal = np.concatenate(normals)
    first = eye_verts[start[:-1]]
    d = np.einsum("ij,ij->i", normal, first)
    return Polygons(
        verts=eye_verts,
        start=start,
        colour=np.concatenate(colours).astype(np.float32),
        opacity=np.concatenate(opacities).astype(np.float32),
        feature_id=np.concatenate(ids).astype(np.int32),
        plane=np.column_stack([normal, d]),
    )


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
