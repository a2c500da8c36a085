"""The composite and where its time went: the hops from the host's control sample to the
stitched frame in memory (docs/latency.md).

A frame's way through the rig is a chain of wall-clock time stamps: the host samples the
controls and publishes the frame; each worker receives it, renders it and submits its image;
the compositor receives the images and, once it has every channel's, stitches the composite.
The composite waits for the channel whose image came last, so the chain is taken along that
channel (the critical one): its hops then add up exactly to control sample -> composite.
"""

from __future__ import annotations

import threading
from collections import Counter, deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .gather import MAX_SAMPLES, ChannelImage, CompleteFrame, percentiles

#: The hops of a frame's chain, in order: (report key, what it spans). Their sum is the
#: control-to-composite latency.
HOPS: tuple[tuple[str, str], ...] = (
    ("host_sample_to_publish", "host: control sample -> frame published (flight model, eyepoint)"),
    ("publish_to_worker_receive", "host -> worker: frame stream"),
    ("worker_receive_to_render_start", "worker: mailbox -> render start"),
    ("render", "worker: render"),
    ("render_end_to_compositor_receive", "worker -> compositor: encode, send (or share), receive"),
    ("compositor_receive_to_composite", "compositor: last image received -> composite stitched"),
)


@dataclass(frozen=True)
class Composite:
    """A complete frame stitched in memory: what a display output would show.

    Attributes:
        frame: the complete frame (its images, eyepoint, host time stamps).
        rgb: (H, sum of widths, 3) float16 linear RGB or uint8 sRGB (stitch.stitch_format), the
            channels side by side in rig order.
        time: UNIX seconds when the stitch was done (the composite time latency is measured to).
    """

    frame: CompleteFrame
    rgb: np.ndarray
    time: float


def critical_image(frame: CompleteFrame) -> ChannelImage:
    """The image the composite waited for: the one the compositor received last."""
    return max(frame.images, key=lambda img: img.timing.compositor_receive)


def hop_seconds(stamps: Sequence[float]) -> dict[str, float] | None:
    """Seconds spent in each hop of HOPS from the chain's seven time stamps in order (control
    sample, publish, worker receive, render start, render end, compositor receive, composite,
    UNIX seconds); None when one is missing (0: a worker that does not report them)."""
    if len(stamps) != len(HOPS) + 1:
        raise ValueError(f"stamps: {len(stamps)} time stamps, expected {len(HOPS) + 1}")
    if not all(stamps):
        return None
    return {key: b - a for (key, _), a, b in zip(HOPS, stamps[:-1], stamps[1:], strict=True)}


def chain(composite: Composite) -> dict[str, float] | None:
    """hop_seconds of a composite, along its critical channel."""
    frame = composite.frame
    t = critical_image(frame).timing
    return hop_seconds((frame.control_sample_time, frame.publish_time, t.frame_received, t.render_start,
                        t.render_end, t.compositor_receive, composite.time))


@dataclass(frozen=True)
class Figures:
    """What one composite took (TimingStats.add), seconds.

    Attributes:
        latency: control sample -> composite.
        hops: the chain's hops (HOPS' keys), None when a worker did not stamp them.
        interval: since the run's composite before it; None for the first.
    """

    latency: float
    hops: dict[str, float] | None
    interval: float | None


class TimingStats:
    """Per-frame latency, hops and composite intervals of a run, summarised for the report."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        # The figures cover the run's last MAX_SAMPLES composites: a rig runs for hours, and its
        # compositor's memory must not grow with the run.
        self.latencies: deque[float] = deque(maxlen=MAX_SAMPLES)
        self.hops: dict[str, deque[float]] = {key: deque(maxlen=MAX_SAMPLES) for key, _ in HOPS}
        self.critical: Counter[str] = Counter()
        self.intervals: deque[float] = deque(maxlen=MAX_SAMPLES)
        self._first_time: float | None = None
        self._last_time: float | None = None
        # The external host's frames (CIGI): which reached the screen, and in what order.
        self.host_frames: dict[str, Any] = {"composites": 0, "first": None, "last": None, "repeated": 0,
                                            "skipped": 0}

    def add(self, composite: Composite) -> Figures:
        """Account for one composite (composites arrive in frame order); returns its figures."""
        hops = chain(composite)
        latency = composite.time - composite.frame.control_sample_time
        interval = None
        with self._lock:
            self.latencies.append(latency)
            if self._last_time is not None:
                interval = composite.time - self._last_time
                self.intervals.append(interval)
            else:
                self._first_time = composite.time
            self._last_time = composite.time
            self._count_host_frame(composite.frame.host_frame_number)
            if hops is not None:
                for key, seconds in hops.items():
                    self.hops[key].append(seconds)
                self.critical[critical_image(composite.frame).channel] += 1
        return Figures(latency, hops, interval)

    def _count_host_frame(self, number: int | None) -> None:
        """A composite of an external host's frame: repeated (the host did not keep pace and
        its last eyepoint was shown again) or skipped frames of the host (counted mod 2^32)."""
        if number is None:
            return
        h = self.host_frames
        last = h["last"]
        if last is not None:
            step = (number - last) % (1 << 32)
            if step == 0:
                h["repeated"] += 1
            elif step < 1 << 31:
                h["skipped"] += step - 1
        if h["first"] is None:
            h["first"] = number
        h["composites"] += 1
        h["last"] = number

    def report(self) -> dict:
        """The report's timing keys (docs/frame-lock.md, docs/latency.md).

        The samples are copied under the lock and summarised outside it, as the gatherer's
        report does: the lock is taken for every composite."""
        with self._lock:
            latencies, intervals = list(self.latencies), list(self.intervals)
            hops = {key: list(v) for key, v in self.hops.items()}
            critical = dict(sorted(self.critical.items()))
            first, last = self._first_time, self._last_time
            host_frames = dict(self.host_frames) if self.host_frames["composites"] else None
        median = float(np.median(intervals)) if intervals else 0.0
        return {
            "control_to_composite_latency": percentiles(latencies),
            "latency_chain": {key: percentiles(v) for key, v in hops.items()},
            "critical_channel": critical,
            "composite_interval": percentiles(intervals),
            # The rate the rig sustained: the median interval, so that the first frames of a
            # run (pages of terrain loading) do not count for the whole run.
            "composite_rate_hz": round(1.0 / median, 3) if median > 0 else None,
            # Wall-clock times (UNIX seconds) of the run's first and last composite: when
            # the picture first appeared and how long the run showed it (`ig demo` reports
            # its time to the first stitched frame from them); None before any.
            "first_composite_time": first,
            "last_composite_time": last,
            **({"host_frames": host_frames} if host_frames is not None else {}),
        }
