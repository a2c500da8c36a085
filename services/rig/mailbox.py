"""A subscriber's mailbox: bounded, drop-oldest, closed at the end of a run.

The host's frame stream and the compositor's composite stream hand items to each subscriber
through one; a subscriber that stalls loses its oldest items (counted), never slows the
producer or the other subscribers.
"""

from __future__ import annotations

import collections
import threading
from typing import Generic, TypeVar

T = TypeVar("T")


class Mailbox(Generic[T]):
    """Items for one subscriber, at most `depth` waiting.

    Attributes:
        dropped: items dropped because the subscriber fell behind.
    """

    def __init__(self, depth: int) -> None:
        if depth < 1:
            raise ValueError(f"depth: {depth} is not >= 1")
        self.depth = depth
        self.dropped = 0
        self._queue: collections.deque[T] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False

    def put(self, item: T) -> None:
        """Queue item, dropping the oldest waiting one if the mailbox is full."""
        with self._cond:
            if len(self._queue) >= self.depth:
                self._queue.popleft()
                self.dropped += 1
            self._queue.append(item)
            self._cond.notify_all()

    def close(self) -> None:
        """End the run: get returns what is left, then None at once."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def get(self, timeout_s: float) -> T | None:
        """The next item; None if none came within timeout_s or the run is over (see closed)."""
        with self._cond:
            self._cond.wait_for(lambda: self._queue or self._closed, timeout=timeout_s)
            return self._queue.popleft() if self._queue else None

    @property
    def closed(self) -> bool:
        """True once the run is over and every item was taken."""
        with self._cond:
            return self._closed and not self._queue
