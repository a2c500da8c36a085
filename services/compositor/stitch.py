"""Stitching complete frames side by side, and recording the composites off the critical path."""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from services.rig.colour import decode_srgb8, linear_to_srgb8
from services.rig.image_io import write_image

from .blend import BlendPlan
from .gather import CompleteFrame
from .timing import Composite

log = logging.getLogger("ig.compositor")


#: The composite's numpy type of each wire format.
_DTYPES: dict[str, np.dtype] = {"srgb8": np.dtype(np.uint8), "half": np.dtype(np.float16)}


def stitch_format(frame: CompleteFrame, prefer: str = "srgb8") -> str:
    """The format a frame is stitched in: its images' own when they agree (no conversion on the
    way to the composite), prefer (the rig's wire format) when they do not."""
    formats = {img.wire for img in frame.images}
    return formats.pop() if len(formats) == 1 else prefer


def as_format(rgb: np.ndarray, wire: str) -> np.ndarray:
    """An image in the wire format wire: as it is, or converted (sRGB bytes decoded to linear and
    rounded to half floats; half floats encoded to sRGB bytes as the PNGs are)."""
    if rgb.dtype == _DTYPES[wire]:
        return rgb
    return decode_srgb8(rgb).astype(np.float16) if wire == "half" else linear_to_srgb8(rgb)


def _linear(rgb: np.ndarray) -> np.ndarray:
    """Linear float32 of an image in either format (a new array)."""
    return decode_srgb8(rgb) if rgb.dtype == np.uint8 else rgb.astype(np.float32)


def stitch(frame: CompleteFrame, plan: BlendPlan | None = None, *, prefer: str = "srgb8") -> np.ndarray:
    """The channels' images side by side in rig order, (H, W, 3): uint8 sRGB when the channels
    sent sRGB bytes, float16 linear when they sent half floats (stitch_format).

    Without a plan, or with one whose seams all abut, W is the sum of the widths and the
    result a plain concatenation: one copy of the pixels, in the format they arrived in
    (widening to float32 here would take four times as long, 20 ms for three 1024 x 768
    half-float channels, on the way to the composite; the recorder widens what it writes, on
    its own thread). With overlaps, W is plan.stitched_width and each seam's overlap columns are
    the two channels cross-faded with the plan's linear-light weights, in float32 (float16
    products would lose a bit in the ramp; sRGB bytes are decoded to linear light first and
    encoded again after), the rest copied as it came.

    Args:
        frame: a complete frame, images in rig order.
        plan: the rig's blend_plan (built from the channels at the size they are rendered).
        prefer: the format of a frame whose channels sent different ones ("srgb8" or "half").

    Raises:
        ValueError: the channels differ in height (a rig of unequal rows cannot be stitched), or
            their number or widths are not the plan's.
    """
    heights = {img.rgb.shape[0] for img in frame.images}
    if len(heights) != 1:
        raise ValueError(f"frame {frame.frame_number}: channel heights {sorted(heights)} differ")
    if plan is not None:
        widths = tuple(img.rgb.shape[1] for img in frame.images)
        if widths != plan.widths:
            raise ValueError(f"frame {frame.frame_number}: channel widths {list(widths)} are not the "
                             f"blend plan's {list(plan.widths)}")
    wire = stitch_format(frame, prefer)
    images = [as_format(img.rgb, wire) for img in frame.images]
    if plan is None or not plan.blends:
        return np.concatenate(images, axis=1)
    out = np.empty((heights.pop(), plan.stitched_width, 3), _DTYPES[wire])
    for i, rgb in enumerate(images):
        # The columns this channel shows alone: between its left and right overlaps.
        nl, nr = plan.left_weights[i].size, plan.right_weights[i].size
        width = plan.widths[i]
        x = plan.offsets[i]
        out[:, x + nl:x + width - nr] = rgb[:, nl:width - nr]
    for i, n in enumerate(plan.overlaps):
        if n == 0:
            continue
        a = _linear(images[i][:, plan.widths[i] - n:])
        b = _linear(images[i + 1][:, :n])
        a *= plan.right_weights[i][None, :, None]
        b *= plan.left_weights[i + 1][None, :, None]
        a += b
        x = plan.offsets[i + 1]
        # float32 -> float16 rounded to nearest, or encoded to sRGB bytes as the PNGs are.
        out[:, x:x + n] = a if wire == "half" else linear_to_srgb8(a)
    return out


def compose(frame: CompleteFrame, plan: BlendPlan | None = None, *,
            clock: Callable[[], float] = time.time, prefer: str = "srgb8") -> Composite:
    """The composite of a complete frame: stitched now, and time-stamped when it is done.

    The channel images of the returned frame are views of the composite, so the buffers they
    arrived in are freed and a composite waiting for the recorder or a watcher holds one copy
    of the pixels. With a blending plan each view starts at the channel's offset and is as wide
    as the channel, so adjacent views share (and show blended) the overlap columns.

    Args:
        frame: a complete frame, images in rig order.
        plan: the rig's blend_plan; None stitches side by side.
        clock: UNIX seconds, for the composite's time stamp.
        prefer: as stitch.

    Raises:
        ValueError: as stitch.
    """
    rgb = stitch(frame, plan, prefer=prefer)
    done = clock()
    images, x = [], 0
    for i, img in enumerate(frame.images):
        width = img.rgb.shape[1]
        if plan is not None:
            x = plan.offsets[i]
        images.append(replace(img, rgb=rgb[:, x:x + width]))
        x += width
    return Composite(replace(frame, images=tuple(images)), rgb, done)


def frame_attributes(frame: CompleteFrame, wire: str = "half") -> dict[str, str | float | int]:
    """Image attributes of a stitched frame: frame number, sim time, eyepoint, channel order, the
    wire format the composite was stitched in (an EXR of an "srgb8" composite holds 8-bit
    levels decoded to linear: quantised), and the external host's frame number (CIGI) when
    there is one.

    Image files store float attributes as float32, centimetres at airfield distances; the
    `eyepoint` string ("x y z heading pitch roll", metres and degrees) keeps the exact float64s.
    """
    x, y, z, h, p, r = frame.eyepoint
    attributes: dict[str, str | float | int] = {
        "frame_number": frame.frame_number, "sim_time_s": frame.sim_time_s, "eye_x": x, "eye_y": y,
        "eye_z": z, "heading_deg": h, "pitch_deg": p, "roll_deg": r,
        "eyepoint": " ".join(repr(float(v)) for v in frame.eyepoint),
        "channels": ",".join(img.channel for img in frame.images), "wire": wire}
    if frame.host_frame_number is not None:
        # A string: image files keep integer attributes as int32, and CIGI's are uint32.
        attributes["host_frame_number"] = str(frame.host_frame_number)
    return attributes


@dataclass
class RecorderCounts:
    """What the recorder has done.

    Attributes:
        written: composites written (their PNG, or their EXR when no PNG was due).
        errors: composites whose files could not be written.
        not_recorded: composites due for recording that were left out because the writer was
            behind (its queue was full).
    """

    written: int = 0
    errors: int = 0
    not_recorded: int = 0


class FrameRecorder:
    """Records composites to files on its own thread; never makes the rig wait.

    Writes `frame_NNNNNN.png` (sRGB 8-bit) for every frame number divisible by record_every and
    `frame_NNNNNN.exr` (linear half RGB with the frame attributes) for every one divisible by
    exr_every (0: never, for either). A composite of sRGB-wire channels (uint8) goes into its
    PNG byte for byte; its EXR holds those bytes decoded to linear, 8-bit levels (quantised;
    the `ig:wire` attribute says "srgb8"): record from half-float channels for accurate EXRs.

    Recording is a copy of what the rig shows, not part of showing it: encoding a 3072 x 768
    PNG takes a few hundred milliseconds, longer than a frame. So offer() never waits: when the
    composites waiting to be written (the one being written included) hold max_bytes of pixels,
    a composite due for recording is left out and counted (`not_recorded`) instead of holding
    the channel whose image completed it, and through the frame lock the host. The bound is in
    bytes, not composites, so small channels ride out a stall of the writer (its first write
    loads the image plugins from disk; on a fresh install that took longer than 8 frames of
    a 20 Hz test rig) while large ones stay within the same memory. Choose record_every so
    that the writer keeps up (docs/latency.md).

    Args:
        out_dir: directory of the frame files (created when the first one is written).
        record_every: PNG period in frame numbers.
        exr_every: EXR period in frame numbers.
        record_per_s: when > 0, PNGs by the frames' simulation time instead of record_every:
            the first frame of each 1 / record_per_s seconds of the run (a rig whose rate is not
            known in advance, such as one paced by its own frame lock, still records a fixed
            number of pictures a simulated second).
        max_bytes: pixels waiting to be written before further composites are left out (one
            composite is always taken when none waits). The default holds 18 composites of the
            default rig (3072 x 768 half-float RGB, 14 MB).
    """

    def __init__(self, out_dir: Path, *, record_every: int = 1, exr_every: int = 30,
                 max_bytes: int = 256 * 2**20, record_per_s: float = 0.0) -> None:
        for name, value in (("record_every", record_every), ("exr_every", exr_every),
                            ("max_bytes", max_bytes), ("record_per_s", record_per_s)):
            if not value >= 0 or value == float("inf"):  # NaN fails the comparison
                raise ValueError(f"{name}: {value} must be >= 0 and finite")
        self.out_dir = Path(out_dir)
        self.record_every = record_every
        self.record_per_s = record_per_s
        self._last_slot = -1  # the last 1 / record_per_s interval a PNG was due in
        self.exr_every = exr_every
        self.max_bytes = max_bytes
        self.last_path = ""
        self.last_error = ""
        self._counts = RecorderCounts()
        self._lock = threading.Lock()
        self._waiting_bytes = 0
        # A stitched composite holds its own pixels, so the queue keeps nothing the gatherer reuses.
        self._queue: queue.Queue[tuple[Composite, bool, bool] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="frame-recorder", daemon=True)
        self._thread.start()

    def due(self, frame_number: int, sim_time_s: float = 0.0) -> tuple[bool, bool]:
        """(PNG due, EXR due) for a frame; called once per composite, in frame order (by time,
        a frame is due when it is the first of a new interval)."""
        exr = self.exr_every > 0 and frame_number % self.exr_every == 0
        if self.record_per_s <= 0:
            return self.record_every > 0 and frame_number % self.record_every == 0, exr
        if not math.isfinite(sim_time_s):
            return False, exr
        slot = math.floor(sim_time_s * self.record_per_s)
        if slot <= self._last_slot:
            return False, exr
        self._last_slot = slot
        return True, exr

    def offer(self, composite: Composite) -> bool:
        """Queue a composite for writing if it is due; never blocks.

        Returns:
            False if it was due but left out because the writer is behind (counted), else True.
        """
        png, exr = self.due(composite.frame.frame_number, composite.frame.sim_time_s)
        if not (png or exr):
            return True
        size = composite.rgb.nbytes
        with self._lock:
            if self._waiting_bytes > 0 and self._waiting_bytes + size > self.max_bytes:
                self._counts.not_recorded += 1
                log.debug("frame %d not recorded: the writer is behind", composite.frame.frame_number)
                return False
            self._waiting_bytes += size
        self._queue.put_nowait((composite, png, exr))
        return True

    def close(self) -> None:
        """Write everything queued, then stop."""
        self._queue.put(None)
        self._thread.join()

    def snapshot(self) -> RecorderCounts:
        """The counts so far."""
        with self._lock:
            return replace(self._counts)

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            composite, png, exr = item
            frame = composite.frame
            try:
                attrs = frame_attributes(frame, "srgb8" if composite.rgb.dtype == np.uint8 else "half")
                path = self.out_dir / f"frame_{frame.frame_number:06d}.png"
                if png:
                    write_image(path, composite.rgb, attributes=attrs)
                if exr:
                    write_image(path.with_suffix(".exr"), composite.rgb, attributes=attrs)
                with self._lock:
                    self._counts.written += 1
                    self.last_path = str(path if png else path.with_suffix(".exr"))
            except (OSError, ValueError) as exc:
                # A full disk or an unwritable directory must not stop the rig: counted, logged.
                with self._lock:
                    self._counts.errors += 1
                    self.last_error = f"frame {frame.frame_number}: {exc}"
                log.error("frame %d not written: %s", frame.frame_number, exc)
            finally:
                with self._lock:
                    self._waiting_bytes -= composite.rgb.nbytes
