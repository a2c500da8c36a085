"""Attitudes as quaternions: conversion, interpolation, the change of frame for logged
attitudes far from the origin, and the estimate for logs without them.

Attitudes follow docs/conventions.md: body -> world = Rz(-heading) Rx(pitch) Ry(roll) with the
body frame x right, y forward, z up (services.rig.frame.hpr_matrix). Quaternions
are float64 [w, x, y, z] of that rotation. Interpolating them (slerp) turns on the shortest
arc, so heading 359 -> 1 passes through 0 and never through 180, and pitch +-90 is no
singularity.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from services.rig import geodetic

G_MPS2 = 9.80665
#: Horizontal GNSS noise the heading must ignore: the standard deviation of a fix in east and in
#: north, metres. Consumer receivers and flight loggers give 1-3 m; 3 m is a poor sky view.
GNSS_NOISE_M = 3.0
#: The track gives the heading only where the window's displacement (between the mean positions
#: of its halves, MOTION_WINDOW_S) is at least this, metres, and its speed at least
#: MIN_TRACK_SPEED_MPS; elsewhere the heading holds its last value and pitch and bank are 0 (a
#: parked or creeping glider, a hovering drone). At 1 Hz each half has 4 fixes, so the
#: displacement of a still aircraft has noise 0.61 GNSS_NOISE_M = 1.8 m in each axis: 10 m is 5.4
#: times that, exceeded with probability exp(-5.4^2 / 2) = 4e-7 per record, where a speed
#: threshold of 1 m/s (3 m over the window) was exceeded every few records at 1.5 m of noise and
#: spun the heading. A taxi (5 m/s and up: 15 m) passes it; a creep below about 3.3 m/s holds.
MOVING_DISPLACEMENT_M = 10.0
#: The speed floor, m/s: sparse logs (fixes 10 s or more apart) cover MOVING_DISPLACEMENT_M by
#: slow drift of the fixes, which this keeps from turning the heading.
MIN_TRACK_SPEED_MPS = 1.0
#: Largest estimated bank, degrees (noise in a slow turn must not roll the picture over).
MAX_BANK_DEG = 60.0
#: Largest estimated flight-path angle, degrees: steeper than a light aircraft's best climb
#: (about 10 degrees) or a steep approach (6), so only a glitch or aerobatics reach it.
MAX_PITCH_DEG = 30.0
#: The flight-path angle is the climb over at least this much horizontal path and this much
#: time, whichever is longer. GNSS heights wander by several metres (sigma about 2 m); the
#: climb between the mean heights of the window's halves then has an error of about
#: 4 sigma / (L sqrt(N)) radians for N records over L metres: 0.3 degrees for 400 m of 1 Hz
#: records at 30 m/s, so that the worst of a few minutes of climb stays within a degree. Over
#: 10 m (two taxiing fixes) the same noise gives tens of degrees.
PITCH_WINDOW_M = 400.0
PITCH_WINDOW_S = 12.0
#: The pitch window grows to at most this long, seconds; an aircraft that does not cover
#: PITCH_WINDOW_M in it (slower than about 7 m/s) is too slow for its climb to show through the noise:
#: its pitch is 0 (a hover, a vertical climb, a taxi).
PITCH_WINDOW_MAX_S = 60.0
#: Heading, turn rate and speed come from a window this long, seconds: long enough that fixes
#: jittering by a metre do not swing the heading of a parked aircraft, short enough to follow a
#: turn entry. It limits how fast the estimated bank can change.
MOTION_WINDOW_S = 6.0
#: Ground roll: slower than TAKEOFF_SPEED_MPS (below the rotation speed of light aircraft and
#: gliders on tow, above a fast taxi) and within GROUND_HEIGHT_M of the ground level, the lowest
#: smoothed height within GROUND_WINDOW_S / 2 either side. Speed alone would put a slow flyer
#: (paraglider, helicopter) on the ground; height alone would put a level cruise there.
TAKEOFF_SPEED_MPS = 20.0
GROUND_HEIGHT_M = 10.0
GROUND_WINDOW_S = 60.0
#: Estimated pitch and bank change no faster than this, degrees per second (a brisk rotation on
#: take-off; a light aircraft's roll into a turn), against the steps where the ground rule starts
#: or stops applying and against a glitch that the windows do not average away.
MAX_PITCH_RATE_DPS = 10.0
MAX_BANK_RATE_DPS = 30.0
#: Estimated heading turns no faster than this, degrees per second: above any aircraft's turn
#: that the track can show (a 60-degree-bank turn at 50 m/s is 20 deg/s, a taxiing aircraft turns
#: at most 20-30 deg/s), so that a glitch or the noise of a slow track cannot spin the picture.
MAX_HEADING_RATE_DPS = 30.0


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
    """(heading in [0, 360), pitch, roll) degrees of one unit quaternion (hpr_of_matrix)."""
    h, p, r = hpr_of_matrix(matrix(q))
    return float(h), float(p), float(r)


def hpr_of_matrix(m: np.ndarray) -> np.ndarray:
    """(..., 3) heading in [0, 360), pitch in [-90, 90], roll in (-180, 180] degrees of
    body -> world rotation matrices (..., 3, 3).

    At pitch +-90 heading and roll turn about the same axis: roll is taken as 0 and heading
    says which way the top of the picture points. Pitch is atan2(forward up, forward
    horizontal), which stays exact next to +-90 where asin(forward up) does not.
    """
    m = np.asarray(m, np.float64)
    right, forward, up = m[..., :, 0], m[..., :, 1], m[..., :, 2]
    horizontal = np.hypot(forward[..., 0], forward[..., 1])
    pitch = np.degrees(np.arctan2(forward[..., 2], horizontal))
    # Looking straight up (down) the picture's top is -up (+up) projected on the ground.
    vertical = horizontal <= 1e-9
    sign = np.where(forward[..., 2] > 0.0, 1.0, -1.0)
    heading = np.degrees(np.where(vertical, np.arctan2(-sign * up[..., 0], -sign * up[..., 1]),
                                  np.arctan2(forward[..., 0], forward[..., 1]))) % 360.0
    heading = np.where(heading >= 360.0, 0.0, heading)  # -1e-17 % 360 rounds to 360.0
    roll = np.where(vertical, 0.0, np.degrees(np.arctan2(-right[..., 2], up[..., 2])))
    return np.stack([heading, pitch, roll], axis=-1)


def local_to_world(hpr_deg: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray,
                   origin: tuple[float, float, float]) -> np.ndarray:
    """(n, 3) heading, pitch, roll degrees in the world frame of attitudes logged against local
    north and the local horizontal at each aircraft position.

    The world is the east-north-up tangent frame at origin (services.rig.geodetic.enu); far from
    it local north and up are tilted (about 1 degree per 111 km: 5.4 at 600 km). Each attitude
    goes body -> ENU at the aircraft -> ECEF -> ENU at the origin, as rotation matrices, and
    back to angles by hpr_of_matrix (no singularity at pitch +-90).

    Args:
        hpr_deg: (n, 3) heading, pitch, roll degrees relative to the local frame at each position.
        lat_deg, lon_deg: (n,) WGS-84 latitude and longitude of each position, degrees.
        origin: the world's reference point (latitude deg, longitude deg, height m).

    Raises:
        ValueError: hpr_deg is not (n, 3) or lat_deg / lon_deg do not have its n.
    """
    hpr, tilt = _tilt(hpr_deg, lat_deg, lon_deg, origin)
    return hpr_of_matrix(tilt @ matrix(from_hpr(hpr)))


def world_to_local(hpr_deg: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray,
                   origin: tuple[float, float, float]) -> np.ndarray:
    """The inverse of local_to_world: (n, 3) heading, pitch, roll degrees against local north
    and the local horizontal at each position of attitudes (n, 3) in the world frame. An
    attitude estimated from the world track is brought to the logged columns' frame so that
    the two can be mixed angle by angle (track.build_track).

    Raises:
        ValueError: hpr_deg is not (n, 3) or lat_deg / lon_deg do not have its n.
    """
    hpr, tilt = _tilt(hpr_deg, lat_deg, lon_deg, origin)
    # The inverse tilt is its transpose (a rotation).
    return hpr_of_matrix(np.swapaxes(tilt, -1, -2) @ matrix(from_hpr(hpr)))


def _tilt(hpr_deg: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray,
          origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(hpr (n, 3) float64, the rotations (n, 3, 3) from the ENU frame at each position to the
    origin's), after checking the shapes (the Raises of local_to_world)."""
    hpr = np.asarray(hpr_deg, np.float64)
    lat, lon = np.asarray(lat_deg, np.float64), np.asarray(lon_deg, np.float64)
    if hpr.ndim != 2 or hpr.shape[1] != 3:
        raise ValueError(f"hpr_deg: shape {hpr.shape}, need (n, 3)")
    for name, a in (("lat_deg", lat), ("lon_deg", lon)):
        if a.shape != hpr.shape[:1]:
            raise ValueError(f"{name}: shape {a.shape}, need ({hpr.shape[0]},) like hpr_deg")
    # (ECEF -> origin ENU) @ (aircraft ENU -> ECEF): the transpose of a rotation is its inverse.
    tilt = geodetic.enu_rotation(np.array(origin[0]), np.array(origin[1])) @ \
        np.swapaxes(geodetic.enu_rotation(lat, lon), -1, -2)
    return hpr, tilt


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


class AttitudeEstimate(NamedTuple):
    """An attitude estimated from a track, with what it took for granted.

    Attributes:
        hpr: (n, 3) heading, pitch, roll degrees in the track's frame.
        on_ground: (n,) True where the record was taken for ground roll (pitch and bank 0).
        assumptions: plain statements of every rule and constant the estimate relies on.
    """

    hpr: np.ndarray
    on_ground: np.ndarray
    assumptions: list[str]


def assumptions() -> list[str]:
    """The estimator's assumptions in plain language, with its constants."""
    return [
        "The aircraft flies where its nose points: heading is the direction of travel over the ground "
        "(no wind, no sideslip) and pitch is the flight-path angle (no angle of attack).",
        f"Heading, speed and turn rate are taken over {MOTION_WINDOW_S:g} s: the direction between the mean "
        f"positions of the window's two halves, and the change of heading between them.",
        f"The aircraft is moving where the window's displacement is at least {MOVING_DISPLACEMENT_M:g} m and its "
        f"speed at least {MIN_TRACK_SPEED_MPS:g} m/s, well beyond what GNSS noise of {GNSS_NOISE_M:g} m per fix "
        f"makes of a still aircraft. Elsewhere (parked, or creeping slower than about "
        f"{MOVING_DISPLACEMENT_M / (MOTION_WINDOW_S / 2.0):.1f} m/s at 1 Hz) the heading holds its last value "
        f"(before the first movement: the first moving heading), and pitch and bank are 0.",
        f"Pitch is the rise between the mean heights of the two halves of a window at least {PITCH_WINDOW_M:g} m "
        f"of path and {PITCH_WINDOW_S:g} s long, so that GNSS height noise of a few metres moves it by well under a "
        f"degree; it therefore lags and smooths real pitch changes over that window.",
        f"An aircraft that does not cover {PITCH_WINDOW_M:g} m in {PITCH_WINDOW_MAX_S:g} s (a hover, a vertical "
        f"climb, a taxi) is too slow for its climb to be told from noise: its pitch is 0.",
        f"Ground roll: slower than {TAKEOFF_SPEED_MPS:g} m/s and within {GROUND_HEIGHT_M:g} m of the lowest "
        f"smoothed height within {GROUND_WINDOW_S / 2:g} s either side. On the ground pitch and bank are 0. A "
        f"take-off or landing roll faster than that counts as flight (its track is level and straight, so its "
        f"estimate is nearly level); a slow aircraft holding its height for longer than that (a long hover, a "
        f"paraglider ridge-soaring) counts as on the ground and loses its bank.",
        f"Bank is that of a coordinated turn, atan(speed x turn rate / g), g = {G_MPS2} m/s^2 (no wind, no "
        f"slip).",
        f"Pitch is limited to +-{MAX_PITCH_DEG:g} deg and bank to +-{MAX_BANK_DEG:g} deg; they change by at most "
        f"{MAX_PITCH_RATE_DPS:g} and {MAX_BANK_RATE_DPS:g} deg/s. Heading turns by at most "
        f"{MAX_HEADING_RATE_DPS:g} deg/s (faster than an aircraft turns on the ground or in a 60-degree-bank "
        f"turn at 50 m/s); the turn rate behind the bank is that of this limited heading.",
    ]


def estimate(t_s: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(n, 3) heading, pitch, roll degrees estimated from a track: estimate_with_report().hpr."""
    return estimate_with_report(t_s, position).hpr


def estimate_with_report(t_s: np.ndarray, position: np.ndarray) -> AttitudeEstimate:
    """Attitudes estimated from a track, with the records taken for ground roll and the
    assumptions made (docs/replay-formats.md, "Attitude estimate").

    Heading is the track; pitch the flight-path angle over a window long enough for height
    noise to average out (PITCH_WINDOW_M, PITCH_WINDOW_S); bank that of a coordinated turn,
    atan(v turn rate / g). Each slope is the difference of the means of a window's two halves
    over the difference of their means of time or path (Wald's grouping method), which
    averages the noise of every record in the window. On the ground (slow and low: the
    constants above) pitch and bank are 0. Pitch and bank are then bounded in value and rate.

    Args:
        t_s: (n,) strictly increasing times, seconds.
        position: (n, 3) world positions (east, north, up), metres.

    Raises:
        ValueError: the shapes do not match, a value is not finite, or the times do not increase.
    """
    t = np.asarray(t_s, np.float64)
    p = np.asarray(position, np.float64)
    if t.ndim != 1 or p.shape != (len(t), 3):
        raise ValueError(f"position: shape {p.shape}, need ({len(t)}, 3) for t_s of shape {t.shape}")
    for name, a in (("t_s", t), ("position", p)):
        if not np.isfinite(a).all():
            bad = np.argwhere(~np.isfinite(a))[0]
            raise ValueError(f"{name}[{', '.join(map(str, bad))}]: {a[tuple(bad)]} is not finite")
    n = len(t)
    if n > 1 and not (np.diff(t) > 0.0).all():
        i = int(np.argmin(np.diff(t) > 0.0)) + 1
        raise ValueError(f"t_s[{i}]: {t[i]} does not come after t_s[{i - 1}] = {t[i - 1]}")
    if n < 2:
        return AttitudeEstimate(np.zeros((n, 3)), np.zeros(n, bool), assumptions())
    path = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])))])
    idx = np.arange(n)

    # Motion: heading, speed, turn rate.
    lo, hi = _window(t, np.full(n, MOTION_WINDOW_S / 2.0))
    prefix = _prefix(np.column_stack([t, p]))
    first, second = _half_means(prefix, lo, idx, hi)
    d = second - first
    # lo < i or i < hi whenever n >= 2 (_window), and times increase: d_t > 0, no 0 / 0.
    d_t = d[:, 0]
    displacement = np.hypot(d[:, 1], d[:, 2])
    ground_speed = displacement / d_t
    moving = (displacement >= MOVING_DISPLACEMENT_M) & (ground_speed >= MIN_TRACK_SPEED_MPS)
    track = np.degrees(np.arctan2(d[:, 1], d[:, 2]))
    if moving.any():
        last = np.where(moving, idx, -1)
        np.maximum.accumulate(last, out=last)  # last moving record at or before each one
        last[last < 0] = int(np.argmax(moving))
        track = track[last]
    else:
        track = np.zeros(n)
    # Limited before the turn rate is taken, so that the bank is that of the heading shown.
    unwrapped = _rate_limited(t, np.degrees(np.unwrap(np.radians(track))), MAX_HEADING_RATE_DPS,
                              np.zeros(n, bool))
    h_first, h_second = _half_means(_prefix(unwrapped[:, None]), lo, idx, hi)
    turn_rate = np.radians(h_second[:, 0] - h_first[:, 0]) / d_t
    # Along the path rather than between the half means: a chord cuts a tight turn short.
    path_speed = (path[hi] - path[lo]) / (t[hi] - t[lo])  # lo < hi when n >= 2
    bank = np.clip(np.degrees(np.arctan(path_speed * turn_rate / G_MPS2)), -MAX_BANK_DEG, MAX_BANK_DEG)

    # Ground roll: slow and near the lowest smoothed height around.
    height = (prefix[hi + 1, 3] - prefix[lo, 3]) / (hi - lo + 1)
    g_lo, g_hi = _window(t, np.full(n, GROUND_WINDOW_S / 2.0))
    ground_level = _range_min(height, g_lo, g_hi)
    on_ground = (ground_speed < TAKEOFF_SPEED_MPS) & (height - ground_level < GROUND_HEIGHT_M)

    # Flight path: the climb over a window of PITCH_WINDOW_M of path and PITCH_WINDOW_S.
    half = _pitch_half_width(t, path)
    lo, hi = _window(t, half)
    first, second = _half_means(_prefix(np.column_stack([path, p[:, 2]])), lo, idx, hi)
    run, rise = second[:, 0] - first[:, 0], second[:, 1] - first[:, 1]
    # run > 0 wherever the window has path (path is non-decreasing and the record is in both
    # halves); too_slow covers every window without enough of it, so atan2 never sees 0 / 0.
    too_slow = path[hi] - path[lo] < PITCH_WINDOW_M
    pitch = np.clip(np.degrees(np.arctan2(rise, np.maximum(run, 1e-9))), -MAX_PITCH_DEG, MAX_PITCH_DEG)

    level = on_ground | ~moving
    pitch = _rate_limited(t, np.where(level | too_slow, 0.0, pitch), MAX_PITCH_RATE_DPS, on_ground)
    bank = _rate_limited(t, np.where(level, 0.0, bank), MAX_BANK_RATE_DPS, on_ground)
    heading = unwrapped % 360.0
    heading = np.where(heading >= 360.0, 0.0, heading)
    return AttitudeEstimate(np.stack([heading, pitch, bank], axis=-1), on_ground, assumptions())


def _window(t: np.ndarray, half_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Record index ranges [lo, hi] of windows t +- half_s: from the last record at or before
    the start to the first at or after the end (so at least one neighbour each side, where
    there is one), clipped to the track."""
    n = len(t)
    lo = np.clip(np.searchsorted(t, t - half_s, side="right") - 1, 0, n - 1)
    hi = np.clip(np.searchsorted(t, t + half_s, side="left"), 0, n - 1)
    return lo, hi


def _prefix(values: np.ndarray) -> np.ndarray:
    """(n + 1, k) running sums of (n, k) values from 0, for means over index ranges. The values
    are taken relative to the first record so that the sums stay small."""
    return np.concatenate([np.zeros((1, values.shape[1])), np.cumsum(values - values[0], axis=0)])


def _half_means(prefix: np.ndarray, lo: np.ndarray, i: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Means of records [lo, i] and [i, hi] from running sums, for Wald's grouping estimate of a
    slope (A. Wald, The fitting of straight lines if both variables are subject to error, 1940):
    the difference of the halves' means of y over that of x. Record i is in both halves, so three
    records give the central difference. Each half has at least record i: no 0 / 0."""
    first = (prefix[i + 1] - prefix[lo]) / (i - lo + 1)[:, None]
    second = (prefix[hi + 1] - prefix[i]) / (hi - i + 1)[:, None]
    return first, second


def _pitch_half_width(t: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Half-width, seconds, of each record's pitch window: the least that covers PITCH_WINDOW_M
    of path (path interpolated in time, clamped at the track's ends) and PITCH_WINDOW_S,
    at most PITCH_WINDOW_MAX_S / 2. Bisection: the path covered only grows with the width."""
    def covered(h: np.ndarray) -> np.ndarray:
        return np.interp(t + h, t, path) - np.interp(t - h, t, path)

    low = np.full(len(t), PITCH_WINDOW_S / 2.0)
    high = np.full(len(t), PITCH_WINDOW_MAX_S / 2.0)
    for _ in range(30):  # (30 - 5) s / 2^30: well under a microsecond
        mid = 0.5 * (low + high)
        enough = covered(mid) >= PITCH_WINDOW_M
        high, low = np.where(enough, mid, high), np.where(enough, low, mid)
    return np.where(covered(low) >= PITCH_WINDOW_M, low, high)


def _range_min(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min(values[lo:hi + 1]) for each range, by a sparse table of minima over power-of-two spans
    (Bender and Farach-Colton, The LCA problem revisited, 2000): a range is covered by two
    overlapping spans of the largest power of two that fits in it."""
    table = [values]  # table[k][j] = min(values[j:j + 2^k])
    while (1 << len(table)) <= len(values):
        span = 1 << (len(table) - 1)
        table.append(np.minimum(table[-1][:-span], table[-1][span:]))
    level = np.frexp(hi - lo + 1)[1] - 1  # floor(log2(count)), exactly; count >= 1
    out = np.empty(len(lo))
    for k in np.unique(level):
        m = level == k
        out[m] = np.minimum(table[k][lo[m]], table[k][hi[m] - (1 << k) + 1])
    return out


def _rate_limited(t: np.ndarray, x: np.ndarray, rate: float, zero: np.ndarray) -> np.ndarray:
    """x changed as little as possible to change by at most rate per second between records
    while staying 0 where zero is True (ground roll stays level: the ramp to and from it happens
    in the air).

    x is first clamped to +-rate x the time to the nearest zero record, which every sequence
    holding both constraints obeys; then it is clamped forwards, then backwards. Each pass keeps
    that bound (a clamp only moves a value towards its neighbour's reachable range), so the zeros
    stay 0, and the backward pass keeps the forward pass's bound on each step, so both hold.
    """
    if zero.any():
        at = t[zero]
        k = np.clip(np.searchsorted(at, t), 1, len(at) - 1) if len(at) > 1 else np.zeros(len(t), int)
        nearest = np.minimum(np.abs(t - at[k]), np.abs(t - at[np.maximum(k - 1, 0)]))
        x = np.clip(x, -rate * nearest, rate * nearest)
    step = rate * np.diff(t)
    out = x.astype(np.float64).tolist()
    for i in range(1, len(out)):
        out[i] = min(max(out[i], out[i - 1] - step[i - 1]), out[i - 1] + step[i - 1])
    for i in range(len(out) - 2, -1, -1):
        out[i] = min(max(out[i], out[i + 1] - step[i]), out[i + 1] + step[i])
    result = np.array(out)
    result[zero] = 0.0  # rate x (t1 - t0) and rate x t1 - rate x t0 differ by a rounding
    return result
