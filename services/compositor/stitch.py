"""Stitching complete frames side by side and writing them (PNG every frame, EXR every Nth)."""

from __future__ import annotations

import logging
import queue
import threading
from pathlib import Path

import numpy as np

from services.image_io import write_image

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
    x, y, z, h, p, r = frame.eyepoint
    return {"frame_number": frame.frame_number, "sim_time_s": frame.sim_time_s, "eye_x": x, "eye_y": y,
            "eye_z": z, "heading_deg": h, "pitch_deg": p, "roll_deg": r,
            "channels": ",".join(img.channel for img in frame.images)}


class FrameWriter:
    """Writes stitched frames on its own thread so gathering never waits for the disk.

    The queue is bounded: if the disk cannot keep up, submissions wait, which through the frame
    lock slows the host instead of losing frames.
    """

    def __init__(self, out_dir: Path, *, exr_every: int = 30, depth: int = 8) -> None:
        self.out_dir = Path(out_dir)
        self.exr_every = exr_every
        self.written = 0
        self.errors = 0
        self.last_path = ""
        self._queue: queue.Queue[CompleteFrame | None] = queue.Queue(maxsize=depth)
        self._thread = threading.Thread(target=self._run, name="frame-writer", daemon=True)
        self._thread.start()

    def put(self, frame: CompleteFrame) -> None:
        self._queue.put(frame)

    def close(self) -> None:
        """Write everything queued, then stop."""
        self._queue.put(None)
        self._thread.join()

    def _run(self) -> None:
        while (frame := self._queue.get()) is not None:
            try:
                rgb = stitch(frame)
                attrs = frame_attributes(frame)
                png = self.out_dir / f"frame_{frame.frame_number:06d}.png"
                write_image(png, rgb, attributes=attrs)
                if self.exr_every > 0 and frame.frame_number % self.exr_every == 0:
                    write_image(png.with_suffix(".exr"), rgb, attributes=attrs)
                self.written += 1
                self.last_path = str(png)
            except (OSError, ValueError) as exc:
                self.errors += 1
                log.error("frame %d not written: %s", frame.frame_number, exc)
