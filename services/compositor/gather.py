"""Frame gathering and synchronisation checks, without a network.

A frame is complete when every channel of the rig has delivered an image of it, each rendered
from exactly (bitwise) the eyepoint the host published for that frame number. Complete frames
go to the stitcher; every other outcome is counted by cause and never stitched silently.
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ig.v1 import compositor_pb2, frame_pb2

# Causes of an incomplete frame.
MISSING_CHANNEL = "missing_channel"
EYEPOINT_MISMATCH = "eyepoint_mismatch"
# Causes of a rejected submission.
UNKNOWN_CHANNEL = "unknown_channel"
BAD_EYEPOINT = "non_finite_eyepoint"
BAD_PIXELS = "bad_pixels"
DUPLICATE = "duplicate_image"


class InvalidSubmission(ValueError):
    """A submission the compositor refuses; the message names the field and value."""

    def __init__(self, cause: str, message: str) -> None:
        super().__init__(message)
        self.cause = cause


@dataclass(frozen=True)
class ChannelImage:
    """A validated channel image."""

    channel: str
    rgb: np.ndarray  # (H, W, 3) float16 linear
    eyepoint: tuple[float, ...]
    render_time_s: float
    control_sample_time: float
    frames_skipped: int


@dataclass(frozen=True)
class CompleteFrame:
    """A frame ready to stitch: images in rig channel order."""

    frame_number: int
    sim_time_s: float
    eyepoint: tuple[float, ...]
    images: tuple[ChannelImage, ...]


@dataclass
class _Pending:
    images: dict[str, ChannelImage] = field(default_factory=dict)


def eyepoint_tuple(msg: frame_pb2.Eyepoint) -> tuple[float, ...]:
    return (msg.x, msg.y, msg.z, msg.heading_deg, msg.pitch_deg, msg.roll_deg)


_EYE_FIELDS = ("x", "y", "z", "heading_deg", "pitch_deg", "roll_deg")


def percentiles(values: Sequence[float]) -> dict[str, float | None]:
    """p50, p95, p99 in milliseconds (None without data)."""
    if not values:
        return {"p50_ms": None, "p95_ms": None, "p99_ms": None, "count": 0}
    a = np.asarray(values) * 1000.0
    return {"p50_ms": round(float(np.percentile(a, 50)), 3), "p95_ms": round(float(np.percentile(a, 95)), 3),
            "p99_ms": round(float(np.percentile(a, 99)), 3), "count": int(a.size)}


class FrameGatherer:
    """Collects channel images per frame number and decides each frame's fate.

    Args:
        channels: rig channel names in display order.
        on_complete: called (outside the lock) with every complete frame, in frame order.
        clock: wall clock (UNIX seconds) for latency figures.
    """

    def __init__(self, channels: Sequence[str], on_complete: Callable[[CompleteFrame], None],
                 clock: Callable[[], float] = time.time) -> None:
        self.channels = tuple(channels)
        self.on_complete = on_complete
        self.clock = clock
        self._lock = threading.Lock()
        self._published: dict[int, tuple[tuple[float, ...], float]] = {}
        self._pending: dict[int, _Pending] = {}
        self._final: dict[int, str] = {}  # frame number -> "complete" or incomplete cause
        self.frames_published = 0
        self.complete = 0
        self.incomplete: Counter[str] = Counter()
        self.late_images = 0
        self.rejected: Counter[str] = Counter()
        self.last_rejection = ""
        self.render_times: dict[str, list[float]] = {c: [] for c in self.channels}
        self.skipped: dict[str, int] = {c: 0 for c in self.channels}
        self.latencies: list[float] = []
        self.run_id = ""

    # --- inputs -----------------------------------------------------------------------------
    def on_published(self, frame: frame_pb2.Frame) -> None:
        """The host published a frame (from the observer stream)."""
        ready = []
        with self._lock:
            self.run_id = frame.run_id
            self.frames_published += 1
            self._published[frame.frame_number] = (eyepoint_tuple(frame.eyepoint), frame.sim_time_s)
            ready = self._settle(frame.frame_number)
        self._emit(ready)

    def submit(self, request: compositor_pb2.SubmitChannelImageRequest) -> None:
        """A channel delivered an image.

        Raises:
            InvalidSubmission: unknown channel, non-finite eyepoint, pixels of the wrong size or
                format, a second image for the same channel and frame. Counted by cause.
        """
        try:
            image = self._validate(request)
        except InvalidSubmission as exc:
            with self._lock:
                self.rejected[exc.cause] += 1
                self.last_rejection = str(exc)
            raise
        number = request.frame_number
        with self._lock:
            self.render_times[image.channel].append(image.render_time_s)
            self.skipped[image.channel] = max(self.skipped[image.channel], image.frames_skipped)
            if number in self._final:
                self.late_images += 1
                return
            pending = self._pending.setdefault(number, _Pending())
            if image.channel in pending.images:
                self.rejected[DUPLICATE] += 1
                raise InvalidSubmission(DUPLICATE, f"channel_name: {image.channel!r} already delivered frame {number}")
            pending.images[image.channel] = image
            ready = self._settle(number)
        self._emit(ready)

    def finalize_all(self) -> None:
        """End of run: every frame not yet decided is incomplete."""
        with self._lock:
            for number in sorted(set(self._pending) | set(self._published)):
                if number not in self._final:
                    self._finalize(number, MISSING_CHANNEL)

    # --- decisions ----------------------------------------------------------------------------
    def _validate(self, r: compositor_pb2.SubmitChannelImageRequest) -> ChannelImage:
        if r.channel_name not in self.channels:
            raise InvalidSubmission(UNKNOWN_CHANNEL, f"channel_name: {r.channel_name!r} is not a channel of the rig "
                                                     f"({', '.join(self.channels)})")
        for name in _EYE_FIELDS:
            value = getattr(r.eyepoint, name)
            if not math.isfinite(value):
                raise InvalidSubmission(BAD_EYEPOINT, f"eyepoint.{name}: {value} is not finite")
        if r.pixel_format != compositor_pb2.PIXEL_FORMAT_RGB_F16:
            raise InvalidSubmission(BAD_PIXELS, f"pixel_format: {r.pixel_format} is not PIXEL_FORMAT_RGB_F16")
        expected = r.width * r.height * 3 * 2
        if r.width == 0 or r.height == 0 or len(r.pixels) != expected:
            raise InvalidSubmission(BAD_PIXELS, f"pixels: {len(r.pixels)} bytes, expected {expected} for "
                                                f"{r.width} x {r.height} RGB half floats")
        rgb = np.frombuffer(r.pixels, dtype="<f2").reshape(r.height, r.width, 3)
        return ChannelImage(r.channel_name, rgb, eyepoint_tuple(r.eyepoint), r.render_time_s,
                            r.control_sample_time_unix_s, r.frames_skipped)

    def _settle(self, number: int) -> list[CompleteFrame]:
        """Decide frame number if it can be decided now (lock held); older open frames that
        can no longer complete are finalised as incomplete."""
        pending = self._pending.get(number)
        if pending is None or number not in self._published or len(pending.images) < len(self.channels):
            return []
        eyepoint, sim_time = self._published[number]
        if any(img.eyepoint != eyepoint for img in pending.images.values()):
            self._finalize(number, EYEPOINT_MISMATCH)
            return []
        # Frames are rendered in order: once a newer frame is complete, older open ones never will be.
        for older in [n for n in set(self._pending) | set(self._published) if n < number]:
            if older not in self._final:
                self._finalize(older, MISSING_CHANNEL)
        images = tuple(pending.images[c] for c in self.channels)
        self._finalize(number, "complete")
        now = self.clock()
        self.latencies.append(now - images[0].control_sample_time)
        return [CompleteFrame(number, sim_time, eyepoint, images)]

    def _finalize(self, number: int, outcome: str) -> None:
        self._final[number] = outcome
        self._pending.pop(number, None)
        self._published.pop(number, None)
        if outcome == "complete":
            self.complete += 1
        else:
            self.incomplete[outcome] += 1

    def _emit(self, ready: list[CompleteFrame]) -> None:
        for frame in ready:
            self.on_complete(frame)

    # --- report -------------------------------------------------------------------------------
    def report(self) -> dict:
        """Counters and latency figures as a JSON-ready dict."""
        with self._lock:
            return {
                "run_id": self.run_id,
                "channels": list(self.channels),
                "frames_published": self.frames_published,
                "frames_complete": self.complete,
                "frames_incomplete": {MISSING_CHANNEL: self.incomplete[MISSING_CHANNEL],
                                      EYEPOINT_MISMATCH: self.incomplete[EYEPOINT_MISMATCH]},
                "frames_pending": len(set(self._pending) | set(self._published)),
                "late_images": self.late_images,
                "rejected_submissions": dict(sorted(self.rejected.items())),
                "last_rejection": self.last_rejection,
                "render_time": {c: percentiles(v) for c, v in self.render_times.items()},
                "control_to_composite_latency": percentiles(self.latencies),
                "frames_skipped": dict(self.skipped),
            }
