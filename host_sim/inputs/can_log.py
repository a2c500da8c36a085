"""CANaerospace controls replayed from a recorded CAN log at its recorded timing.

URL: `canlog:///path/to/flight.asc` (also .blf and .trc, read by python-can's readers; a
relative path is `canlog:relative/flight.asc`). Option: `stale_after` (seconds).

Timing follows the caller's clock, not the wall clock: a frame recorded t seconds after the
first one is delivered by the first poll(now_s) with now_s >= start + t (within a
nanosecond), where start is the now_s of the first poll. The host polls with simulation time
before every flight-model step, so a replayed log drives the model identically on every run
and at every frame rate, however slowly the rig renders.

A record a reader cannot parse, or passes over as unreadable, is counted (`bad_frame`) and
skipped: text logs (.asc, .trc) go on at the next line; a binary .blf log ends at the damaged
record (its container cannot be resynchronised), counted once as `device_error`.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO, cast

from .base import ControlSource, Rejected
from .can_bus import frame_value

log = logging.getLogger("ig.host.inputs")

#: Log suffixes and whether python-can reads them as text (resynchronised line by line).
SUFFIXES = {".asc": True, ".trc": True, ".blf": False}
#: Lines of a .asc log that are events, not frames: skipped without counting.
_EVENTS = ("Start of measurement", "Statistic")


class _Lines:
    """A list of text lines served as a file to python-can's readers, counting what it read."""

    def __init__(self, lines: list[str]) -> None:
        self.lines = lines
        self.read = 0

    def __iter__(self) -> _Lines:
        return self

    def __next__(self) -> str:
        if self.read >= len(self.lines):
            raise StopIteration
        self.read += 1
        return self.lines[self.read - 1]

    def close(self) -> None:
        pass


class CanLogSource(ControlSource):
    """Replays a .asc, .blf or .trc CAN log (module doc).

    Args:
        name: the URL.
        path: the log file.
        **kw: ControlSource arguments (stale_after_s); the clock is the time given to poll().

    Raises:
        ValueError: the suffix is not a CAN log format, or the file does not exist.
    """

    def __init__(self, name: str, *, path: str, **kw: Any) -> None:
        kw.pop("clock", None)
        super().__init__(name, **kw)
        self.path = Path(path)
        if self.path.suffix.lower() not in SUFFIXES:
            raise ValueError(f"{name}: {self.path.suffix or 'no suffix'} is not a CAN log "
                             f"({', '.join(SUFFIXES)})")
        if not self.path.is_file():
            raise ValueError(f"{name}: {self.path}: no such file")
        self._time = 0.0  # the caller's time of the last poll
        self._start: float | None = None  # the caller's time of the first poll
        self._t0: float | None = None  # log time of the first frame
        self._messages = self._records()
        self._pending = next(self._messages, None)
        #: True once every frame of the log has been delivered.
        self.finished = self._pending is None

    def _now(self, now_s: float | None) -> float:
        if now_s is not None:
            self._time = float(now_s)
        return self._time

    def _read(self, now_s: float | None) -> None:
        now = self._now(now_s)
        if self._start is None:
            self._start = now
        while self._pending is not None:
            msg = self._pending
            if self._t0 is None:
                self._t0 = msg.timestamp
            # Within a nanosecond: a step at 0.3 s must get the frame recorded at 0.3 s even
            # when the two times round differently.
            if msg.timestamp - self._t0 > now - self._start + 1e-9:
                return
            self._count("frames")
            try:
                signal, value = frame_value(msg)
                self._accept(signal.name, value, now)
            except Rejected as rejection:
                self._reject(rejection)
            self._pending = next(self._messages, None)
        self.finished = True

    def _records(self) -> Iterator[Any]:
        """Every message of the log in file order; unparsable records counted and skipped."""
        import can  # optional dependency (the `devices` extra)

        suffix = self.path.suffix.lower()
        if not SUFFIXES[suffix]:
            try:
                with can.LogReader(str(self.path)) as reader:
                    yield from reader
            except Exception as exc:
                self._reject(Rejected("device_error", f"{self.path.name}: {type(exc).__name__}: {exc}; "
                                                      f"the rest of the log is skipped"))
            return
        reader_class = can.ASCReader if suffix == ".asc" else can.TRCReader
        lines = self.path.read_text(errors="replace").splitlines(keepends=True)
        # The header (format, base, trigger block) is everything before the first record; a
        # record starts with a number (.asc time stamp, .trc message number). After a record
        # that makes the reader fail, a new reader starts on the header and the lines after it.
        head = len(list(itertools.takewhile(lambda s: not s.strip()[:1].isdigit(), lines)))
        offset = head  # index in lines of the first body line given to the reader
        while True:
            source = _Lines(lines[:head] + lines[offset:])

            def line_index(j: int, offset: int = offset) -> int:  # index in lines of the reader's line j
                return j if j < head else offset + j - head

            done = 0  # reader lines accounted for
            try:
                # The readers need only iteration and close() of what they are given.
                for msg in reader_class(cast(TextIO, source)):
                    self._skipped(lines, [line_index(j) for j in range(done, source.read - 1)])
                    done = source.read
                    yield msg
                self._skipped(lines, [line_index(j) for j in range(done, source.read)])
                return
            except Exception as exc:
                bad = line_index(source.read - 1)  # the line the reader was parsing
                self._skipped(lines, [line_index(j) for j in range(done, source.read - 1)])
                self._reject(Rejected("bad_frame", f"{self.path.name} line {bad + 1}: "
                                                   f"{type(exc).__name__}: {exc}"))
                if bad < offset:  # the header itself: nothing more can be read
                    return
                offset = bad + 1

    def _skipped(self, lines: list[str], indices: list[int]) -> None:
        """Count the record lines the reader passed over without a message (it skips what
        it cannot match); event lines it skips by design are not counted."""
        for i in indices:
            text = lines[i].strip()
            if text[:1].isdigit() and not any(event in text for event in _EVENTS):
                self._reject(Rejected("bad_frame", f"{self.path.name} line {i + 1}: not a CAN record: "
                                                   f"{text[:40]!r}"))
