"""CANaerospace controls replayed from a recorded CAN log at its recorded timing.

URL: `canlog:///path/to/flight.asc` (also .blf and .trc, read by python-can's readers; a
relative path is `canlog:relative/flight.asc`). Option: `stale_after` (seconds).

Timing follows the caller's clock, not the wall clock: a frame recorded t seconds after the
first one is delivered by the first poll(now_s) with now_s >= start + t (within a
nanosecond), where start is the now_s of the first poll. The host polls with simulation time
before every flight-model step, so a replayed log drives the model identically on every run
and at every frame rate, however slowly the rig renders.

Every line of a text log (.asc, .trc) is either part of the format (header, comment, blank
line, trigger block, measurement start, bus statistics: passed over) or a record. A record
that is not a usable control frame is counted by cause (base.CAUSES): `bad_frame` when no
CAN frame can be read from it (the reader skips it or fails on it), a non-finite time stamp,
or a remote or error frame; otherwise the cause canaerospace.decode gives (identifier not in
the table, wrong length or data type, value not finite or out of range). Reading goes on at
the next line. A binary .blf log ends at a damaged record (its container cannot be
resynchronised), counted once as `device_error`.

A log without a single usable frame is refused when it is opened (ValueError naming the file
and the counts by cause): replaying it would fly with neutral controls.
"""

from __future__ import annotations

import logging
import math
import re
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO, cast

from .base import ControlSource, Rejected
from .can_bus import frame_value

log = logging.getLogger("ig.host.inputs")


def _not_a_counted_line(record: logging.LogRecord) -> bool:
    # python-can's TRC reader warns about every line it cannot parse; those lines are counted
    # here (bad_frame) and logged a bounded number of times, so a log of garbage does not
    # flood the host's log with one warning per line.
    return not record.getMessage().startswith("TRCReader: Failed to parse message")


logging.getLogger("can.io.trc").addFilter(_not_a_counted_line)

#: Log suffixes and whether python-can reads them as text (resynchronised line by line).
SUFFIXES = {".asc": True, ".trc": True, ".blf": False}

#: Lines of a .asc log that python-can's reader takes as its header (date, number base,
#: comments, the internal-events line); given to the reader before the records.
_ASC_HEADER = re.compile(r"//.*|date\s+\S.*|base\s+(hex|dec)(\s+timestamps\s+(absolute|relative))?"
                         r"|(no\s+)?internal\s+events\s+logged", re.IGNORECASE)
#: Other lines of the .asc format that carry no frame: trigger blocks and the events that
#: Vector's tools write between frames (measurement start, bus statistics, chip status).
_ASC_EVENT = re.compile(r"(begin|end)\s+triggerblock\b.*|\d+\.\d+\s+(start\s+of\s+measurement"
                        r"|\d+\s+statistic:.*|can\s+\d+\s+status:.*)", re.IGNORECASE)
#: Closes the header given to the .asc reader: it takes the first line that is not a header
#: line as the end of the header and drops it, which must not be a record.
_ASC_END_OF_HEADER = "no internal events logged\n"
_ASC_EVENTS_LOGGED = re.compile(r"(no\s+)?internal\s+events\s+logged", re.IGNORECASE)


class _Lines:
    """Header lines then records[start:], served as a file to python-can's readers; counts
    the lines read, so that what the reader passed over can be told from what it parsed."""

    def __init__(self, header: list[str], records: list[tuple[int, str]], start: int) -> None:
        self.header = header
        self.records = records
        self.start = start
        self.read = 0

    def __iter__(self) -> _Lines:
        return self

    def __next__(self) -> str:
        j = self.read
        if j < len(self.header):
            self.read += 1
            return self.header[j]
        k = self.start + j - len(self.header)
        if k >= len(self.records):
            raise StopIteration
        self.read += 1
        return self.records[k][1]

    def record(self, j: int) -> int | None:
        """Index in records of the reader's line j, None for a header line."""
        return None if j < len(self.header) else self.start + j - len(self.header)

    def close(self) -> None:
        pass


class CanLogSource(ControlSource):
    """Replays a .asc, .blf or .trc CAN log (module doc).

    Args:
        name: the URL.
        path: the log file.
        **kw: ControlSource arguments (stale_after_s); the clock is the time given to poll().

    Raises:
        ValueError: the suffix is not a CAN log format, the file does not exist or cannot be
            read, or it holds no usable control frame (the message counts its lines by cause).
    """

    def __init__(self, name: str, *, path: str, **kw: Any) -> None:
        kw.pop("clock", None)
        super().__init__(name, **kw)
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in SUFFIXES:
            raise ValueError(f"{name}: {self.path.suffix or 'no suffix'} is not a CAN log "
                             f"({', '.join(SUFFIXES)})")
        if not self.path.is_file():
            raise ValueError(f"{name}: {self.path}: no such file")
        self._text: list[str] | None = None
        if SUFFIXES[suffix]:
            try:
                # Universal newlines, then one line per "\n" as the readers see the file (not
                # str.splitlines, which also splits at form feeds and other separators).
                text = self.path.read_text(errors="replace")
            except OSError as exc:
                raise ValueError(f"{name}: {self.path}: cannot be read: {exc}") from None
            self._text = [line + "\n" for line in text.split("\n")]
            if self._text[-1] == "\n":
                self._text.pop()
        self._check_usable()
        self._time = 0.0  # the caller's time of the last poll
        self._start: float | None = None  # the caller's time of the first poll
        self._t0: float | None = None  # log time of the first frame
        self._events = self._records()
        self._pending = self._next()
        #: True once every frame of the log has been delivered.
        self.finished = self._pending is None

    def _check_usable(self) -> None:
        """Refuse a log in which no frame gives a control value, counting its lines by cause.

        Reads up to the first usable frame (all of a log that has none); the replay reads the
        log again from its start, so that its counters see every line at its time.
        """
        refused: Counter[str] = Counter()
        first = ""
        frames = 0
        for event in self._records():
            try:
                if isinstance(event, Rejected):
                    raise event
                frames += 1
                frame_value(event)
                return
            except Rejected as rejection:
                refused[rejection.cause] += 1
                first = first or str(rejection)
        counts = ", ".join(f"{n} {cause}" for cause, n in sorted(refused.items()))
        raise ValueError(f"{self.name}: {self.path.name} has no usable CANaerospace control frame "
                         f"({frames} CAN frame(s) read; refused: {counts or 'nothing'}"
                         f"{'; first: ' + first if first else ''})")

    def _now(self, now_s: float | None) -> float:
        if now_s is not None:
            self._time = float(now_s)
        return self._time

    def _next(self) -> Any:
        """The next CAN message of the log, counting the refused records on the way; None at the end."""
        for event in self._events:
            if isinstance(event, Rejected):
                self._reject(event)
            else:
                return event
        return None

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
            self._pending = self._next()
        self.finished = True

    def _records(self) -> Iterator[Any]:
        """Every CAN message of the log in file order, and a Rejected for every record that
        gives none (module doc)."""
        import can  # optional dependency (the `devices` extra)

        if self._text is None:
            try:
                # The file is opened here, so that it is closed when the reader fails on its header.
                with open(self.path, "rb") as file, can.BLFReader(file) as reader:
                    for msg in reader:
                        yield self._timed(msg, "")
            except Exception as exc:
                yield Rejected("device_error", f"{self.path.name}: {type(exc).__name__}: {exc}; "
                                               f"the rest of the log is skipped")
            return
        if self.path.suffix.lower() == ".asc":
            reader_class: Any = can.ASCReader
            header, records = self._split(_ASC_HEADER, _ASC_EVENT)
            header = [line for line in header if not _ASC_EVENTS_LOGGED.fullmatch(line.strip())]
            header.append(_ASC_END_OF_HEADER)
        else:
            reader_class = can.TRCReader
            header, records = self._split(re.compile(r";.*"), None)
        start = 0  # index in records of the first record given to the current reader
        while start < len(records):
            source = _Lines(header, records, start)
            done = 0  # reader lines accounted for
            try:
                # The readers need only iteration and close() of what they are given.
                for msg in reader_class(cast(TextIO, source)):
                    yield from self._passed_over(source, records, done, source.read - 1)
                    done = source.read
                    k = source.record(done - 1)
                    yield self._timed(msg, "" if k is None else f" line {records[k][0] + 1}")
                yield from self._passed_over(source, records, done, source.read)
                return
            except Exception as exc:
                failed = source.record(source.read - 1)
                yield from self._passed_over(source, records, done, source.read - 1)
                reason = f"{type(exc).__name__}: {exc}"
                if failed is None:
                    # The reader failed on a header line: without it, read on from the
                    # record where this reader started.
                    i = source.read - 1
                    log.warning("%s: %s: a header line is ignored: %r: %s", self.name, self.path.name,
                                header[i].strip()[:60], reason)
                    header = header[:i] + header[i + 1:]
                    continue
                yield Rejected("bad_frame", f"{self.path.name} line {records[failed][0] + 1}: {reason}: "
                                            f"{records[failed][1].strip()[:60]!r}")
                start = failed + 1

    def _split(self, header_line: re.Pattern[str], event_line: re.Pattern[str] | None
               ) -> tuple[list[str], list[tuple[int, str]]]:
        """(header lines before the first record, [(line index, text)] of every record)."""
        assert self._text is not None
        header: list[str] = []
        records: list[tuple[int, str]] = []
        for i, line in enumerate(self._text):
            text = line.strip()
            if not text or (event_line is not None and event_line.fullmatch(text)):
                continue
            if header_line.fullmatch(text):
                if not records:
                    header.append(line)
                continue
            records.append((i, line))
        return header, records

    def _passed_over(self, source: _Lines, records: list[tuple[int, str]], first: int, end: int
                     ) -> Iterator[Rejected]:
        """A Rejected for each record among the reader's lines first..end-1: it passed them
        over without a message (it skips what does not match its record pattern)."""
        for j in range(first, end):
            k = source.record(j)
            if k is not None:
                i, line = records[k]
                yield Rejected("bad_frame", f"{self.path.name} line {i + 1}: not a CAN frame record: "
                                            f"{line.strip()[:60]!r}")

    def _timed(self, msg: Any, where: str) -> Any:
        """msg, or a Rejected if its time stamp is not a finite number of seconds (the replay
        could never deliver it, or would deliver everything at once)."""
        if not math.isfinite(msg.timestamp):
            return Rejected("bad_frame", f"{self.path.name}{where}: time stamp {msg.timestamp} is not finite")
        return msg
