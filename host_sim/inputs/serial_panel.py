"""Controls from serial panel hardware speaking the framed protocol of panel_protocol.py.

URL: `serial:///dev/ttyUSB0?baud=115200` for a device (`serial:///COM3` on Windows), or
`serial+PYSERIAL_URL` for any pyserial URL handler: `serial+loop://` (tests),
`serial+socket://panel.local:7000`, `serial+rfc2217://...`. Options: `baud` (default 115200)
and `stale_after` (seconds); a pyserial URL keeps its own options.

A panel's bytes are read without blocking at every poll. A frame left incomplete for
PARTIAL_TIMEOUT_S (the panel stopped mid-frame, or a false start byte) is dropped and counted,
and the bytes behind it are parsed again (FrameDecoder.flush).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from . import panel_protocol
from .base import ControlSource, Rejected

DEFAULT_BAUD = 115200
#: Silence after which a partial frame is dropped, seconds (about 70 frames at 115200 baud).
PARTIAL_TIMEOUT_S = 0.1
#: Most bytes one poll reads.
MAX_BYTES_PER_POLL = 65536


class SerialPanelSource(ControlSource):
    """Reads panel frames from a serial port (module doc for the URL).

    Args:
        name: the URL.
        port_url: what pyserial opens (a device path or a pyserial URL).
        baud: serial speed, bit/s.
        clock: monotonic clock, seconds (staleness and the partial-frame timeout).
        **kw: ControlSource arguments (stale_after_s).

    Raises:
        ValueError: the port cannot be opened (the message names it).
    """

    def __init__(self, name: str, *, port_url: str, baud: int = DEFAULT_BAUD,
                 clock: Callable[[], float] = time.monotonic, **kw: Any) -> None:
        super().__init__(name, clock=clock, **kw)
        import serial  # optional dependency (the `devices` extra)

        try:
            self.port = serial.serial_for_url(port_url, baudrate=baud, timeout=0)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise ValueError(f"{name}: cannot open serial port {port_url!r}: {exc}") from exc
        self.decoder = panel_protocol.FrameDecoder()
        self._last_byte = clock()
        self._last_seq: int | None = None

    def _read(self, now_s: float | None) -> None:
        waiting = self.port.in_waiting
        data = self.port.read(min(waiting, MAX_BYTES_PER_POLL)) if waiting else b""
        now = self.clock()
        if data:
            self._last_byte = now
            self.handle(self.decoder.feed(data), now_s)
        elif self.decoder.buffer and now - self._last_byte > PARTIAL_TIMEOUT_S:
            self.handle(self.decoder.flush(), now_s)

    def handle(self, events: list[panel_protocol.PanelFrame | Rejected], now_s: float | None = None) -> None:
        """Accept or count every record and every piece of damage the decoder found."""
        for event in events:
            if isinstance(event, Rejected):
                self._reject(event)
                continue
            self._count("frames")
            if self._last_seq is not None and event.seq != (self._last_seq + 1) & 0xFF:
                self._count("sequence_gaps")  # frames lost (or repeated) on the line
            self._last_seq = event.seq
            if not event.payload:
                self._heartbeat(now_s)
            for record in panel_protocol.records(event):
                if isinstance(record, Rejected):
                    self._reject(record)
                else:
                    self._accept(record[0].name, record[1], now_s)

    def close(self) -> None:
        self.port.close()
