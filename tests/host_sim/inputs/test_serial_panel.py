"""Serial panels: frames through pyserial's loop:// and through a pty, damage counted."""

from __future__ import annotations

import os
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_sim.inputs import open_source
from host_sim.inputs.base import Controls
from host_sim.inputs.panel_protocol import encode_frame
from host_sim.inputs.serial_panel import PARTIAL_TIMEOUT_S

pytest.importorskip("serial", reason="pyserial is in the devices extra")


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def panel():
    clock = FakeClock()
    src = open_source("serial+loop://", clock=clock)
    yield src, src.port, clock
    src.close()


def test_panel_frames_set_the_controls(panel):
    src, port, _ = panel
    port.write(encode_frame(0, [(414, 0.5), (415, 0.7), (430, 1.0)]) + encode_frame(1, [(432, 1.0), (433, 0.5)]))
    assert src.poll() == 5
    assert src.latest() == Controls(throttle=pytest.approx(0.6), flaps=1.0, park_brake=1.0, speed_brake=0.5)
    assert src.status().counters == {"frames": 2}


def test_damage_is_counted_and_the_good_frames_around_it_are_read(panel):
    src, port, clock = panel
    bad_crc = bytearray(encode_frame(1, [(400, 0.9)]))
    bad_crc[-1] ^= 1
    port.write(b"noise" + encode_frame(0, [(400, 0.1)]) + bytes(bad_crc) + encode_frame(2, [(401, 0.2), (999, 0.0)])
               + encode_frame(4, [(402, 0.0)]) + encode_frame(5, payload=b"\x01\x90\x00")
               + encode_frame(6, [(400, 0.3)])
               + encode_frame(7, [(400, 0.0)])[:6])  # the last frame is cut short
    src.poll()
    status = src.status()
    assert src.latest().pitch == pytest.approx(0.3) and src.latest().roll == pytest.approx(0.2)
    assert status.rejected["bad_crc"] == 1
    assert status.rejected["unknown_identifier"] == 2  # 999, and 402 (lateral trim is not read)
    assert status.rejected["bad_length"] == 1  # a 3-byte payload
    assert status.rejected["bad_frame"] >= 1  # the noise
    assert status.counters["sequence_gaps"] == 2  # 1 lost to the CRC, 3 never sent
    before = status.rejected["bad_frame"]
    clock.t += PARTIAL_TIMEOUT_S / 2
    src.poll()
    assert src.status().rejected["bad_frame"] == before  # still waiting for the rest
    clock.t += PARTIAL_TIMEOUT_S
    src.poll()
    # the cut frame is dropped: its start byte, then the rest as bytes outside a frame
    assert src.status().rejected["bad_frame"] == before + 2


def test_heartbeats_keep_a_panel_fresh_and_silence_makes_it_stale(panel):
    src, port, clock = panel
    port.write(encode_frame(0, [(400, -0.4)]))
    src.poll()
    for k in range(1, 6):
        clock.t += 0.3
        port.write(encode_frame(k))  # nothing changed
        src.poll()
        assert not src.status().stale
    clock.t += src.stale_after_s + 0.1
    src.poll()
    assert src.status().stale and src.status().rejected["stale"] == 1
    assert src.latest().pitch == pytest.approx(-0.4)


def test_a_panel_on_a_pty():
    master, slave = os.openpty()
    try:
        src = open_source(f"serial://{os.ttyname(slave)}?baud=115200")
        try:
            os.write(master, b"\x00\xff" + encode_frame(0, [(400, 0.25), (401, -0.75)]))
            deadline = time.monotonic() + 10.0
            while src.status().accepted < 2 and time.monotonic() < deadline:
                src.poll()
                time.sleep(0.01)
            assert src.latest() == Controls(pitch=0.25, roll=-0.75)
            assert src.status().rejected["bad_frame"] == 1
        finally:
            src.close()
    finally:
        os.close(master)
        os.close(slave)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.binary(max_size=20).filter(lambda b: 0xA5 not in b),
                          st.floats(-1, 1, width=32)), min_size=1, max_size=6))
def test_garbage_between_frames_is_counted_and_every_value_arrives(parts):
    clock = FakeClock()
    with open_source("serial+loop://", clock=clock) as src:
        port = src.port  # type: ignore[attr-defined]
        for seq, (garbage, pitch) in enumerate(parts):
            port.write(garbage + encode_frame(seq, [(400, pitch)]))
            assert src.poll() == 1  # the frame behind the garbage, in the same poll
            assert src.latest().pitch == pitch
        status = src.status()
        # Garbage without a start byte is counted once per run of bytes between two frames.
        assert status.rejected["bad_frame"] == sum(1 for garbage, _ in parts if garbage)
        assert sum(status.rejected.values()) == status.rejected["bad_frame"]
        assert status.counters["frames"] == len(parts) and "sequence_gaps" not in status.counters
