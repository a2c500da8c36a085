"""The CANaerospace control table: codec, refusals, and the DBC file that bus tools decode with."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.inputs import canaerospace as ca
from host_sim.inputs.base import Rejected

cantools = pytest.importorskip("cantools", reason="cantools is a test dependency")

DBC = Path(ca.__file__).resolve().parent.parent / "data" / "canaerospace_controls.dbc"


def test_the_checked_in_dbc_is_the_table():
    assert DBC.read_text() == ca.dbc(), "regenerate: python -m host_sim.inputs.canaerospace > " + str(DBC)


def test_identifiers_are_the_standards_normal_operation_flight_controls():
    ids = {s.name: s.can_id for s in ca.CONTROLS}
    assert ids["pitch_control_position"] == 400
    assert ids["roll_control_position"] == 401
    assert ids["yaw_control_position"] == 403
    assert [ids[f"throttle_{k}_lever_position"] for k in (1, 2, 3, 4)] == [414, 415, 416, 417]
    assert (ids["flaps_lever_position"], ids["park_brake_lever_position"], ids["speed_brake_lever_position"]) \
        == (430, 432, 433)
    # can_as.h: PLT_LEFT_BRAKE_POS_ID 435, PLT_RIGHT_BRAKE_POS_ID 436 (the pilot's toe brakes).
    assert (ids["left_brake_pedal_position"], ids["right_brake_pedal_position"]) == (435, 436)
    assert all(400 <= i <= 442 and i < 2048 for i in ids.values())  # the flight-controls block; 11-bit


def test_frame_layout_is_header_then_big_endian_data():
    can_id, data = ca.encode("pitch_control_position", -0.25, node_id=7, message_code=42, service_code=0)
    assert can_id == 400
    assert data == bytes([7, ca.FLOAT, 0, 42]) + struct.pack(">f", -0.25)
    can_id, data = ca.encode("park_brake_lever_position", 1, node_id=3)
    assert (can_id, data) == (432, bytes([3, ca.UCHAR, 0, 0, 1]))


signals = st.sampled_from(ca.CONTROLS)


@given(signals, st.data(), st.integers(0, 255), st.integers(0, 255))
def test_cantools_decodes_what_the_host_decodes(signal, data, node_id, message_code):
    db = cantools.database.load_file(str(DBC))
    if signal.data_type == ca.UCHAR:
        value = float(data.draw(st.integers(int(signal.lo), int(signal.hi))))
    else:
        value = data.draw(st.floats(signal.lo, signal.hi, width=32))
    can_id, payload = ca.encode(signal.name, value, node_id=node_id, message_code=message_code)
    ours = ca.decode(can_id, payload)
    theirs = db.decode_message(can_id, payload)
    assert ours == (signal, value)
    assert theirs[signal.name] == value
    assert (theirs["node_id"], theirs["data_type"], theirs["message_code"]) == (node_id, signal.data_type,
                                                                               message_code)
    # and the other way: what cantools encodes from the DBC, the host decodes
    encoded = db.encode_message(can_id, {"node_id": node_id, "data_type": signal.data_type, "service_code": 0,
                                         "message_code": message_code, signal.name: value})
    assert ca.decode(can_id, encoded) == (signal, value)


@pytest.mark.parametrize("can_id,data,extended,cause,words", [
    (999, b"\x01\x02\x00\x00\x00\x00\x00\x00", False, "unknown_identifier", "999"),
    (400, b"\x01\x02\x00\x00\x00\x00\x00\x00", True, "unknown_identifier", "29-bit"),
    (400, b"\x01\x02\x00\x00\x00\x00", False, "bad_length", "6 bytes, expected 8"),
    (400, b"\x01\x06\x00\x00\x00\x00\x00\x00", False, "wrong_data_type", "code 6"),
    (432, b"\x01\x02\x00\x00\x00\x00\x00\x00", False, "bad_length", "8 bytes, expected 5"),
    (432, b"\x01\x02\x00\x00\x01", False, "wrong_data_type", "FLOAT, expected UCHAR"),
    (400, bytes([1, 2, 0, 0]) + struct.pack(">f", math.nan), False, "not_finite", "nan"),
    (400, bytes([1, 2, 0, 0]) + struct.pack(">f", math.inf), False, "not_finite", "inf"),
    (400, bytes([1, 2, 0, 0]) + struct.pack(">f", 1.5), False, "out_of_range", "1.5 is outside [-1, 1]"),
    (414, bytes([1, 2, 0, 0]) + struct.pack(">f", -0.1), False, "out_of_range", "throttle_1"),
    (432, b"\x01\x0a\x00\x00\x02", False, "out_of_range", "park_brake"),
])
def test_refusals_name_their_cause(can_id, data, extended, cause, words):
    with pytest.raises(Rejected) as err:
        ca.decode(can_id, data, extended=extended)
    assert err.value.cause == cause and words in err.value.detail


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.integers(-(1 << 40), 1 << 40), st.sampled_from([s.can_id for s in ca.CONTROLS])),
       st.binary(max_size=64), st.booleans())
def test_any_identifier_and_payload_decode_or_are_refused_by_cause(can_id, data, extended):
    try:
        signal, value = ca.decode(can_id, data, extended=extended)
    except Rejected as rejection:
        assert rejection.cause in ("unknown_identifier", "bad_length", "wrong_data_type", "not_finite",
                                   "out_of_range")
        assert str(can_id) in rejection.detail
    else:
        assert signal.can_id == can_id and not extended and len(data) == signal.dlc
        assert data[1] == signal.data_type and signal.lo <= value <= signal.hi
