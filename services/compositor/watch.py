"""Watchers of the composites (WatchComposites): each composite's time stamps and row profiles,
streamed to whoever asks, without ever slowing the rig down.

The gatherer's thread only appends the composite to each watcher's queue (bounded, oldest
dropped and counted, as the host does for its subscribers); the summary, row profiles
included, is computed on the watcher's own stream thread.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from ig.v1 import compositor_pb2, frame_pb2
from services.rig.colour import SRGB8_TO_LINEAR
from services.rig.mailbox import Mailbox

from .gather import CompleteFrame
from .timing import Composite

#: Composites a watcher may have waiting before the oldest is dropped (counted): half a second
#: at 15 Hz, and at most this many composites' pixels held for a watcher that stalls.
QUEUE_DEPTH = 8

#: Columns a row profile averages at most: the horizon's row needs every row, not every column.
PROFILE_COLUMNS = 256

#: Rec. 709 luminance of linear RGB.
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722], np.float32)


def row_profile(rgb: np.ndarray, *, max_columns: int = PROFILE_COLUMNS) -> np.ndarray:
    """Mean linear luminance of every row of an (H, W, 3) image, top row first, (H,) float32.

    The image is linear (float) or sRGB bytes (uint8, decoded by table). Every
    ceil(W / max_columns)-th column is averaged: a few milliseconds for a 1024 x 768 channel
    instead of ten.
    """
    stride = max(1, -(-rgb.shape[1] // max_columns))
    columns = rgb[:, ::stride]
    if columns.dtype == np.uint8:
        columns = SRGB8_TO_LINEAR[columns]
    return np.einsum("hwc,c->h", columns, _LUMINANCE, dtype=np.float32) / np.float32(columns.shape[1])


class Watch(Mailbox[Composite]):
    """One watcher's queue: bounded (QUEUE_DEPTH), drop-oldest, closed at the end of the run.

    Attributes:
        name: the watcher's name, for the log.
        profile_channels: channels whose row profile it wants.
        dropped: composites dropped because it fell behind.
    """

    def __init__(self, name: str, profile_channels: Sequence[str]) -> None:
        super().__init__(QUEUE_DEPTH)
        self.name = name
        self.profile_channels = tuple(profile_channels)


class Watchers:
    """The watchers of a compositor.

    Args:
        channels: rig channel names in display order.
    """

    def __init__(self, channels: Sequence[str]) -> None:
        self.channels = tuple(channels)
        self._lock = threading.Lock()
        self._watches: list[Watch] = []
        # Other consumers of every composite in the same process (the live view, liveview/),
        # fed the same way but not WatchComposites streams: len() leaves them out.
        self._feeds: list[Mailbox[Composite]] = []
        self._closed = False

    def add(self, name: str, profile_channels: Sequence[str]) -> Watch:
        """A new watcher, closed at once if the run is over.

        Raises:
            ValueError: a profile channel is not a rig channel (the message names it).
        """
        unknown = [c for c in profile_channels if c not in self.channels]
        if unknown:
            raise ValueError(f"profile_channels: {unknown[0]!r} is not a channel of the rig "
                             f"({', '.join(self.channels)})")
        watch = Watch(name, profile_channels)
        with self._lock:
            if self._closed:
                watch.close()
            self._watches.append(watch)
        return watch

    def attach(self, feed: Mailbox[Composite]) -> None:
        """Hand every composite to feed too (bounded, never waits), closed with the watchers."""
        with self._lock:
            if self._closed:
                feed.close()
            self._feeds.append(feed)

    def __len__(self) -> int:
        """Watchers connected now."""
        with self._lock:
            return len(self._watches)

    def remove(self, watch: Watch) -> None:
        """Forget a watcher whose stream ended."""
        with self._lock:
            if watch in self._watches:
                self._watches.remove(watch)

    def publish(self, composite: Composite) -> None:
        """Hand a composite to every watcher (never waits)."""
        with self._lock:
            watches = [*self._watches, *self._feeds]
        for watch in watches:
            watch.put(composite)

    def close(self) -> None:
        """The run is over: every stream ends once its queue is empty."""
        with self._lock:
            self._closed = True
            watches = [*self._watches, *self._feeds]
        for watch in watches:
            watch.close()


def summary(composite: Composite, watch: Watch) -> compositor_pb2.WatchCompositesResponse:
    """The WatchCompositesResponse of a composite for one watcher (row profiles computed here)."""
    frame: CompleteFrame = composite.frame
    x, y, z, h, p, r = frame.eyepoint
    by_name = {img.channel: img for img in frame.images}
    return compositor_pb2.WatchCompositesResponse(
        host_frame_number=frame.host_frame_number,
        frame_number=frame.frame_number, run_id=frame.run_id, sim_time_s=frame.sim_time_s,
        eyepoint=frame_pb2.Eyepoint(x=x, y=y, z=z, heading_deg=h, pitch_deg=p, roll_deg=r),
        control_sample_time_unix_s=frame.control_sample_time, publish_time_unix_s=frame.publish_time,
        composite_time_unix_s=composite.time,
        channels=[compositor_pb2.ChannelTiming(
            channel_name=img.channel, frame_received_unix_s=img.timing.frame_received,
            render_start_unix_s=img.timing.render_start, render_end_unix_s=img.timing.render_end,
            submit_unix_s=img.timing.submit, compositor_receive_unix_s=img.timing.compositor_receive)
            for img in frame.images],
        profiles=[compositor_pb2.RowProfile(channel_name=c, luminance=row_profile(by_name[c].rgb))
                  for c in watch.profile_channels],
        watcher_drops=watch.dropped)
