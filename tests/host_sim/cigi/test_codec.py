"""The CIGI codec: round trips for every packet kind, version and byte order; garbage raises
CigiError only; hand-written datagrams (struct.pack here, not the encoder) decode as expected."""

from __future__ import annotations

import contextlib
import dataclasses
import struct
import typing

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.cigi.codec import (
    RAW_PACKETS,
    SUPPORTED_VERSIONS,
    bench_decode,
    decode,
    encode,
    kinds_of,
    layout_fields,
)
from host_sim.cigi.packets import (
    V3_2,
    V3_3,
    V4_0,
    CigiError,
    EntityControl,
    EntityControlV4,
    EntityPosition,
    HatHotRequest,
    HatHotResponse,
    IGControl,
    LosVectorRequest,
    RawPacket,
    StartOfFrame,
    Version,
)

IG_TO_HOST = {"StartOfFrame", "HatHotResponse", "HatHotExtendedResponse", "LosResponse", "LosExtendedResponse"}
ORDERS = ("<", ">")

# Value ranges of the wire fields, by struct format; bit fields are bounded by their width.
_f32 = st.floats(width=32, allow_nan=False)
_f64 = st.floats(allow_nan=False)


def _field_strategy(version: Version, kind: type, name: str) -> st.SearchStrategy[typing.Any]:
    from host_sim.cigi.codec import _BY_KIND, Seq

    layout = _BY_KIND[version, "<"][kind]
    for fmt, slot in layout.spec:
        if isinstance(slot, tuple):
            for bit in slot:
                if bit.name == name:
                    return st.booleans() if bit.is_bool else st.integers(0, (1 << bit.width) - 1)
        elif isinstance(slot, Seq) and slot.name == name:
            return st.tuples(*[st.integers(0, 2**32 - 1)] * slot.count)
        elif slot == name:
            return {"B": st.integers(0, 255), "b": st.integers(-128, 127), "H": st.integers(0, 2**16 - 1),
                    "I": st.integers(0, 2**32 - 1), "f": _f32, "d": _f64}[fmt]
    raise AssertionError(name)


def _packet_strategy(version: Version, kind: type) -> st.SearchStrategy[typing.Any]:
    return st.builds(kind, **{n: _field_strategy(version, kind, n) for n in layout_fields(version, kind)})


CASES = [(v, k) for v in SUPPORTED_VERSIONS for k in kinds_of(v)]


def _first(kind: type, version: Version) -> typing.Any:
    return StartOfFrame() if kind.__name__ in IG_TO_HOST else IGControl()


@pytest.mark.parametrize(("version", "kind"), CASES, ids=[f"{v}-{k.__name__}" for v, k in CASES])
@pytest.mark.parametrize("order", ORDERS)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_round_trip_every_kind(version: Version, kind: type, order: str, data: st.DataObject) -> None:
    packet = data.draw(_packet_strategy(version, kind))
    first = _first(kind, version)
    sender = "ig" if isinstance(first, StartOfFrame) else "host"
    wire = encode([first, packet], version, order)
    message = decode(wire, sender=sender)
    assert (message.version, message.byte_order) == (version, order)
    assert message.packets == (first, packet)
    assert encode(message.packets, version, order) == wire


@pytest.mark.parametrize("version", SUPPORTED_VERSIONS)
@pytest.mark.parametrize("order", ORDERS)
@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_raw_packets_re_encode_exactly(version: Version, order: str, data: st.DataObject) -> None:
    pid, (_, fixed) = data.draw(st.sampled_from(sorted(RAW_PACKETS[version].items())))
    header = 4 if version.major >= 4 else 2
    length = fixed - header if fixed is not None else data.draw(st.integers(0, 12)) * 8 + 8 - header
    raw = RawPacket(pid, data.draw(st.binary(min_size=length, max_size=length)))
    wire = encode([IGControl(), raw], version, order)
    message = decode(wire)
    assert message.packets == (IGControl(), raw)
    assert encode(message.packets, version, order) == wire


def test_unknown_ids_are_skipped_and_counted() -> None:
    wire = encode([IGControl(), RawPacket(250, bytes(6)), RawPacket(250, bytes(14)), HatHotRequest()], V3_3, "<")
    message = decode(wire)
    assert message.skipped == {250: 2}
    assert message.packets == (IGControl(), HatHotRequest())


def test_golden_little_endian_ig_control_from_an_x86_ccl_host() -> None:
    wire = bytes.fromhex("0118030031000080") + struct.pack("<III4x", 7, 123, 6)
    message = decode(wire)
    assert (message.version, message.byte_order) == (V3_3, "<")
    assert message.packets == (IGControl(ig_mode=1, host_frame=7, timestamp=123, last_ig_frame=6),)


def test_big_endian_datagram_written_by_hand() -> None:
    ig = struct.pack(">BBBbBxHIII4x", 1, 24, 3, 5, 0x35, 0x8000, 42, 1000, 41)
    entity = struct.pack(">BBHBBBxHHfffddd", 2, 48, 0, 0x01, 0x10, 255, 0, 0, 1.5, -2.0, 90.0, 36.3, -84.2, 300.0)
    hot = struct.pack(">BBHBBHddd", 24, 32, 7, 0x01, 0, 0, 36.3, -84.2, 0.0)
    message = decode(ig + entity + hot)
    assert (message.version, message.byte_order) == (V3_3, ">")
    assert message.packets == (
        IGControl(database_number=5, ig_mode=1, timestamp_valid=True, host_frame=42, timestamp=1000,
                  last_ig_frame=41),
        EntityControl(entity_state=1, smoothing=True, roll=1.5, pitch=-2.0, yaw=90.0, lat_x=36.3, lon_y=-84.2,
                      alt_z=300.0),
        HatHotRequest(request_id=7, request_type=1, lat_x=36.3, lon_y=-84.2),
    )


@pytest.mark.parametrize("order", ORDERS)
def test_cigi_4_datagram_written_by_hand(order: str) -> None:
    ig = struct.pack(order + "HHBbBBIII4x", 24, 0x0000, 4, 0, 0, 0x01, 10, 9, 555)
    position = struct.pack(order + "HHBxHH2xfffddd", 48, 0x01, 0, 0, 0, 0.0, 5.0, 180.0, 36.3, -84.2, 300.0)
    control = struct.pack(order + "HHBBHBBHBBBB", 16, 0x25, 0x01, 255, 0, 1, 2, 225, 1, 2, 3, 0)
    hot = struct.pack(order + "HHHHBB6xddd", 40, 0x17, 3, 0, 0x01, 0, 36.3, -84.2, 0.0)
    message = decode(ig + position + control + hot)
    assert (message.version, message.byte_order) == (V4_0, order)
    assert message.packets == (
        IGControl(ig_mode=1, host_frame=10, last_ig_frame=9, timestamp=555),
        EntityPosition(pitch=5.0, yaw=180.0, lat_x=36.3, lon_y=-84.2, alt_z=300.0),
        EntityControlV4(entity_state=1, alpha=255, entity_kind=1, entity_domain=2, entity_type=225,
                        entity_category=1, entity_subcategory=2, entity_specific=3),
        HatHotRequest(request_id=3, request_type=1, lat_x=36.3, lon_y=-84.2),
    )


def test_cigi_4_response_height_is_a_double() -> None:
    sof = struct.pack("<HHBbxBIII2H", 24, 0xFFFF, 4, 0, 0x01, 3, 0, 2, 0, 0)
    resp = struct.pack("<HHBxHd", 16, 0x0FFF, 0x03 | (2 << 4), 7, 123.456789012345)
    message = decode(sof + resp, sender="ig")
    assert message.packets[1] == HatHotResponse(request_id=7, valid=True, response_type=1, host_frame_lsn=2,
                                                height=123.456789012345)


@pytest.mark.parametrize(("wire", "sender", "cause"), [
    (b"", "host", "empty"),
    (bytes.fromhex("01180300"), "host", "truncated"),
    (bytes.fromhex("651803003100008000000000000000000000000000000000"), "host", "first_packet"),
    (bytes.fromhex("011803003100008000000000000000000000000000000000"), "ig", "first_packet"),
    (bytes.fromhex("011802003100008000000000000000000000000000000000"), "host", "version"),
    (bytes.fromhex("011803001100008000000000000000000000000000000000"), "host", "version"),
    (bytes.fromhex("011803003100123400000000000000000000000000000000"), "host", "magic"),
    (bytes.fromhex("011803003100008000000000000000000000000000000000") + bytes(2), "host", "bad_size"),
    (bytes.fromhex("011803003100008000000000000000000000000000000000") + bytes((24, 40)), "host", "truncated"),
])
def test_bad_datagrams_name_their_cause(wire: bytes, sender: str, cause: str) -> None:
    with pytest.raises(CigiError) as info:
        decode(wire, sender=sender)
    assert info.value.cause == cause


def test_size_mismatch_names_packet_field_and_value() -> None:
    wire = encode([IGControl(), EntityControl()], V3_3, "<") + bytes((24, 40)) + bytes(38)
    with pytest.raises(CigiError, match=r"packet 3 \(id 24 HAT/HOT Request\) at byte 72: size 40 differs from 32"):
        decode(wire)


def test_encode_refuses_kinds_and_values_the_version_lacks() -> None:
    with pytest.raises(CigiError, match=r"EntityPosition does not exist in CIGI 3\.3") as info:
        encode([EntityPosition()], V3_3, "<")
    assert info.value.cause == "packet_kind"
    with pytest.raises(CigiError, match=r"EntityControl does not exist in CIGI 4\.0"):
        encode([EntityControl()], V4_0, "<")
    with pytest.raises(CigiError, match="ig_mode = 7"):
        encode([IGControl(ig_mode=7)], V3_3, "<")
    with pytest.raises(CigiError, match="request_id = 70000"):
        encode([HatHotRequest(request_id=70000)], V3_3, "<")
    with pytest.raises(CigiError, match="version"):
        encode([IGControl()], Version(3, 1), "<")


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=200), st.sampled_from(["host", "ig"]))
def test_garbage_raises_cigi_error_only(wire: bytes, sender: str) -> None:
    with contextlib.suppress(CigiError):
        decode(wire, sender=sender)


@st.composite
def _valid_then_damaged(draw: st.DrawFn) -> bytes:
    version = draw(st.sampled_from(SUPPORTED_VERSIONS))
    order = draw(st.sampled_from(ORDERS))
    kinds = [k for k in kinds_of(version) if k.__name__ not in IG_TO_HOST]
    body = draw(st.lists(st.sampled_from(kinds).flatmap(lambda k: _packet_strategy(version, k)), max_size=4))
    wire = bytearray(encode([IGControl(), *body], version, order))
    cut = draw(st.integers(0, len(wire)))
    del wire[cut:]
    for _ in range(draw(st.integers(0, 3))):
        if wire:
            wire[draw(st.integers(0, len(wire) - 1))] = draw(st.integers(0, 255))
    return bytes(wire)


@settings(max_examples=300, deadline=None)
@given(_valid_then_damaged())
def test_truncated_and_corrupted_datagrams_raise_cigi_error_only(wire: bytes) -> None:
    with contextlib.suppress(CigiError):
        decode(wire)


def test_wrong_first_packet_for_each_version() -> None:
    for version in SUPPORTED_VERSIONS:
        for order in ORDERS:
            wire = encode([HatHotRequest(), IGControl()], version, order)
            with pytest.raises(CigiError) as info:
                decode(wire)
            assert info.value.cause in {"first_packet", "version"}
            with pytest.raises(CigiError) as info:
                decode(encode([IGControl()], version, order), sender="ig")
            assert info.value.cause == "first_packet"


def test_3_2_entity_control_has_no_smoothing_bit() -> None:
    assert "smoothing" not in layout_fields(V3_2, EntityControl)
    assert "smoothing" in layout_fields(V3_3, EntityControl)


def test_los_vector_request_keeps_fields() -> None:
    packet = LosVectorRequest(los_id=3, elevation=-90.0, max_range=5000.0, src_lat_x=36.3, update_period=2)
    assert decode(encode([IGControl(), packet], V3_3, "<")).packets[1] == packet


def test_bench_decode_runs() -> None:
    assert bench_decode(iterations=3) > 0.0


def test_every_dataclass_field_has_a_default() -> None:
    for version in SUPPORTED_VERSIONS:
        for kind in kinds_of(version):
            kind()  # all defaults
            assert dataclasses.is_dataclass(kind)
