"""The live view's pictures: the newest composite, scaled down and encoded as JPEG, for every
browser watching.

Three hand-overs, each a mailbox that drops the oldest and counts (services/rig/mailbox.py), so
nothing downstream can slow what is upstream:

    gathering thread --(feed, 1 deep)--> view thread: scale, encode --(one per browser, 1 deep)--> browser

The gathering thread only appends the composite to the feed (Watchers.attach), as it does for
the WatchComposites streams. The view's own thread takes the newest composite at most
max_rate_hz times a second, averages it down to at most max_width pixels and encodes it through
OpenImageIO; composites it never took were replaced in the feed (`composites_skipped`: the
rate cap, not a fault). Each browser's stream thread takes the newest frame from its own
mailbox; a frame replaced there before the browser took it is a frame that browser missed
because it was still receiving an earlier one (`frames_dropped`: a slow or stalled browser).
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.rig.colour import linear_to_srgb8
from services.rig.image_io import encode_jpeg
from services.rig.mailbox import Mailbox

from ..timing import Composite

log = logging.getLogger("ig.compositor")

#: Frames a second the view encodes at most: enough to watch a flight, a small share of a core.
MAX_RATE_HZ = 10.0
#: Widest picture sent, pixels: the default rig's 3072-pixel panorama is averaged 4 x 4 to 768.
MAX_WIDTH = 960
#: JPEG quality: a 768 x 192 frame of the demo is about 40 KB.
JPEG_QUALITY = 80
#: Seconds of composite latencies kept for the page's plot.
LATENCY_WINDOW_S = 60.0
#: Latencies kept at most (a minute at 60 Hz), whatever the rate.
_LATENCY_SAMPLES = 3600


@dataclass(frozen=True)
class ViewFrame:
    """One encoded picture of the panorama.

    Attributes:
        sequence: 1 for the view's first frame, then one more for each.
        jpeg: the JPEG file's bytes.
        width, height: its size, pixels.
        run_id, frame_number, sim_time_s: the composite it shows.
        composite_time: UNIX seconds the composite was stitched.
    """

    sequence: int
    jpeg: bytes
    width: int
    height: int
    run_id: str
    frame_number: int
    sim_time_s: float
    composite_time: float


def downscale(rgb: np.ndarray, max_width: int) -> np.ndarray:
    """The composite as sRGB bytes at most max_width wide: the mean of every f x f block,
    f = ceil(W / max_width), the last rows and columns that make no whole block left out.

    uint8 sRGB is averaged as it is (a preview: no linear-light round trip); float16 linear is
    averaged in linear light, then encoded. Strided sums (about 6 ms for 3072 x 768 on one
    core) rather than OpenImageIO's resize, which took 150 ms with a box filter.
    """
    f = max(1, -(-rgb.shape[1] // max_width))
    h, w = rgb.shape[0] // f * f, rgb.shape[1] // f * f
    if f == 1:
        return rgb if rgb.dtype == np.uint8 else linear_to_srgb8(rgb)
    wide = np.dtype(np.uint32) if rgb.dtype == np.uint8 else np.dtype(np.float32)
    rows: np.ndarray = rgb[0:h:f, :w].astype(wide)
    for i in range(1, f):
        rows += rgb[i:h:f, :w]
    blocks = rows.reshape(h // f, w // f, f, 3)
    total = blocks[:, :, 0].copy()
    for j in range(1, f):
        total += blocks[:, :, j]
    if rgb.dtype == np.uint8:
        return ((total + f * f // 2) // (f * f)).astype(np.uint8)
    return linear_to_srgb8(total / np.float32(f * f))


class Client(Mailbox[ViewFrame]):
    """One browser's stream: the newest frame waiting (one deep), the rest dropped and counted."""

    def __init__(self) -> None:
        super().__init__(1)


class _Feed(Mailbox[Composite]):
    """The gathering thread's side: the newest composite waiting for the view's thread, and the
    latency of every composite (for the plot), both a constant-time append."""

    def __init__(self) -> None:
        super().__init__(1)
        self.lock = threading.Lock()
        self.latencies: deque[tuple[float, float]] = deque(maxlen=_LATENCY_SAMPLES)

    def put(self, item: Composite) -> None:
        with self.lock:
            self.latencies.append((item.time, item.time - item.frame.control_sample_time))
        super().put(item)


class FrameSource:
    """Encodes the newest composite on its own thread and hands it to every browser.

    Args:
        max_rate_hz: frames encoded a second at most.
        max_width: the widest picture, pixels.
        quality: JPEG quality.
    """

    def __init__(self, *, max_rate_hz: float = MAX_RATE_HZ, max_width: int = MAX_WIDTH,
                 quality: int = JPEG_QUALITY) -> None:
        if not max_rate_hz > 0 or max_width < 1:
            raise ValueError(f"max_rate_hz {max_rate_hz}, max_width {max_width}: both must be > 0")
        self.max_rate_hz = max_rate_hz
        self.max_width = max_width
        self.quality = quality
        #: What the compositor hands composites to (Watchers.attach).
        self.feed = _Feed()
        self._lock = threading.Lock()
        self._clients: list[Client] = []
        self._latest: ViewFrame | None = None
        self._encoded = 0
        self._dropped_gone = 0  # frames dropped for browsers that have left
        self._errors = 0
        self._stop = threading.Event()
        self._scratch_dir: Path | None = None
        self._thread = threading.Thread(target=self._run, name="live-view-encoder", daemon=True)

    def start(self) -> None:
        """Start encoding (close() stops it and removes its scratch file)."""
        # The encoder's scratch file: in memory where /dev/shm is there (OpenImageIO writes files only).
        shm = Path("/dev/shm")
        self._scratch_dir = Path(tempfile.mkdtemp(prefix="ig-view-", dir=shm if os.access(shm, os.W_OK) else None))
        self._thread.start()

    def close(self) -> None:
        """Stop encoding; every browser's stream ends once it has its last frame."""
        self._stop.set()
        self.feed.close()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        with self._lock:
            clients = list(self._clients)
        for client in clients:
            client.close()
        if self._scratch_dir is not None:
            shutil.rmtree(self._scratch_dir, ignore_errors=True)

    # --- browsers -----------------------------------------------------------------------------
    def join(self, *, limit: int) -> Client | None:
        """A new browser's stream, the newest frame already waiting in it; None when limit
        streams are open already."""
        client = Client()
        with self._lock:
            if len(self._clients) >= limit:
                return None
            if self._latest is not None:
                client.put(self._latest)
            if self._stop.is_set():
                client.close()
            self._clients.append(client)
        return client

    def leave(self, client: Client) -> None:
        """A browser's stream ended: its drops go into the total."""
        with self._lock:
            if client in self._clients:
                self._clients.remove(client)
                self._dropped_gone += client.dropped

    @property
    def latest(self) -> ViewFrame | None:
        """The newest frame encoded (None before the first)."""
        with self._lock:
            return self._latest

    def counts(self) -> dict[str, int]:
        """frames_encoded, composites_skipped (replaced in the feed before the view took them),
        frames_dropped (frames a browser missed: still receiving an earlier one), clients
        (browsers receiving the stream now), encode_errors."""
        with self._lock:
            return {"frames_encoded": self._encoded, "composites_skipped": self.feed.dropped,
                    "frames_dropped": self._dropped_gone + sum(c.dropped for c in self._clients),
                    "clients": len(self._clients), "encode_errors": self._errors}

    def latencies(self, now: float | None = None) -> list[tuple[float, float]]:
        """(composite time, control-to-composite latency), UNIX seconds and seconds, of every
        composite of the last LATENCY_WINDOW_S."""
        since = (time.time() if now is None else now) - LATENCY_WINDOW_S
        with self.feed.lock:
            return [s for s in self.feed.latencies if s[0] >= since]

    # --- the view's thread --------------------------------------------------------------------
    def _run(self) -> None:
        period = 1.0 / self.max_rate_hz
        next_at = 0.0
        while not self._stop.is_set():
            # Composites that come while the view waits replace each other in the feed.
            if self._stop.wait(max(0.0, next_at - time.monotonic())):
                return
            composite = self.feed.get(0.5)
            if composite is None:
                if self.feed.closed:
                    return
                continue
            next_at = time.monotonic() + period
            try:
                frame = self._encode(composite)
            except (OSError, ValueError) as exc:
                with self._lock:
                    self._errors += 1
                log.warning("live view: frame %d not encoded: %s", composite.frame.frame_number, exc)
                continue
            with self._lock:
                self._latest = frame
                clients = list(self._clients)
            for client in clients:
                client.put(frame)

    def _encode(self, composite: Composite) -> ViewFrame:
        assert self._scratch_dir is not None  # made by start(), before this thread runs
        small = downscale(composite.rgb, self.max_width)
        jpeg = encode_jpeg(small, self._scratch_dir / "frame.jpg", quality=self.quality)
        with self._lock:
            self._encoded += 1
            sequence = self._encoded
        frame = composite.frame
        return ViewFrame(sequence, jpeg, small.shape[1], small.shape[0], frame.run_id, frame.frame_number,
                         frame.sim_time_s, composite.time)
