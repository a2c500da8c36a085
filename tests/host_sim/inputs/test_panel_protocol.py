"""The serial panel framing: CRC, round trip, and resynchronisation after any damage."""

from __future__ import annotations

import struct

from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.inputs import panel_protocol as pp
from host_sim.inputs.base import Rejected


def test_crc_is_ccitt_false():
    assert pp.crc16(b"123456789") == 0x29B1
    assert pp.crc16(b"") == 0xFFFF


def test_frame_layout():
    frame = pp.encode_frame(7, [(400, 0.5)])
    body = bytes([6, 7]) + struct.pack(">Hf", 400, 0.5)
    assert frame == bytes([0xA5]) + body + pp.crc16(body).to_bytes(2, "big")


def test_round_trip_and_records():
    events = pp.FrameDecoder().feed(pp.encode_frame(3, [(400, -0.5), (414, 1.0)]) + pp.encode_frame(4))
    assert events == [pp.PanelFrame(3, struct.pack(">HfHf", 400, -0.5, 414, 1.0)), pp.PanelFrame(4, b"")]
    recs = pp.records(events[0])
    assert [(s.name, v) for s, v in recs] == [("pitch_control_position", -0.5), ("throttle_1_lever_position", 1.0)]


def test_record_refusals():
    payload = struct.pack(">HfHfHf", 999, 0.0, 401, float("nan"), 401, 3.0)
    causes = [r.cause for r in pp.records(pp.PanelFrame(1, payload))]
    assert causes == ["unknown_identifier", "not_finite", "out_of_range"]
    [bad] = pp.records(pp.PanelFrame(1, payload[:-1]))
    assert bad.cause == "bad_length" and "17 bytes" in bad.detail


def causes(events):
    return [e.cause for e in events if isinstance(e, Rejected)]


def test_garbage_partial_frames_and_bad_crc_resynchronise():
    good = [pp.encode_frame(k, [(400, k / 10)]) for k in range(4)]
    damaged = bytearray(good[1])
    damaged[5] ^= 0xFF  # a flipped bit in the payload
    stream = b"\x00\x13" + good[0] + bytes(damaged) + good[2][:5] + good[3] + b"\xA5\xFF\x01"
    d = pp.FrameDecoder()
    events = d.feed(stream)
    frames = [e.seq for e in events if isinstance(e, pp.PanelFrame)]
    assert frames == [0, 3]  # 1 damaged, 2 cut short; 3 is found again after both
    assert causes(events).count("bad_crc") >= 1 and "bad_frame" in causes(events)
    assert "bad_length" in causes(events)  # 0xFF is no frame length
    assert not d.buffer and d.flush() == []  # the tail after the bad length was garbage


def test_flush_finds_frames_behind_a_false_start():
    frame = pp.encode_frame(9, [(401, 0.25)])
    d = pp.FrameDecoder()
    assert d.feed(b"\xA5" + frame) == []  # 0xA5 as a length: waits for 170 bytes
    events = d.flush()
    assert [e for e in events if isinstance(e, pp.PanelFrame)] == [pp.PanelFrame(9, frame[3:-2])]
    assert causes(events) == ["bad_frame"]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.binary(max_size=12), st.integers(0, 255),
                          st.lists(st.tuples(st.sampled_from([400, 401, 414]), st.floats(-1, 1, width=32)),
                                   max_size=3)), max_size=6),
       st.lists(st.integers(1, 40), max_size=8))
def test_every_intact_frame_is_found_whatever_is_between_and_however_the_bytes_arrive(parts, cuts):
    stream = bytearray()
    sent = []
    for garbage, seq, recs in parts:
        # Garbage between frames may contain start bytes and look like frame headers.
        stream += garbage
        frame = pp.encode_frame(seq, recs)
        stream += frame
        sent.append((seq, frame[3:-2]))
    d = pp.FrameDecoder()
    got = []
    pos = 0
    for n in cuts + [len(stream)]:  # feed in arbitrary pieces
        got += [e for e in d.feed(bytes(stream[pos:pos + n])) if isinstance(e, pp.PanelFrame)]
        pos += n
    got += [e for e in d.flush() if isinstance(e, pp.PanelFrame)]  # the line goes quiet
    assert not d.buffer
    got_pairs = [(f.seq, f.payload) for f in got]
    # Every frame sent is found, in order (garbage may rarely forge an extra valid frame, never lose one).
    it = iter(got_pairs)
    assert all(any(g == s for g in it) for s in sent), (sent, got_pairs)


def _events(stream: bytes, cuts: list[int]) -> list:
    """Everything a decoder makes of stream fed in pieces, then flushed (the line goes quiet)."""
    d = pp.FrameDecoder()
    events, pos = [], 0
    for n in [*cuts, len(stream)]:
        events += d.feed(stream[pos:pos + n])
        pos += n
    events += d.flush()
    assert not d.buffer
    return events


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300), st.lists(st.integers(1, 40), max_size=8))
def test_random_bytes_give_only_frames_and_refusals_and_every_byte_is_accounted_for(data, cuts):
    events = _events(data, cuts)
    assert all(isinstance(e, (pp.PanelFrame, Rejected)) for e in events)
    frames = [e for e in events if isinstance(e, pp.PanelFrame)]
    if data and not frames:
        assert any(isinstance(e, Rejected) for e in events)  # garbage is never passed over silently
    for frame in frames:  # whatever a forged frame holds, its records are values or refusals
        for record in pp.records(frame):
            assert isinstance(record, (Rejected, tuple))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(st.tuples(st.sampled_from([400, 401, 414, 432, 999]), st.floats(-2, 2, width=32)),
                         max_size=4), min_size=2, max_size=6),
       st.data(), st.lists(st.integers(1, 40), max_size=8))
def test_a_corrupted_frame_is_counted_and_the_frames_around_it_are_decoded(frames, data, cuts):
    encoded = [pp.encode_frame(seq, recs) for seq, recs in enumerate(frames)]
    bad = data.draw(st.integers(0, len(encoded) - 1))
    frame = bytearray(encoded[bad])
    # Corrupt one byte after the start byte (LEN, SEQ, payload or CRC): the CRC catches it.
    at = data.draw(st.integers(1, len(frame) - 1))
    frame[at] ^= data.draw(st.integers(1, 255))
    stream = b"".join(bytes(frame) if k == bad else f for k, f in enumerate(encoded))
    events = _events(stream, cuts)
    got = [(e.seq, e.payload) for e in events if isinstance(e, pp.PanelFrame)]
    sent = [(k, f[3:-2]) for k, f in enumerate(encoded) if k != bad]
    it = iter(got)
    assert all(any(g == s for g in it) for s in sent), (sent, got)
    assert (bad, encoded[bad][3:-2]) not in got
    assert any(isinstance(e, Rejected) and e.cause in ("bad_crc", "bad_length", "bad_frame") for e in events)
