"""Attitudes as quaternions: conversion, interpolation, and the estimate for logs without them.

Attitudes follow docs/conventions.md: body -> world = Rz(-heading) Rx(pitch) Ry(roll) with the
body frame x right, y forward, z up (services.rig.frame.hpr_matrix). Quaternions
are float64 [w, x, y, z] of that rotation. Interpolating them (slerp) turns on the shortest
arc, so heading 359 -> 1 passes through 0 and never through 180, and pitch +-90 is no
singularity.
"""

from __future__ import annotations

import math

import numpy as np

G_MPS2 = 9.80665
#: Below this horizontal speed the track says nothing about heading (a parked glider, a
#: hovering drone): the estimate holds the last heading and levels pitch and bank, m/s.
MIN_TRACK_SPEED_MPS = 1.0
#: Largest estimated bank, degrees (noise in a slow turn must not roll the picture over).
MAX_BANK_DEG = 60.0


def _axis_quat(axis: int, angle_rad: np.ndarray) -> np.ndarray:
    q = np.zeros(np.shape(angle_rad) + (4,))
    q[..., 0] = np.cos(angle_rad / 2.0)
    q[..., 1 + axis] = np.sin(angle_rad / 2.0)
    return q


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a b of quaternions (..., 4)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def from_hpr(hpr_deg: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) of attitudes (..., 3): heading, pitch, roll in degrees."""
    h, p, r = np.moveaxis(np.radians(np.asarray(hpr_deg, np.float64)), -1, 0)
    return multiply(multiply(_axis_quat(2, -h), _axis_quat(0, p)), _axis_quat(1, r))


def matrix(q: np.ndarray) -> np.ndarray:
    """Body -> world rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    w, x, y, z = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def to_hpr(q: np.ndarray) -> tuple[float, float, float]:
    """(heading in [0, 360), pitch, roll) degrees of one unit quaternion.

    At pitch +-90 heading and roll turn about the same axis: roll is taken as 0 and heading
    says which way the top of the picture points.
    """
    m = matrix(q)
    right, forward, up = m[:, 0], m[:, 1], m[:, 2]
    pitch = math.degrees(math.asin(min(max(forward[2], -1.0), 1.0)))
    if math.hypot(forward[0], forward[1]) > 1e-9:
        heading = math.degrees(math.atan2(forward[0], forward[1]))
        roll = math.degrees(math.atan2(-right[2], up[2]))
    else:  # looking straight up (down): the picture's top is -up (+up) projected
        sign = 1.0 if forward[2] > 0 else -1.0
        heading = math.degrees(math.atan2(-sign * up[0], -sign * up[1]))
        roll = 0.0
    heading %= 360.0
    return (0.0 if heading >= 360.0 else heading), pitch, roll


def continuous(q: np.ndarray) -> np.ndarray:
    """The quaternions (n, 4) with signs flipped so that neighbours are on the same hemisphere
    (q and -q are the same attitude; slerp between neighbours then takes the short way)."""
    out = np.array(q, np.float64)
    for i in range(1, len(out)):
        if np.dot(out[i - 1], out[i]) < 0.0:
            out[i] = -out[i]
    return out


def slerp(a: np.ndarray, b: np.ndarray, f: float) -> np.ndarray:
    """The unit quaternion a fraction f of the way from a to b along the shortest arc."""
    d = float(np.dot(a, b))
    if d < 0.0:
        b, d = -b, -d
    if d > 0.9995:  # nearly equal: linear interpolation is exact enough and avoids 0 / 0
        q = a + f * (b - a)
        return q / np.linalg.norm(q)
    theta = math.acos(min(d, 1.0))
    return (math.sin((1.0 - f) * theta) * a + math.sin(f * theta) * b) / math.sin(theta)


def from_ned_quaternion(q_ned: np.ndarray) -> np.ndarray:
    """(n, 3) heading, pitch, roll degrees of PX4 attitudes: quaternions [w, x, y, z] that
    rotate the FRD (forward, right, down) body frame into NED (north, east, down).

    Their ZYX Euler angles are exactly heading (yaw from north, clockwise), pitch (nose up)
    and roll (right wing down) of docs/conventions.md.
    """
    w, x, y, z = np.moveaxis(np.asarray(q_ned, np.float64), -1, 0)
    yaw = np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    pitch = np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0)))
    roll = np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
    return np.stack([yaw % 360.0, pitch, roll], axis=-1)


def estimate(t_s: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(n, 3) heading, pitch, roll degrees estimated from a track (docs/replay-formats.md).

    heading = direction of the horizontal velocity (the track), pitch = flight-path angle,
    bank = atan(v turn rate / g), the bank of a coordinated turn. Velocities are central
    differences of the positions; the turn rate is the central difference of the unwrapped
    track, averaged over three samples against the noise of GNSS fixes. Below
    MIN_TRACK_SPEED_MPS the heading holds (the first moving heading is used before the
    aircraft first moves) and pitch and bank are 0.
    """
    n = len(t_s)
    if n < 2:
        return np.zeros((n, 3))
    v = np.gradient(position, t_s, axis=0)
    v_h = np.hypot(v[:, 0], v[:, 1])
    moving = v_h >= MIN_TRACK_SPEED_MPS
    track = np.degrees(np.arctan2(v[:, 0], v[:, 1]))
    if moving.any():
        idx = np.where(moving, np.arange(n), -1)
        np.maximum.accumulate(idx, out=idx)  # last moving sample at or before each one
        idx[idx < 0] = int(np.argmax(moving))
        track = track[idx]
    else:
        track = np.zeros(n)
    unwrapped = np.degrees(np.unwrap(np.radians(track)))
    rate = np.radians(np.gradient(unwrapped, t_s))
    rate = np.convolve(np.pad(rate, 1, mode="edge"), np.ones(3) / 3.0, mode="valid")
    bank = np.degrees(np.arctan(v_h * rate / G_MPS2))
    bank = np.where(moving, np.clip(bank, -MAX_BANK_DEG, MAX_BANK_DEG), 0.0)
    pitch = np.where(moving, np.degrees(np.arctan2(v[:, 2], np.maximum(v_h, 1e-9))), 0.0)
    return np.stack([track % 360.0, pitch, bank], axis=-1)
