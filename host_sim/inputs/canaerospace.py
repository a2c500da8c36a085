"""The CANaerospace control messages the host reads: the table, the codec and its DBC file.

A CANaerospace message (CANaerospace v1.7, Stock Flight Systems) is an 11-bit CAN frame whose
data field starts with a 4-byte header, then up to 4 bytes of big-endian data:

    byte 0 node id | 1 data type | 2 service code | 3 message code | 4.. data (big-endian)

The identifier says what the value is (normal operation data, 300-1799); the data type byte
says how it is encoded, so a receiver can check it. The message code counts the messages of
an identifier (modulo 256). The identifiers and names below are the standard's (its flight
controls block, 400-442; see docs/host-inputs.md for the source); the data types, ranges and
signs are what this host accepts.

`python -m host_sim.inputs.canaerospace` prints the DBC file (host_sim/data/
canaerospace_controls.dbc; tests/host_sim/inputs/test_canaerospace.py checks it is current).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from .base import Rejected

#: CANaerospace data type codes (the standard's AS_* values) -> (name, data bytes, struct format).
DATA_TYPES = {
    2: ("FLOAT", 4, ">f"),
    10: ("UCHAR", 1, ">B"),
}
FLOAT = 2
UCHAR = 10

#: Header length, bytes: node id, data type, service code, message code.
HEADER_BYTES = 4


@dataclass(frozen=True)
class Signal:
    """One control of the table.

    Attributes:
        can_id: 11-bit CAN identifier (CANaerospace normal operation data).
        name: signal name (also the DBC message and signal name).
        data_type: CANaerospace data type code accepted (FLOAT or UCHAR).
        lo, hi: accepted range, inclusive.
        unit: unit of the value.
        sense: what the positive (or larger) value means.
    """

    can_id: int
    name: str
    data_type: int
    lo: float
    hi: float
    unit: str
    sense: str

    @property
    def dlc(self) -> int:
        """Frame length: the header plus the data type's bytes."""
        return HEADER_BYTES + DATA_TYPES[self.data_type][1]


#: The controls read by the host, by identifier (docs/host-inputs.md).
CONTROLS: tuple[Signal, ...] = (
    Signal(400, "pitch_control_position", FLOAT, -1.0, 1.0, "norm", "aft +, forward -"),
    Signal(401, "roll_control_position", FLOAT, -1.0, 1.0, "norm", "right +, left -"),
    Signal(403, "yaw_control_position", FLOAT, -1.0, 1.0, "norm", "right pedal forward +"),
    Signal(414, "throttle_1_lever_position", FLOAT, 0.0, 1.0, "norm", "idle 0, full 1 (engine 1, ECS channel A)"),
    Signal(415, "throttle_2_lever_position", FLOAT, 0.0, 1.0, "norm", "idle 0, full 1 (engine 2, ECS channel A)"),
    Signal(416, "throttle_3_lever_position", FLOAT, 0.0, 1.0, "norm", "idle 0, full 1 (engine 3, ECS channel A)"),
    Signal(417, "throttle_4_lever_position", FLOAT, 0.0, 1.0, "norm", "idle 0, full 1 (engine 4, ECS channel A)"),
    Signal(430, "flaps_lever_position", FLOAT, 0.0, 1.0, "norm", "retracted 0, fully extended 1"),
    Signal(432, "park_brake_lever_position", UCHAR, 0.0, 1.0, "enum", "released 0, set 1"),
    Signal(433, "speed_brake_lever_position", FLOAT, 0.0, 1.0, "norm", "retracted 0, fully extended 1"),
    Signal(435, "left_brake_pedal_position", FLOAT, 0.0, 1.0, "norm",
           "released 0, fully pressed 1 (pilot's left toe brake)"),
    Signal(436, "right_brake_pedal_position", FLOAT, 0.0, 1.0, "norm",
           "released 0, fully pressed 1 (pilot's right toe brake)"),
)
BY_ID = {s.can_id: s for s in CONTROLS}
BY_NAME = {s.name: s for s in CONTROLS}


def check_value(signal: Signal, value: float) -> float:
    """value if it is finite and within the signal's range.

    Raises:
        Rejected: not_finite or out_of_range, naming the signal and value.
    """
    if not math.isfinite(value):
        raise Rejected("not_finite", f"{signal.name} ({signal.can_id}): {value} is not finite")
    if not signal.lo <= value <= signal.hi:
        raise Rejected("out_of_range", f"{signal.name} ({signal.can_id}): {value:g} is outside "
                                       f"[{signal.lo:g}, {signal.hi:g}]")
    return value


def decode(can_id: int, data: bytes, *, extended: bool = False) -> tuple[Signal, float]:
    """The signal and value of one CAN frame, checked against the table.

    Args:
        can_id: the frame's identifier.
        data: the frame's data bytes (its DLC is len(data)).
        extended: the frame has a 29-bit identifier (CANaerospace uses 11-bit ones only).

    Raises:
        Rejected: unknown_identifier, bad_length, wrong_data_type, not_finite or out_of_range.
    """
    signal = None if extended else BY_ID.get(can_id)
    if signal is None:
        kind = "29-bit identifier" if extended else "identifier"
        raise Rejected("unknown_identifier", f"{kind} {can_id} (0x{can_id:X}) is not a control of the table")
    if len(data) != signal.dlc:
        raise Rejected("bad_length", f"{signal.name} ({can_id}): {len(data)} bytes, expected {signal.dlc}")
    if data[1] != signal.data_type:
        expected = DATA_TYPES[signal.data_type][0]
        got = DATA_TYPES.get(data[1], (f"code {data[1]}",))[0]
        raise Rejected("wrong_data_type", f"{signal.name} ({can_id}): data type {got}, expected {expected}")
    (value,) = struct.unpack(DATA_TYPES[signal.data_type][2], bytes(data[HEADER_BYTES:]))
    return signal, check_value(signal, float(value))


def encode(name: str, value: float, *, node_id: int = 1, message_code: int = 0,
           service_code: int = 0) -> tuple[int, bytes]:
    """(identifier, data bytes) of one control message, as a cockpit node sends it.

    The value is not checked (tests send bad ones on purpose); a UCHAR value is rounded.
    """
    signal = BY_NAME[name]
    fmt = DATA_TYPES[signal.data_type][2]
    payload = struct.pack(fmt, int(round(value)) if signal.data_type == UCHAR else value)
    header = bytes([node_id & 0xFF, signal.data_type, service_code & 0xFF, message_code & 0xFF])
    return signal.can_id, header + payload


def dbc() -> str:
    """The control table as a DBC file, so that cantools and bus analysers decode the traffic.

    Each message carries the CANaerospace header as four 8-bit signals and the value as a
    big-endian (Motorola) signal in bytes 4 onwards: IEEE float for FLOAT, unsigned for UCHAR.
    """
    lines = ['VERSION ""', "", "", "NS_ :", "", "BS_:", "", "BU_: COCKPIT IG_HOST", ""]
    valtypes = []
    for s in CONTROLS:
        lines.append(f"BO_ {s.can_id} {s.name}: {s.dlc} COCKPIT")
        for i, header in enumerate(("node_id", "data_type", "service_code", "message_code")):
            # Motorola start bit = most significant bit: bit 7 of byte i.
            lines.append(f' SG_ {header} : {8 * i + 7}|8@0+ (1,0) [0|255] "" IG_HOST')
        if s.data_type == FLOAT:
            lines.append(f' SG_ {s.name} : 39|32@0- (1,0) [{s.lo:g}|{s.hi:g}] "{s.unit}" IG_HOST')
            valtypes.append(f"SIG_VALTYPE_ {s.can_id} {s.name} : 1;")
        else:
            lines.append(f' SG_ {s.name} : 39|8@0+ (1,0) [{s.lo:g}|{s.hi:g}] "{s.unit}" IG_HOST')
        lines.append("")
    lines.append('CM_ "CANaerospace flight controls read by the ig host (docs/host-inputs.md); '
                 'generated by python -m host_sim.inputs.canaerospace";')
    for s in CONTROLS:
        lines.append(f'CM_ SG_ {s.can_id} {s.name} "{s.sense}";')
    lines += valtypes
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(dbc(), end="")
