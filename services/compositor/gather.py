"""Frame gathering and synchronisation checks, without a network.

A frame is complete when every channel of the rig has delivered an image of it, each rendered
from exactly (bitwise) the eyepoint the host published for that frame number. Complete frames
go to the stitcher; every other outcome is counted by cause and never stitched silently.
"""

from __future__ import annotations

import math
import struct
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ig.v1 import compositor_pb2, frame_pb2
from services.rig.shared_images import SharedImageError, SharedImageReader

# Causes of an incomplete frame.
MISSING_CHANNEL = "missing_channel"
EYEPOINT_MISMATCH = "eyepoint_mismatch"
INCOMPLETE_CAUSES = (MISSING_CHANNEL, EYEPOINT_MISMATCH)
# Causes of a rejected submission.
UNKNOWN_CHANNEL = "unknown_channel"
BAD_EYEPOINT = "non_finite_eyepoint"
BAD_PIXELS = "bad_pixels"
DUPLICATE = "duplicate_image"
OTHER_RUN = "other_run"
WRONG_SIZE = "wrong_size"
UNPUBLISHED = "unpublished_frame"
SHARED_UNAVAILABLE = "shared_memory_unavailable"  # the worker's segment cannot be opened here
STALE_SHARED = "stale_shared_image"  # the segment's slot no longer (or never) held the image

#: The pixel formats taken: their wire name and numpy type (services/rig/rigfile.WIRE_FORMATS).
PIXEL_FORMATS: dict[int, tuple[str, np.dtype]] = {compositor_pb2.PIXEL_FORMAT_RGB_SRGB8: ("srgb8", np.dtype(np.uint8)),
                 compositor_pb2.PIXEL_FORMAT_RGB_F16: ("half", np.dtype("<f2"))}

#: Frames beyond the last one seen published whose images are taken and held: a worker's image
#: can overtake the compositor's own copy of the frame from the host by a few milliseconds.
LOOKAHEAD_FRAMES = 4
#: Decided frames remembered, to tell a late image from an image of a frame never seen; older
#: ones count as decided (the gatherer's memory stays flat over a run of hours).
DECIDED_MEMORY = 1024
#: Samples kept of each per-frame figure (18 minutes at 60 Hz, 6 hours at the demo's 3 Hz).
MAX_SAMPLES = 65536
#: The parts of the worker -> compositor hop in the report's "wire" figures.
WIRE_HOPS = ("render_end_to_compositor_receive", "encode", "transfer")

_COMPLETE = "complete"
_EYE_FIELDS = ("x", "y", "z", "heading_deg", "pitch_deg", "roll_deg")


class InvalidSubmission(ValueError):
    """A submission the compositor refuses; the message names the field and value."""

    def __init__(self, cause: str, message: str) -> None:
        super().__init__(message)
        self.cause = cause


@dataclass(frozen=True)
class ChannelTiming:
    """Where one channel's image of a frame was when, UNIX seconds (docs/latency.md).

    The first four are the worker's wall clock, the last the compositor's: across machines they
    are only as comparable as the clocks are synchronised (deploy/README.md). 0.0: not reported
    (a worker from before these fields).

    Attributes:
        frame_received: the worker received the frame from the host.
        render_start: the worker started rendering it.
        render_end: the worker finished rendering it.
        submit: the worker handed the encoded image to gRPC (its encoding done).
        compositor_receive: the compositor had the image's pixels (read out of the message, or
            copied out of the worker's shared memory).
    """

    frame_received: float = 0.0
    render_start: float = 0.0
    render_end: float = 0.0
    submit: float = 0.0
    compositor_receive: float = 0.0


@dataclass(frozen=True)
class ChannelImage:
    """A validated channel image.

    Attributes:
        channel: rig channel name.
        rgb: (H, W, 3), top row first, as the wire carried it: float16 linear RGB or uint8
            sRGB-encoded RGB (a read-only view of the received bytes, or a copy out of the
            worker's shared memory).
        eyepoint: the eyepoint the channel rendered: x, y, z metres, heading, pitch, roll degrees.
        render_time_s: seconds the channel spent rendering.
        control_sample_time: UNIX seconds of the control sample the frame was computed from.
        frames_skipped: the worker's skipped-frame counter when it submitted.
        timing: the image's time stamps on its way to the compositor.
        shared: the pixels came through shared memory.
    """

    channel: str
    rgb: np.ndarray
    eyepoint: tuple[float, ...]
    render_time_s: float
    control_sample_time: float
    frames_skipped: int
    timing: ChannelTiming = ChannelTiming()
    shared: bool = False

    @property
    def wire(self) -> str:
        """The image's wire format: "srgb8" or "half"."""
        return "srgb8" if self.rgb.dtype == np.uint8 else "half"


@dataclass(frozen=True)
class CompleteFrame:
    """A frame ready to stitch: images in rig channel order.

    Attributes:
        frame_number: the host's frame number.
        sim_time_s: simulation time of the frame, seconds.
        eyepoint: the published eyepoint (as ChannelImage.eyepoint).
        control_sample_time: UNIX seconds of the control sample the frame was computed from.
        images: one per rig channel, in display order, left to right.
        publish_time: UNIX seconds when the host published the frame.
        run_id: the host's run.
        host_frame_number: the external simulation host's frame (CIGI), when there is one.
    """

    frame_number: int
    sim_time_s: float
    eyepoint: tuple[float, ...]
    control_sample_time: float
    images: tuple[ChannelImage, ...]
    publish_time: float = 0.0
    run_id: str = ""
    host_frame_number: int | None = None


@dataclass
class _Open:
    """A frame not decided yet: what the host published (if seen) and the images so far."""

    since: float  # monotonic seconds when the compositor first heard of the frame
    published: frame_pb2.Frame | None = None  # what the host published
    images: dict[str, ChannelImage] = field(default_factory=dict)
    nbytes: int = 0  # pixels held by images


def eyepoint_tuple(msg: frame_pb2.Eyepoint) -> tuple[float, ...]:
    """x, y, z (metres), heading, pitch, roll (degrees) of a protobuf Eyepoint."""
    return tuple(getattr(msg, name) for name in _EYE_FIELDS)


def same_bits(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    """True if two eyepoints are bitwise identical float64s (0.0 and -0.0 differ)."""
    return struct.pack("<6d", *a) == struct.pack("<6d", *b)


def percentiles(values: Sequence[float]) -> dict[str, float | int | None]:
    """p50, p95, p99 and max in milliseconds of values in seconds (None without data), and the count."""
    if not len(values):
        return {"p50_ms": None, "p95_ms": None, "p99_ms": None, "max_ms": None, "count": 0}
    a = np.asarray(values, dtype=np.float64) * 1000.0
    p50, p95, p99 = (round(float(v), 3) for v in np.percentile(a, [50, 95, 99]))
    return {"p50_ms": p50, "p95_ms": p95, "p99_ms": p99, "max_ms": round(float(a.max()), 3), "count": int(a.size)}


class FrameGatherer:
    """Collects channel images per frame number and decides each frame's fate.

    A frame is decided once: complete (every channel, bitwise the published eyepoint), or
    incomplete by cause: as soon as the channels the host waited for have delivered and one of
    the rig's was not among them (its worker was down), when a newer frame has all its images
    (frames are rendered in order, so an older open frame never will), when it has been open for
    pending_timeout_s, when the open frames exceed max_pending_frames or max_pending_bytes (the
    oldest goes first), or at the end of the run. Images for a decided frame are counted as
    late and dropped.

    Args:
        channels: rig channel names in display order.
        on_complete: called (outside the lock) with every complete frame, in frame order.
        pending_timeout_s: longest a frame stays open, seconds (see expire).
        monotonic: clock for pending_timeout_s, seconds.
        clock: wall clock, UNIX seconds: the time an image is received (ChannelTiming).
        sizes: each channel's (width, height) from the rig file; an image of another size is
            refused. None: any size.
        max_pending_frames: frames held open at once.
        max_pending_bytes: pixels the open frames may hold.
        run_id: the run the gatherer collects, "" until the first published frame names it.
        shared: reads images out of the workers' shared memory; None: such images are refused
            as unavailable (the workers then send them inline).
    """

    def __init__(self, channels: Sequence[str], on_complete: Callable[[CompleteFrame], None], *,
                 pending_timeout_s: float = 30.0, monotonic: Callable[[], float] = time.monotonic,
                 clock: Callable[[], float] = time.time, sizes: Mapping[str, tuple[int, int]] | None = None,
                 max_pending_frames: int = 16, max_pending_bytes: int = 512 * 2**20, run_id: str = "",
                 shared: SharedImageReader | None = None) -> None:
        if max_pending_frames < 1 or max_pending_bytes < 1:
            raise ValueError(f"max_pending_frames {max_pending_frames}, max_pending_bytes {max_pending_bytes}: "
                             f"both must be >= 1")
        self.channels = tuple(channels)
        self.on_complete = on_complete
        self.pending_timeout_s = pending_timeout_s
        self.monotonic = monotonic
        self.clock = clock
        self.sizes = dict(sizes) if sizes is not None else None
        self.max_pending_frames = max_pending_frames
        self.max_pending_bytes = max_pending_bytes
        self._lock = threading.Lock()
        self._open: dict[int, _Open] = {}
        self._decided: dict[int, str] = {}  # frame number -> "complete" or incomplete cause
        self._floor = -1  # frames up to this number count as decided (DECIDED_MEMORY)
        self._settled = -1  # the newest frame that had all its images
        self._bytes = 0  # pixels held by the open frames
        self.last_published = -1
        self.run_id = run_id
        self.frames_published = 0
        self.complete = 0
        self.incomplete: Counter[str] = Counter(dict.fromkeys(INCOMPLETE_CAUSES, 0))
        self.evicted = 0
        self.peak_pending_frames = 0
        self.peak_pending_bytes = 0
        self.late_images = 0
        self.late_by_channel: dict[str, int] = dict.fromkeys(self.channels, 0)
        self.missing_by_channel: dict[str, int] = dict.fromkeys(self.channels, 0)
        self.rejected: Counter[str] = Counter()
        self.last_rejection = ""
        self.last_incomplete = ""
        self.render_times: dict[str, deque[float]] = {c: deque(maxlen=MAX_SAMPLES) for c in self.channels}
        self.skipped: dict[str, int] = dict.fromkeys(self.channels, 0)
        self.shared = shared
        # The worker -> compositor hop of every image taken (docs/latency.md): render end to
        # received, and its parts, the worker's encoding (render end to submit) and the transfer
        # (submit to received); what each channel sent.
        self.wire_hops: dict[str, deque[float]] = {k: deque(maxlen=MAX_SAMPLES) for k in WIRE_HOPS}
        self.wire_images: dict[str, Counter[str]] = {c: Counter() for c in self.channels}
        self.wire_bytes: dict[str, int] = dict.fromkeys(self.channels, 0)

    # --- inputs -----------------------------------------------------------------------------
    def on_published(self, frame: frame_pb2.Frame) -> None:
        """The host published a frame (from the observer stream)."""
        with self._lock:
            if not self.run_id:
                # Images may arrive before the first published frame names the run: they are its.
                self.run_id = frame.run_id
            elif frame.run_id != self.run_id:
                raise ValueError(f"run_id: {frame.run_id!r} is not this gatherer's run {self.run_id!r} (the "
                                 f"compositor starts a gatherer per run)")
            self.frames_published += 1
            self.last_published = max(self.last_published, frame.frame_number)
            entry = self._entry(frame.frame_number)
            if entry is None:
                if frame.frame_number not in self._decided and frame.frame_number > self._floor:
                    # Older than a frame that had all its images: it can never complete.
                    self._decide(frame.frame_number, MISSING_CHANNEL, "seen after a newer frame had all its images")
                return
            entry.published = frame
            ready = self._settle(frame.frame_number)
            self._bound()
        self._emit(ready)

    def accepts(self, run_id: str, frame_number: int) -> bool | None:
        """Whether an image of run_id's frame_number passes the run and frame checks now: True;
        False when it may once the compositor's copy of the frame has arrived (another run, or
        a frame just ahead); None when it never will (a frame far beyond the last published)."""
        with self._lock:
            refusal = self._admission(run_id, frame_number)
            if refusal is None:
                return True
            # Before its first frame of the run (a compositor restarted mid-run) any number may
            # be about to be published.
            may_come = refusal.cause == OTHER_RUN or self.last_published < 0 or \
                frame_number <= self.last_published + 4 * LOOKAHEAD_FRAMES
            return False if may_come else None

    def _admission(self, run_id: str, number: int) -> InvalidSubmission | None:
        """Why an image of run_id's frame number is not taken now, or None (lock held)."""
        if run_id and self.run_id and run_id != self.run_id:
            return InvalidSubmission(OTHER_RUN, f"run_id: {run_id[:64]!r} is not the current run {self.run_id!r}")
        if number > self.last_published + LOOKAHEAD_FRAMES:
            last = self.last_published if self.last_published >= 0 else "none yet"
            return InvalidSubmission(UNPUBLISHED, f"frame_number: {number} has not been published (the last is "
                                                  f"{last})")
        return None

    def submit(self, request: compositor_pb2.SubmitChannelImageRequest) -> None:
        """A channel delivered an image.

        Raises:
            InvalidSubmission: unknown channel, non-finite eyepoint, pixels of the wrong size or
                format, another size than the rig file's, another run's image, a frame number
                beyond the last published (LOOKAHEAD_FRAMES), a second image for the same
                channel and frame. The frame is not touched; the rejection is counted by cause.
        """
        try:
            image = self._validate(request)
            with self._lock:
                number = request.frame_number
                refusal = self._admission(request.run_id, number)
                if refusal is not None:
                    raise refusal
                entry = self._entry(number)
                if entry is not None and image.channel in entry.images:
                    raise InvalidSubmission(DUPLICATE, f"channel_name: {image.channel!r} already delivered "
                                                       f"frame_number {number}")
                # A late image was still rendered and sent: its times and the worker's counter are real.
                self.render_times[image.channel].append(image.render_time_s)
                self._count_wire(image)
                self.skipped[image.channel] = max(self.skipped[image.channel], image.frames_skipped)
                if entry is None:
                    self.late_images += 1
                    self.late_by_channel[image.channel] += 1
                    return
                entry.images[image.channel] = image
                entry.nbytes += image.rgb.nbytes
                self._bytes += image.rgb.nbytes
                ready = self._settle(number)
                self._bound()
        except InvalidSubmission as exc:
            with self._lock:
                self.rejected[exc.cause] += 1
                self.last_rejection = str(exc)
            raise
        self._emit(ready)

    def count_refused(self, cause: str, message: str) -> None:
        """Count a submission refused before it reached submit (malformed bytes, overlong text)."""
        with self._lock:
            self.rejected[cause] += 1
            self.last_rejection = message

    def expire(self) -> int:
        """Finalise frames open longer than pending_timeout_s as incomplete; returns how many.

        Called periodically: it catches a frame that no newer frame will overtake, e.g. the
        last frames of a run whose channel died.
        """
        with self._lock:
            limit = self.monotonic() - self.pending_timeout_s
            old = [n for n, e in self._open.items() if e.since <= limit]
            for n in sorted(old):
                self._decide(n, MISSING_CHANNEL)
            return len(old)

    def finalize_all(self) -> None:
        """End of run: every frame not yet decided is incomplete."""
        with self._lock:
            for number in sorted(self._open):
                self._decide(number, MISSING_CHANNEL)

    @property
    def pending(self) -> int:
        """Frames seen but not decided yet."""
        with self._lock:
            return len(self._open)

    # --- decisions ----------------------------------------------------------------------------
    def _entry(self, number: int) -> _Open | None:
        """The open frame number, opened now if new; None if it was decided (lock held)."""
        entry = self._open.get(number)
        if entry is not None:
            return entry
        # Frames are rendered in order: an image of a frame older than one that had all its
        # images comes too late to open it.
        if number in self._decided or number <= self._floor or number < self._settled:
            return None
        entry = self._open[number] = _Open(since=self.monotonic())
        self.peak_pending_frames = max(self.peak_pending_frames, len(self._open))
        return entry

    def _bound(self) -> None:
        """Finalise the oldest open frames while the open ones exceed their bounds (lock held)."""
        self.peak_pending_bytes = max(self.peak_pending_bytes, self._bytes)
        while self._open and (len(self._open) > self.max_pending_frames or self._bytes > self.max_pending_bytes):
            oldest = min(self._open)
            self.evicted += 1
            self._decide(oldest, MISSING_CHANNEL, f"evicted: {len(self._open)} frames, {self._bytes / 2**20:.1f} MiB "
                                                  f"open; the bounds are {self.max_pending_frames} frames, "
                                                  f"{self.max_pending_bytes / 2**20:.0f} MiB")

    def _validate(self, r: compositor_pb2.SubmitChannelImageRequest) -> ChannelImage:
        if r.channel_name not in self.channels:
            raise InvalidSubmission(UNKNOWN_CHANNEL, f"channel_name: {r.channel_name[:64]!r} is not a channel of "
                                                     f"the rig ({', '.join(self.channels)})")
        if not r.HasField("eyepoint"):
            raise InvalidSubmission(BAD_EYEPOINT, "eyepoint: missing")
        for name in _EYE_FIELDS:
            value = getattr(r.eyepoint, name)
            if not math.isfinite(value):
                raise InvalidSubmission(BAD_EYEPOINT, f"eyepoint.{name}: {value} is not finite")
        if r.pixel_format not in PIXEL_FORMATS:
            name = compositor_pb2.PixelFormat.Name(r.pixel_format) if r.pixel_format in \
                compositor_pb2.PixelFormat.values() else str(r.pixel_format)
            raise InvalidSubmission(BAD_PIXELS, f"pixel_format: {name} is not PIXEL_FORMAT_RGB_SRGB8 or "
                                                f"PIXEL_FORMAT_RGB_F16")
        if self.sizes is not None and (r.width, r.height) != self.sizes[r.channel_name]:
            w, h = self.sizes[r.channel_name]
            raise InvalidSubmission(WRONG_SIZE, f"width x height: {r.width} x {r.height} is not channel "
                                                f"{r.channel_name!r}'s {w} x {h} (rig file)")
        wire, dtype = PIXEL_FORMATS[r.pixel_format]
        if r.width == 0 or r.height == 0:
            raise InvalidSubmission(BAD_PIXELS, f"width x height: {r.width} x {r.height} has no pixels")
        shape = (r.height, r.width, 3)
        if r.HasField("shared"):
            rgb = self._read_shared(r, shape, dtype)
        else:
            expected = r.width * r.height * 3 * dtype.itemsize
            # Each read of a bytes field hands out a fresh copy of it: read the pixels once, and
            # keep them as a view of that copy (the stitch is the only other copy the compositor
            # makes).
            pixels = r.pixels
            if len(pixels) != expected:
                raise InvalidSubmission(BAD_PIXELS, f"pixels: {len(pixels)} bytes, expected {expected} for "
                                                    f"{r.width} x {r.height} RGB {wire}")
            rgb = np.frombuffer(pixels, dtype=dtype).reshape(shape)
        timing = ChannelTiming(r.frame_received_unix_s, r.render_start_unix_s, r.render_end_unix_s,
                               r.submit_unix_s, self.clock())
        return ChannelImage(r.channel_name, rgb, eyepoint_tuple(r.eyepoint), r.render_time_s,
                            r.control_sample_time_unix_s, r.frames_skipped, timing, r.HasField("shared"))

    def _read_shared(self, r: compositor_pb2.SubmitChannelImageRequest, shape: tuple[int, int, int],
                     dtype: np.dtype) -> np.ndarray:
        """The pixels of a shared-memory image, copied out of the worker's slot."""
        if r.pixels:
            raise InvalidSubmission(BAD_PIXELS, f"pixels: {len(r.pixels)} bytes as well as shared "
                                                f"{r.shared.segment!r}: one or the other")
        if self.shared is None:
            raise InvalidSubmission(SHARED_UNAVAILABLE, f"shared.segment: {r.shared.segment[:80]!r}: this "
                                                        f"compositor takes no shared memory; send the pixels inline")
        try:
            return self.shared.read(r.channel_name, r.shared.segment, r.shared.slot, r.shared.sequence, shape, dtype)
        except SharedImageError as exc:
            raise InvalidSubmission(SHARED_UNAVAILABLE if exc.unavailable else STALE_SHARED, str(exc)) from None

    def _count_wire(self, image: ChannelImage) -> None:
        """The image's format, way and size, and its hop's parts (lock held)."""
        counts = self.wire_images[image.channel]
        counts[image.wire] += 1
        counts["shared_memory" if image.shared else "inline"] += 1
        self.wire_bytes[image.channel] = image.rgb.nbytes
        t = image.timing
        if t.render_end and t.submit:
            for key, seconds in zip(WIRE_HOPS, (t.compositor_receive - t.render_end, t.submit - t.render_end,
                                                t.compositor_receive - t.submit), strict=True):
                self.wire_hops[key].append(seconds)

    def _settle(self, number: int) -> list[CompleteFrame]:
        """Decide frame number if it can be decided now (lock held)."""
        entry = self._open.get(number)
        if entry is None or entry.published is None:
            return []
        published = entry.published
        # The channels the host waited for; a frame from a host that does not list them waits
        # for every channel of the rig.
        expected = [c for c in published.channels if c in self.channels] or list(self.channels)
        if any(c not in entry.images for c in expected):
            return []
        eyepoint = eyepoint_tuple(published.eyepoint)
        wrong = [img.channel for img in entry.images.values() if not same_bits(img.eyepoint, eyepoint)]
        if wrong:
            self._decide(number, EYEPOINT_MISMATCH, f"channels {', '.join(wrong)} rendered another eyepoint")
            return []
        # Frames are rendered in order: once a newer frame has all its images, older open ones
        # never will.
        for older in sorted(n for n in self._open if n < number):
            self._decide(older, MISSING_CHANNEL)
        self._settled = max(self._settled, number)
        absent = [c for c in self.channels if c not in entry.images]
        if absent:
            self._decide(number, MISSING_CHANNEL, "not subscribed to the host")
            return []
        images = tuple(entry.images[c] for c in self.channels)
        self._decide(number, _COMPLETE)
        host_frame = published.host_frame_number if published.HasField("host_frame_number") else None
        return [CompleteFrame(number, published.sim_time_s, eyepoint, published.control_sample_time_unix_s, images,
                              published.publish_time_unix_s, published.run_id, host_frame)]

    def _decide(self, number: int, outcome: str, detail: str = "") -> None:
        entry = self._open.pop(number, None)
        if entry is not None:
            self._bytes -= entry.nbytes
        self._decided[number] = outcome
        while len(self._decided) > DECIDED_MEMORY:
            oldest = next(iter(self._decided))
            self._floor = max(self._floor, oldest)
            del self._decided[oldest]
        if outcome == _COMPLETE:
            self.complete += 1
            return
        self.incomplete[outcome] += 1
        if outcome == MISSING_CHANNEL and entry is not None:
            missing = [c for c in self.channels if c not in entry.images]
            for c in missing:
                self.missing_by_channel[c] += 1
            if not missing:
                detail = detail or "host frame not seen"
            else:
                detail = f"missing {', '.join(missing)}" + (f" ({detail})" if detail else "")
        self.last_incomplete = f"frame {number}: {outcome}: {detail}"

    def _emit(self, ready: list[CompleteFrame]) -> None:
        for frame in ready:
            self.on_complete(frame)

    # --- report -------------------------------------------------------------------------------
    def report(self) -> dict:
        """Counters and render-time figures as a JSON-ready dict.

        The render times are copied under the lock and their percentiles computed outside it:
        the lock is the one every submission takes, and the report is read once a second by
        `ig demo`'s progress line and by the live view."""
        with self._lock:
            times = {c: list(v) for c, v in self.render_times.items()}
            hops = {k: list(v) for k, v in self.wire_hops.items()}
            wire = self._wire_report()
            doc: dict = {
                "run_id": self.run_id,
                "channels": list(self.channels),
                "frames_published": self.frames_published,
                "frames_complete": self.complete,
                "frames_incomplete": {c: self.incomplete[c] for c in INCOMPLETE_CAUSES},
                "frames_pending": len(self._open),
                "frames_evicted": self.evicted,
                "missing_by_channel": dict(self.missing_by_channel),
                "pending_bytes": self._bytes,
                "peak_pending_frames": self.peak_pending_frames,
                "peak_pending_bytes": self.peak_pending_bytes,
                "max_pending_frames": self.max_pending_frames,
                "max_pending_bytes": self.max_pending_bytes,
                "last_incomplete": self.last_incomplete,
                "late_images": self.late_images,
                "late_by_channel": dict(self.late_by_channel),
                "rejected_submissions": dict(sorted(self.rejected.items())),
                "last_rejection": self.last_rejection,
                "render_time": {},
                "frames_skipped": dict(self.skipped),
                "wire": wire,
            }
        doc["render_time"] = {c: percentiles(v) for c, v in times.items()}
        wire.update({k: percentiles(v) for k, v in hops.items()})
        return doc

    def counters(self) -> dict:
        """The counters alone, as a JSON-ready dict, without the figures report() computes
        (what /metrics reads at every scrape; metrics.run_counts)."""
        with self._lock:
            return {
                "frames_published": self.frames_published,
                "frames_complete": self.complete,
                "frames_incomplete": {c: self.incomplete[c] for c in INCOMPLETE_CAUSES},
                "frames_evicted": self.evicted,
                "frames_pending": len(self._open),
                "pending_bytes": self._bytes,
                "missing_by_channel": dict(self.missing_by_channel),
                "late_by_channel": dict(self.late_by_channel),
                "rejected_submissions": dict(self.rejected),
                "images_by_channel": {c: {w: n[w] for w in ("srgb8", "half")} for c, n in self.wire_images.items()},
                "shared_memory_by_channel": {c: n["shared_memory"] for c, n in self.wire_images.items()},
            }

    def _wire_report(self) -> dict:
        """What the workers sent (lock held): per channel the images by format and way (srgb8,
        half; shared_memory, inline) and the bytes of the last image's pixels. report() adds the
        hop render end -> received over every image, and its parts, outside the lock."""
        channels = {c: {"srgb8": n["srgb8"], "half": n["half"], "shared_memory": n["shared_memory"],
                        "inline": n["inline"], "bytes_per_image": self.wire_bytes[c]}
                    for c, n in self.wire_images.items()}
        return {"channels": channels}
