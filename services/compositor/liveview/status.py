"""What the live view's page shows besides the picture (status.json): each channel's state, the
run's frames complete and incomplete by cause, control-to-composite latency (the run's p50 and
p99, and a minute of it second by second for the plot), the seam check, and the view's own
counts.

The run's numbers are read from the compositor's report document (Compositor.report), the one
report.json is written from, so the page and the file never disagree. Reading it takes the
gatherer's lock while it computes its percentiles, as GetCompositorReport does: StatusBoard
reads it at most once every STATUS_EVERY_S, however many browsers ask.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .frames import FrameSource

#: Longest the page's numbers are reused, seconds (the page asks once a second).
STATUS_EVERY_S = 1.0
#: A channel's state says what happened to it within this many seconds.
STATE_WINDOW_S = 3.0

#: A channel's states, worst first: an image missing from a frame finalised incomplete; an
#: image that came after its frame was decided; images coming; nothing for STATE_WINDOW_S (no
#: run, the run over, or the host paused).
MISSING, LATE, RENDERING, IDLE = "missing", "late", "rendering", "idle"


class ChannelStates:
    """Each channel's state from the report's counters, by what changed within STATE_WINDOW_S.

    Args:
        channels: rig channel names.
        clock: monotonic seconds.
    """

    def __init__(self, channels: Sequence[str], *, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._last: dict[tuple[str, str], int] = {}
        self._changed: dict[tuple[str, str], float] = {}
        self.channels = tuple(channels)

    def update(self, report: Mapping[str, Any]) -> dict[str, str]:
        """The state of every channel after the report's counters (a new run's counters start
        again from 0: any change counts)."""
        now = self.clock()
        states = {}
        for channel in self.channels:
            counts = channel_counts(report, channel)
            for key in (MISSING, LATE, RENDERING):
                if self._last.get((channel, key), 0) != counts[key]:
                    self._changed[channel, key] = now
                self._last[channel, key] = counts[key]
            recent = [key for key in (MISSING, LATE, RENDERING)
                      if now - self._changed.get((channel, key), -np.inf) <= STATE_WINDOW_S]
            states[channel] = recent[0] if recent else IDLE
        return states


def channel_counts(report: Mapping[str, Any], channel: str) -> dict[str, int]:
    """A channel's counts in the report: images taken (rendering), missing, late."""
    wire = report["wire"]["channels"].get(channel, {})
    return {RENDERING: int(wire.get("srgb8", 0)) + int(wire.get("half", 0)),
            MISSING: int(report["missing_by_channel"].get(channel, 0)),
            LATE: int(report["late_by_channel"].get(channel, 0))}


def latency_series(samples: Sequence[tuple[float, float]], now: float, *, window_s: float = 60.0,
                   step_s: float = 1.0) -> list[list[float]]:
    """Control-to-composite latency second by second for the plot: [seconds before now (<= 0),
    p50 ms, p99 ms, composites] of each step that had composites, oldest first.

    Args:
        samples: (composite time, latency), UNIX seconds and seconds.
        now: UNIX seconds.
        window_s: how far back.
        step_s: one point per step.
    """
    if not samples:
        return []
    times = np.array([s[0] for s in samples])
    latency_ms = np.array([s[1] for s in samples]) * 1000.0
    steps = np.floor((now - times) / step_s).astype(int)
    out = []
    for k in sorted(set(steps[(steps >= 0) & (steps < window_s / step_s)].tolist()), reverse=True):
        chosen = latency_ms[steps == k]
        p50, p99 = np.percentile(chosen, [50, 99])
        out.append([-(k + 0.5) * step_s, round(float(p50), 3), round(float(p99), 3), int(chosen.size)])
    return out


class StatusBoard:
    """status.json: the report's numbers and the view's, computed at most every STATUS_EVERY_S.

    Args:
        report: the compositor's report of its current run (Compositor.report).
        channels: rig channel names, in display order.
        frames: the view's frames: its counts, the frame shown, the recent latencies.
        clock: UNIX seconds.
    """

    def __init__(self, report: Callable[[], dict], channels: Sequence[str], frames: FrameSource, *,
                 clock: Callable[[], float] = time.time) -> None:
        self._report = report
        self.frames = frames
        self._states = ChannelStates(channels)
        self.channels = tuple(channels)
        self.clock = clock
        self._lock = threading.Lock()
        self._doc: dict | None = None
        self._at = -np.inf

    def status(self) -> dict:
        """The page's numbers (docs/live-view.md, status.json)."""
        with self._lock:
            now = time.monotonic()
            if self._doc is None or now - self._at >= STATUS_EVERY_S:
                self._doc = self._build()
                self._at = now
            doc = dict(self._doc)
        # The view's own counts and frame are cheap: always the newest.
        doc["view"] = {**self.frames.counts(), "max_rate_hz": self.frames.max_rate_hz,
                       "max_width": self.frames.max_width}
        shown = self.frames.latest
        doc["shown"] = None if shown is None else {
            "run_id": shown.run_id, "frame_number": shown.frame_number, "sim_time_s": round(shown.sim_time_s, 3),
            "width": shown.width, "height": shown.height}
        return doc

    def _build(self) -> dict:
        report = self._report()
        states = self._states.update(report)
        now = self.clock()
        latency = report["control_to_composite_latency"]
        return {
            "time": now,
            "run_id": report["run_id"],
            "run_over": report["run_over"],
            "finished": report["finished"],
            "channels": [self._channel(report, c, states[c]) for c in self.channels],
            "frames_published": report["frames_published"],
            "frames_complete": report["frames_complete"],
            "frames_incomplete": report["frames_incomplete"],
            "frames_pending": report["frames_pending"],
            "composite_rate_hz": report["composite_rate_hz"],
            "latency": {k: latency[k] for k in ("p50_ms", "p99_ms", "count")},
            "latency_series": latency_series(self.frames.latencies(now), now),
            "seams": report["seams"],
        }

    @staticmethod
    def _channel(report: Mapping[str, Any], channel: str, state: str) -> dict:
        counts = channel_counts(report, channel)
        return {"name": channel, "state": state, "images": counts[RENDERING], "missing": counts[MISSING],
                "late": counts[LATE], "render_p50_ms": report["render_time"].get(channel, {}).get("p50_ms")}
