"""The types two processes of the rig exchange about a frame: where the eye is and what each
channel shows (docs/conventions.md: world x east, y north, z up, metres; angles in degrees).

The host computes an Eyepoint per frame, the workers render it through their ChannelSpec, and
the compositor checks that every channel rendered the host's eyepoint; none of them owns these
types, so they live here (wire.py converts them to and from ``ig.v1`` messages).

Body frame of the aircraft: x right, y forward, z up. Heading turns clockwise seen from above,
pitch raises the nose, roll lowers the right wing; they are applied in that order (intrinsic
heading, pitch, roll), so body -> world is ``Rh @ Rp @ Rr`` (hpr_matrix).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Pixels a channel may have on a side: the rig file's, `ig render`'s and render_frame's one
#: limit (a 16384 x 16384 frame's colour alone is 3 GB of float32; docs/scene-format.md, Limits).
MAX_CHANNEL_PIXELS = 16384


@dataclass(frozen=True)
class Eyepoint:
    """Where the aircraft's eye is and how it is oriented.

    Attributes:
        position: world position, metres, float64 (3,).
        heading_deg: clockwise from north.
        pitch_deg: nose-up positive.
        roll_deg: right-wing-down positive.
    """

    position: np.ndarray
    heading_deg: float
    pitch_deg: float
    roll_deg: float

    @staticmethod
    def of(x: float, y: float, z: float, h: float, p: float, r: float) -> Eyepoint:
        """An eyepoint from its six numbers: world metres, then degrees."""
        return Eyepoint(np.array([x, y, z], dtype=np.float64), float(h), float(p), float(r))


@dataclass(frozen=True)
class ChannelSpec:
    """One window of the rig: its offset from the aircraft nose, frustum and raster size.

    Angles in degrees. The frustum angles are measured in the channel's own frame and may be
    asymmetric (left < right, bottom < top, each strictly inside (-90, 90)).
    """

    name: str
    width: int
    height: int
    left_deg: float
    right_deg: float
    bottom_deg: float
    top_deg: float
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0

    @staticmethod
    def symmetric(name: str, width: int, height: int, fov_h_deg: float,
                  fov_v_deg: float | None = None, *, yaw_deg: float = 0.0,
                  pitch_deg: float = 0.0, roll_deg: float = 0.0) -> ChannelSpec:
        """A centred frustum; without fov_v the pixels are square."""
        half_h = fov_h_deg / 2.0
        if fov_v_deg is None:
            tan_v = np.tan(np.radians(half_h)) * height / width
            half_v = float(np.degrees(np.arctan(tan_v)))
        else:
            half_v = fov_v_deg / 2.0
        return ChannelSpec(name, int(width), int(height), -half_h, half_h, -half_v, half_v,
                           yaw_deg, pitch_deg, roll_deg)


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
    for name in ("width", "height"):
        value = getattr(channel, name)
        if value > MAX_CHANNEL_PIXELS:
            raise ValueError(f"channel {channel.name!r}: {name} {value} is more than the "
                             f"{MAX_CHANNEL_PIXELS} pixels a channel may have on a side")
    for name in ("left_deg", "right_deg", "bottom_deg", "top_deg", "yaw_deg", "pitch_deg", "roll_deg"):
        value = float(getattr(channel, name))
        if not math.isfinite(value):
            raise ValueError(f"channel {channel.name!r}: {name} {value} is not finite")
    for name in ("left_deg", "right_deg", "bottom_deg", "top_deg"):
        value = float(getattr(channel, name))
        if not -89.0 <= value <= 89.0:
            raise ValueError(f"channel {channel.name!r}: {name} {value} is outside [-89, 89]")
    if not channel.left_deg < channel.right_deg:
        raise ValueError(f"channel {channel.name!r}: left_deg {channel.left_deg} is not < right_deg "
                         f"{channel.right_deg}")
    if not channel.bottom_deg < channel.top_deg:
        raise ValueError(f"channel {channel.name!r}: bottom_deg {channel.bottom_deg} is not < top_deg "
                         f"{channel.top_deg}")
