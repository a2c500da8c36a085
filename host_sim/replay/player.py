"""Replay of a track at frame times: speed, start time, loop (docs/replay-formats.md).

The eyepoint of simulation time t is the track's at log time start + speed * t (wrapped back
to start at the end when looping): a pure function of t, so a replay is identical frame by
frame on every run and whatever the rig's speed.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

from services.rig.frame import Eyepoint

from .track import Track


@dataclass(frozen=True)
class ReplayStatus:
    """Where a replay is (mirrors ig.v1.ReplayStatus, with the track's problem counts)."""

    path: str
    format: str
    records: int
    log_duration_s: float
    log_time_s: float
    loops: int
    attitude_estimated: bool
    problems: dict[str, int]


class Replay:
    """Eyepoints of a track at simulation times (module doc).

    Args:
        track: the cleaned log.
        speed: log seconds per simulated second (2 plays twice as fast).
        start_s: log time of simulation time 0, seconds from the first record.
        loop: start again at start_s after the end of the log.
        path, format: for the status.

    Raises:
        ValueError: speed not > 0, or start_s outside the log (naming the log's length).
    """

    def __init__(self, track: Track, *, speed: float = 1.0, start_s: float = 0.0, loop: bool = False,
                 path: str = "", format: str = "") -> None:
        if not (speed > 0 and math.isfinite(speed)):
            raise ValueError(f"speed: {speed} must be a finite number > 0")
        if not (0.0 <= start_s < track.duration_s):
            raise ValueError(f"start: {start_s} s is outside the log (0 .. {track.duration_s:.3f} s)")
        self.track = track
        self.speed = float(speed)
        self.start_s = float(start_s)
        self.loop = loop
        self.path, self.format = path, format
        self._lock = threading.Lock()
        self._log_time = self.start_s
        self._loops = 0

    @property
    def duration_s(self) -> float:
        """Simulated seconds from start_s to the end of the log (inf when looping)."""
        return math.inf if self.loop else (self.track.duration_s - self.start_s) / self.speed

    def log_time(self, t_s: float) -> tuple[float, int]:
        """(log time, completed loops) of simulation time t_s (clamped at 0 and, without loop,
        at the end of the log)."""
        elapsed = max(float(t_s), 0.0) * self.speed
        span = self.track.duration_s - self.start_s
        if self.loop and math.isfinite(elapsed):
            loops, into = divmod(elapsed, span)
            return self.start_s + into, int(loops)
        return min(self.start_s + elapsed, self.track.duration_s), 0

    def eyepoint_at(self, t_s: float) -> Eyepoint:
        """The eyepoint at simulation time t_s.

        Raises:
            ValueError: t_s is NaN.
        """
        if math.isnan(t_s):
            raise ValueError("t_s: nan is not a time")
        log_t, loops = self.log_time(t_s)
        with self._lock:
            self._log_time, self._loops = log_t, loops
        return self.track.sample(log_t)

    def status(self) -> ReplayStatus:
        """Where the replay is and what the log held."""
        with self._lock:
            log_t, loops = self._log_time, self._loops
        return ReplayStatus(self.path, self.format, len(self.track.t_s), self.track.duration_s, log_t, loops,
                            self.track.attitude_estimated, dict(self.track.problems))
