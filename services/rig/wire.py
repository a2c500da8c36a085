"""The rig's types to and from their ``ig.v1`` messages, in one place for every process."""

from __future__ import annotations

from ig.v1 import frame_pb2

from .frame import Eyepoint


def eyepoint_to_proto(eyepoint: Eyepoint) -> frame_pb2.Eyepoint:
    """The message of an eyepoint (float64 all the way: the compositor compares bits)."""
    x, y, z = (float(v) for v in eyepoint.position)
    return frame_pb2.Eyepoint(x=x, y=y, z=z, heading_deg=float(eyepoint.heading_deg),
                              pitch_deg=float(eyepoint.pitch_deg), roll_deg=float(eyepoint.roll_deg))


def eyepoint_from_proto(msg: frame_pb2.Eyepoint) -> Eyepoint:
    """The Eyepoint of a message."""
    return Eyepoint.of(msg.x, msg.y, msg.z, msg.heading_deg, msg.pitch_deg, msg.roll_deg)
