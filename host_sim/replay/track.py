"""A flight log made into a track that can be sampled at any time (docs/replay-formats.md).

The readers give a RawLog: records in file order, as found. build_track() puts them in time
order, drops duplicates, finds gaps, converts geodetic positions to the world's east-north-up
frame and fills in the attitude when the log has none; every problem is counted in the
track's report. sample() gives the eyepoint at a log time: positions on a cubic Hermite curve
through the records (smooth: continuous velocity), attitudes by quaternion slerp.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from services.rig import geodetic
from services.rig.frame import Eyepoint

from . import attitude

log = logging.getLogger("ig.host.replay")

#: Problems counted while reading and building a track; every one is a key of the report.
PROBLEMS = (
    "corrupt",       # a record that cannot be parsed, or with a non-finite or impossible field
    "no_fix",        # a record the logger marked as having no valid position (IGC 'V')
    "duplicate",     # a record with the same time as an earlier one (the first is kept)
    "out_of_order",  # a record with a time before an earlier record's (sorted into place)
    "gap",           # an interval longer than the gap threshold (bridged by a straight line)
)
#: An interval is a gap when longer than GAP_FACTOR x the median interval and GAP_MIN_S.
GAP_FACTOR = 5.0
GAP_MIN_S = 1.0
#: Problems named in the report (the counters keep counting past them).
_NOTED = 10


@dataclass
class RawLog:
    """Records of a log in file order, as a reader found them.

    Attributes:
        times: record times, seconds (any origin).
        coords: (n, 3): latitude deg, longitude deg, height m when geodetic, else world
            x, y, z metres.
        geodetic: what coords hold.
        hpr: (n, 3) heading, pitch, roll degrees, or None when the log has no attitude.
        problems: counts by cause (PROBLEMS) found by the reader.
        notes: the first few problems, with their line or record numbers.
    """

    times: list[float] = field(default_factory=list)
    coords: list[tuple[float, float, float]] = field(default_factory=list)
    geodetic: bool = True
    hpr: list[tuple[float, float, float]] | None = None
    problems: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PROBLEMS, 0))
    notes: list[str] = field(default_factory=list)

    def problem(self, cause: str, note: str) -> None:
        """Count a problem and keep its note if it is one of the first."""
        self.problems[cause] += 1
        if sum(self.problems.values()) <= _NOTED:
            self.notes.append(f"{cause}: {note}")


@dataclass(frozen=True)
class Track:
    """A cleaned log, ready to sample.

    Attributes:
        t_s: (n,) strictly increasing times, seconds from the first record.
        position: (n, 3) float64 world (east, north, up) metres.
        quat: (n, 4) attitudes as quaternions (attitude.py), neighbours on one hemisphere.
        gap: (n - 1,) True where the interval after a record is a gap.
        tangent: (n, 3) velocity at each record for the Hermite curve, m/s.
        attitude_estimated: the log had no attitude; it was estimated from the track.
        problems: counts by cause (PROBLEMS).
        notes: the first few problems.
        origin: the geodetic reference point (lat deg, lon deg, h m) of the world frame, or
            None for a log already in world coordinates.
        start_time: time of the first record in the log's own time base, seconds.
    """

    t_s: np.ndarray
    position: np.ndarray
    quat: np.ndarray
    gap: np.ndarray
    tangent: np.ndarray
    attitude_estimated: bool
    problems: dict[str, int]
    notes: list[str]
    origin: tuple[float, float, float] | None
    start_time: float

    @property
    def duration_s(self) -> float:
        """Time from the first record to the last, seconds."""
        return float(self.t_s[-1])

    def sample(self, t_s: float) -> Eyepoint:
        """The eyepoint at t_s seconds from the first record (clamped to the track).

        Raises:
            ValueError: t_s is NaN.
        """
        t = float(t_s)
        if math.isnan(t):
            raise ValueError("t_s: nan is not a time")
        t = min(max(t, 0.0), self.duration_s)
        i = min(int(np.searchsorted(self.t_s, t, side="right")) - 1, len(self.t_s) - 2)
        h = float(self.t_s[i + 1] - self.t_s[i])
        s = (t - float(self.t_s[i])) / h
        p0, p1 = self.position[i], self.position[i + 1]
        if self.gap[i]:
            pos = p0 + s * (p1 - p0)  # across a gap a curve would invent a path: go straight
        else:
            s2, s3 = s * s, s * s * s
            pos = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * self.tangent[i]
                   + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * h * self.tangent[i + 1])
        heading, pitch, roll = attitude.to_hpr(attitude.slerp(self.quat[i], self.quat[i + 1], s))
        return Eyepoint.of(float(pos[0]), float(pos[1]), float(pos[2]), heading, pitch, roll)


def build_track(raw: RawLog, *, origin: tuple[float, float, float] | None = None, name: str = "log") -> Track:
    """Clean a raw log into a Track (module doc).

    Args:
        raw: the records as read.
        origin: geodetic reference (lat deg, lon deg, h m) of the world frame; default the
            first record in time. Ignored for logs in world coordinates.
        name: the log's name, for messages.

    Raises:
        ValueError: fewer than two usable records (naming the log and what was found).
    """
    problems, notes = dict(raw.problems), list(raw.notes)

    def problem(cause: str, note: str) -> None:
        problems[cause] += 1
        if sum(problems.values()) <= _NOTED:
            notes.append(f"{cause}: {note}")

    times = np.asarray(raw.times, np.float64)
    coords = np.asarray(raw.coords, np.float64).reshape(-1, 3)
    hpr = None if raw.hpr is None else np.asarray(raw.hpr, np.float64).reshape(-1, 3)
    # Out of order: a record earlier than one before it. A stable sort keeps the file order of
    # equal times, so the first of duplicates is kept.
    latest = np.maximum.accumulate(times) if len(times) else times
    for i in np.flatnonzero(times[1:] < latest[:-1]) + 1:
        problem("out_of_order", f"record {i + 1} at t={times[i]:.3f} s comes after t={latest[i - 1]:.3f} s")
    order = np.argsort(times, kind="stable")
    times, coords = times[order], coords[order]
    hpr = None if hpr is None else hpr[order]
    keep = np.ones(len(times), bool)
    keep[1:] = np.diff(times) > 0.0
    for i in np.flatnonzero(~keep):
        problem("duplicate", f"a second record at t={times[i]:.3f} s (the first is kept)")
    times, coords = times[keep], coords[keep]
    hpr = None if hpr is None else hpr[keep]
    if len(times) < 2:
        found = ", ".join(f"{k} {v}" for k, v in problems.items() if v) or "no problems"
        raise ValueError(f"{name}: {len(times)} usable record(s), need at least 2 ({found})")

    if raw.geodetic:
        origin = origin or (float(coords[0, 0]), float(coords[0, 1]), float(coords[0, 2]))
        position = geodetic.enu(coords[:, 0], coords[:, 1], coords[:, 2], origin)
    else:
        origin, position = None, coords.copy()
    t = times - times[0]

    dt = np.diff(t)
    threshold = max(GAP_FACTOR * float(np.median(dt)), GAP_MIN_S)
    gap = dt > threshold
    for i in np.flatnonzero(gap):
        problem("gap", f"{dt[i]:.1f} s without records after t={t[i]:.3f} s (gaps are over {threshold:.1f} s)")

    estimated = hpr is None
    if hpr is None:
        hpr = attitude.estimate(t, position)
    quat = attitude.continuous(attitude.from_hpr(hpr))
    track = Track(t, position, quat, gap, _tangents(t, position, gap), estimated, problems, notes, origin,
                  float(times[0]))
    for a in (track.t_s, track.position, track.quat, track.gap, track.tangent):
        a.setflags(write=False)
    return track


def _tangents(t: np.ndarray, p: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Velocity at each record: the time-weighted mean of the slopes on either side
    (Catmull-Rom for uneven spacing), using only a side that is not a gap."""
    slope = np.diff(p, axis=0) / np.diff(t)[:, None]
    h = np.diff(t)
    out = np.zeros_like(p)
    for i in range(len(t)):
        left = i > 0 and not gap[i - 1]
        right = i < len(t) - 1 and not gap[i]
        if left and right:
            out[i] = (slope[i - 1] * h[i - 1] + slope[i] * h[i]) / (h[i - 1] + h[i])
        elif left:
            out[i] = slope[i - 1]
        elif right:
            out[i] = slope[i]
    return out
