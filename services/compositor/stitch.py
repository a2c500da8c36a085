"""Stitching complete frames side by side and writing them (PNG every frame, EXR every Nth)."""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from services.rig.image_io import write_image

from .gather import CompleteFrame

log = logging.getLogger("ig.compositor")


def stitch(frame: CompleteFrame) -> np.ndarray:
    """The channels' images side by side in rig order, (H, sum W, 3) float32 linear.

    Raises:
        ValueError: the channels differ in height (a rig of unequal rows cannot be stitched).
    """
    heights = {img.rgb.shape[0] for img in frame.images}
    if len(heights) != 1:
        raise ValueError(f"frame {frame.frame_number}: channel heights {sorted(heights)} differ")
    return np.concatenate([img.rgb.astype(np.float32) for img in frame.images], axis=1)


def frame_attributes(frame: CompleteFrame) -> dict[str, str | float | int]:
    """Image attributes of a stitched frame: frame number, sim time, eyepoint, channel order.

    Image files store float attributes as float32, centimetres at airfield distances; the
    `eyepoint` string ("x y z heading pitch roll", metres and degrees) keeps the exact float64s.
    """
    x, y, z, h, p, r = frame.eyepoint
    return {"frame_number": frame.frame_number, "sim_time_s": frame.sim_time_s, "eye_x": x, "eye_y": y,
            "eye_z": z, "heading_deg": h, "pitch_deg": p, "roll_deg": r,
            "eyepoint": " ".join(repr(float(v)) for v in frame.eyepoint),
            "channels": ",".join(img.channel for img in frame.images)}


class FrameWriter:
    """Stitches complete frames and writes them on its own thread, so gathering never waits for
    the disk.

    Writes `frame_NNNNNN.png` (sRGB 8-bit) for every frame and `frame_NNNNNN.exr` (linear half
    RGB with the frame attributes) for every frame number divisible by exr_every (0: never).

    The queue is bounded: if the disk cannot keep up, submissions wait, which through the frame
    lock slows the host instead of losing frames.

    Args:
        out_dir: directory of the frame files (created).
        exr_every: EXR period in frames.
        depth: frames waiting to be written before put blocks.
        clock: wall clock, UNIX seconds, for the control-to-composite latency.
    """

    def __init__(self, out_dir: Path, *, exr_every: int = 30, depth: int = 8,
                 clock: Callable[[], float] = time.time) -> None:
        self.out_dir = Path(out_dir)
        self.exr_every = exr_every
        self.clock = clock
        self.written = 0
        self.errors = 0
        self.last_path = ""
        self.last_error = ""
        #: Seconds from each frame's control sample to its stitched image (composite wall time),
        #: one per stitched frame.
        self.latencies: list[float] = []
        self._lock = threading.Lock()
        self._queue: queue.Queue[tuple[CompleteFrame, np.ndarray] | None] = queue.Queue(maxsize=depth)
        self._thread = threading.Thread(target=self._run, name="frame-writer", daemon=True)
        self._thread.start()

    def put(self, frame: CompleteFrame) -> None:
        """Stitch a complete frame now and queue it for the disk (blocks while the queue is full).

        Stitching here, on the caller's thread, is the composite: the latency is taken at this
        moment, as a display output would show the frame. Encoding and writing the files is a
        recording of it and happens on the writer thread.
        """
        try:
            rgb = stitch(frame)
        except ValueError as exc:
            self._count_error(frame, exc)
            return
        with self._lock:
            self.latencies.append(self.clock() - frame.control_sample_time)
        self._queue.put((frame, rgb))

    def close(self) -> None:
        """Write everything queued, then stop."""
        self._queue.put(None)
        self._thread.join()

    def snapshot(self) -> tuple[int, int, list[float]]:
        """Frames written, write errors, and a copy of the latencies."""
        with self._lock:
            return self.written, self.errors, list(self.latencies)

    def _count_error(self, frame: CompleteFrame, exc: Exception) -> None:
        # A full disk or an unwritable directory must not stop the rig: counted, logged.
        with self._lock:
            self.errors += 1
            self.last_error = f"frame {frame.frame_number}: {exc}"
        log.error("frame %d not written: %s", frame.frame_number, exc)

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            frame, rgb = item
            try:
                self.out_dir.mkdir(parents=True, exist_ok=True)
                attrs = frame_attributes(frame)
                png = self.out_dir / f"frame_{frame.frame_number:06d}.png"
                write_image(png, rgb, attributes=attrs)
                if self.exr_every > 0 and frame.frame_number % self.exr_every == 0:
                    write_image(png.with_suffix(".exr"), rgb, attributes=attrs)
                with self._lock:
                    self.written += 1
                    self.last_path = str(png)
            except (OSError, ValueError) as exc:
                self._count_error(frame, exc)
