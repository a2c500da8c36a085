"""The framed binary protocol of serial control panels (docs/serial-protocol.md).

    0xA5 | LEN | SEQ | PAYLOAD (LEN bytes) | CRC (2 bytes, big-endian)

CRC is CRC-16/CCITT-FALSE (polynomial 0x1021, initial value 0xFFFF, no reflection, no final
XOR) over LEN, SEQ and PAYLOAD. The payload is a sequence of 6-byte records, each a
CANaerospace identifier (uint16, big-endian) and its value (IEEE float32, big-endian), so a
panel and a CAN node share one control table (canaerospace.CONTROLS). LEN 0 is a heartbeat.

The decoder is a pure function of the bytes fed to it: it resynchronises after garbage,
partial frames and CRC failures by dropping one byte at a time and looking for the next start
byte, so a good frame that follows damage is still found. A frame that waits for bytes that
never come (cut short, or a start byte in garbage whose length byte points past the frames
behind it) is dropped by flush(), which the serial source calls when the line has been quiet
for PARTIAL_TIMEOUT_S; the frames behind it are then found.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from . import canaerospace
from .base import Rejected

START = 0xA5
#: Largest payload: 40 records. A LEN above it cannot start a frame.
MAX_PAYLOAD = 240
RECORD = struct.Struct(">Hf")


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of data (check value: crc16(b"123456789") == 0x29B1)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def encode_frame(seq: int, records: list[tuple[int, float]] | None = None, *, payload: bytes | None = None) -> bytes:
    """One frame: the given (identifier, value) records, or a raw payload (for tests)."""
    if payload is None:
        payload = b"".join(RECORD.pack(can_id, value) for can_id, value in records or [])
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload: {len(payload)} bytes is more than {MAX_PAYLOAD}")
    body = bytes([len(payload), seq & 0xFF]) + payload
    return bytes([START]) + body + crc16(body).to_bytes(2, "big")


@dataclass(frozen=True)
class PanelFrame:
    """A frame whose CRC matched: sequence number and payload."""

    seq: int
    payload: bytes


def records(frame: PanelFrame) -> list[tuple[canaerospace.Signal, float] | Rejected]:
    """The checked (signal, value) of every record of a frame, or why each was refused.

    A payload that is not a whole number of records is refused whole (bad_length).
    """
    if len(frame.payload) % RECORD.size:
        return [Rejected("bad_length", f"frame {frame.seq}: payload of {len(frame.payload)} bytes is not "
                                       f"a whole number of {RECORD.size}-byte records")]
    out: list[tuple[canaerospace.Signal, float] | Rejected] = []
    for can_id, value in RECORD.iter_unpack(frame.payload):
        signal = canaerospace.BY_ID.get(can_id)
        try:
            if signal is None:
                raise Rejected("unknown_identifier", f"frame {frame.seq}: identifier {can_id} is not a control")
            out.append((signal, canaerospace.check_value(signal, float(value))))
        except Rejected as rejection:
            out.append(rejection)
    return out


class FrameDecoder:
    """Turns a byte stream into frames and rejections, whatever the stream holds."""

    def __init__(self) -> None:
        self.buffer = bytearray()

    def feed(self, data: bytes) -> list[PanelFrame | Rejected]:
        """Frames completed by data, and each piece of damage found, in stream order."""
        self.buffer += data
        out: list[PanelFrame | Rejected] = []
        buf = self.buffer
        while buf:
            start = buf.find(START)
            if start != 0:
                skipped = len(buf) if start < 0 else start
                out.append(Rejected("bad_frame", f"{skipped} byte(s) outside a frame skipped"))
                del buf[:skipped]
                continue
            if len(buf) < 2:
                break  # wait for LEN
            length = buf[1]
            if length > MAX_PAYLOAD:
                out.append(Rejected("bad_length", f"frame length {length} is more than {MAX_PAYLOAD}"))
                del buf[:1]
                continue
            total = 3 + length + 2
            if len(buf) < total:
                break  # wait for the rest of the frame
            body = bytes(buf[1:3 + length])
            crc = int.from_bytes(buf[3 + length:total], "big")
            if crc16(body) != crc:
                out.append(Rejected("bad_crc", f"frame {buf[2]} of {length} bytes: CRC {crc:04X}, "
                                               f"computed {crc16(body):04X}"))
                del buf[:1]  # the start byte was false or the frame damaged: look further on
                continue
            out.append(PanelFrame(seq=buf[2], payload=body[2:]))
            del buf[:total]
        return out

    def flush(self) -> list[PanelFrame | Rejected]:
        """The sender has gone quiet: what the buffer still holds cannot be completed.

        A frame waiting for more bytes is either cut short or a false start (a start byte in
        garbage, whose length byte swallowed the frames after it): drop its start byte,
        counted, and parse the rest again, so that frames behind a false start are found.
        """
        out: list[PanelFrame | Rejected] = []
        while self.buffer:
            out.append(Rejected("bad_frame", f"incomplete frame dropped ({len(self.buffer)} byte(s) waiting)"))
            del self.buffer[:1]
            out += self.feed(b"")
        return out
