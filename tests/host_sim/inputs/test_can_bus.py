"""CANaerospace controls from python-can buses: the virtual bus, and slcan over a pty."""

from __future__ import annotations

import os
import struct
import time

import pytest

from host_sim.inputs import canaerospace as ca
from host_sim.inputs import open_source
from host_sim.inputs.base import CAUSES, Controls

can = pytest.importorskip("can", reason="python-can is in the devices extra")


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def message(name, value, **kw):
    can_id, data = ca.encode(name, value, **kw)
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=False)


@pytest.fixture
def bus(request):
    channel = f"test-{request.node.name}"
    clock = FakeClock()
    src = open_source(f"can://virtual/{channel}", clock=clock)
    tx = can.Bus(interface="virtual", channel=channel)
    yield src, tx, clock
    tx.shutdown()
    src.close()


def test_controls_arrive_and_bad_frames_are_counted_by_cause(bus):
    src, tx, _ = bus
    good = [message("pitch_control_position", 0.5), message("roll_control_position", -0.25),
            message("yaw_control_position", 0.125), message("throttle_1_lever_position", 0.5),
            message("throttle_2_lever_position", 1.0), message("flaps_lever_position", 0.5),
            message("speed_brake_lever_position", 0.25), message("park_brake_lever_position", 1)]
    bad = [
        can.Message(arbitration_id=999, data=bytes(8), is_extended_id=False),  # unknown identifier
        can.Message(arbitration_id=400, data=bytes([1, 2, 0, 0]) + struct.pack(">f", 0.1),
                    is_extended_id=True),  # 29-bit
        can.Message(arbitration_id=400, data=bytes([1, 2, 0, 0, 0]), is_extended_id=False),  # bad length
        can.Message(arbitration_id=401, data=bytes([1, 7, 0, 0, 0, 0, 0, 1]), is_extended_id=False),  # USHORT
        message("roll_control_position", float("nan")),
        message("pitch_control_position", 1.01),
        can.Message(arbitration_id=400, is_remote_frame=True, dlc=8, is_extended_id=False),
    ]
    for m in good + bad:
        tx.send(m)
    assert src.poll() == len(good)
    assert src.latest() == Controls(pitch=0.5, roll=-0.25, yaw=0.125, throttle=0.75, flaps=0.5, speed_brake=0.25,
                                    park_brake=1.0)
    status = src.status()
    assert status.accepted == len(good)
    assert status.rejected == {**dict.fromkeys(CAUSES, 0), "unknown_identifier": 2, "bad_length": 1,
                               "wrong_data_type": 1, "not_finite": 1, "out_of_range": 1, "bad_frame": 1}
    assert "remote frame" in status.last_rejection
    assert status.counters["frames"] == len(good) + len(bad)
    assert not status.stale


def test_a_refused_value_leaves_the_last_good_one(bus):
    src, tx, _ = bus
    tx.send(message("pitch_control_position", 0.3))
    src.poll()
    for bad in (float("nan"), 2.0, -7.0):
        tx.send(message("pitch_control_position", bad))
    src.poll()
    assert src.latest().pitch == pytest.approx(0.3)


def test_a_silent_source_goes_stale_after_the_timeout_and_holds(bus):
    src, tx, clock = bus
    assert src.status().stale  # nothing received yet (not counted as a stale event)
    tx.send(message("roll_control_position", 0.5))
    src.poll()
    assert not src.status().stale
    clock.t += src.stale_after_s  # exactly the timeout: still fresh
    src.poll()
    assert not src.status().stale
    clock.t += 0.01
    src.poll()
    src.poll()  # counted once per silence, not per poll
    status = src.status()
    assert status.stale and status.rejected["stale"] == 1 and "holding the last values" in status.last_rejection
    assert status.last_input_age_s == pytest.approx(src.stale_after_s + 0.01)
    assert src.latest().roll == 0.5
    tx.send(message("roll_control_position", -0.5))
    src.poll()
    assert not src.status().stale and src.latest().roll == -0.5
    clock.t += 10.0
    src.poll()
    assert src.status().rejected["stale"] == 2


def test_a_device_error_is_counted_and_the_values_hold(bus):
    src, tx, _ = bus
    tx.send(message("pitch_control_position", 0.2))
    src.poll()

    def broken(timeout=None):
        raise can.CanOperationError("adapter unplugged")
    recv, src.bus.recv = src.bus.recv, broken
    for _ in range(5):
        src.poll()
    status = src.status()
    assert status.rejected["device_error"] == 1 and "adapter unplugged" in status.last_rejection  # once
    assert src.latest().pitch == pytest.approx(0.2)
    src.bus.recv = recv  # plugged in again
    src.poll()
    src.bus.recv = broken
    src.poll()
    assert src.status().rejected["device_error"] == 2


def test_slcan_over_a_pty():
    """CAN over serial: the host opens the pty's device as an slcan adapter; the test is the adapter."""
    master, slave = os.openpty()
    try:
        os.set_blocking(master, False)
        src = open_source(f"can://slcan{os.ttyname(slave)}@115200?sleep_after_open=0")
        try:
            time.sleep(0.05)
            assert b"O\r" in os.read(master, 100)  # the host opened the channel
            can_id, data = ca.encode("pitch_control_position", -0.5)
            os.write(master, f"t{can_id:03X}{len(data)}{data.hex().upper()}\r".encode())
            can_id, data = ca.encode("park_brake_lever_position", 1)
            os.write(master, f"t{can_id:03X}{len(data)}{data.hex().upper()}\r".encode())
            deadline = time.monotonic() + 10.0
            while src.status().accepted < 2 and time.monotonic() < deadline:
                src.poll()
                time.sleep(0.01)
            assert src.latest() == Controls(pitch=-0.5, park_brake=1.0)
        finally:
            src.close()
    finally:
        os.close(master)
        os.close(slave)


#: A sender in another process: what can://virtual cannot reach and udp_multicast can.
_SENDER = """
import sys, time, can
from host_sim.inputs import canaerospace as ca
can_id, data = ca.encode("pitch_control_position", 0.25)
with can.Bus(interface="udp_multicast", channel=sys.argv[1], port=int(sys.argv[2])) as bus:
    for _ in range(200):
        bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
        time.sleep(0.01)
"""


def test_udp_multicast_feeds_a_host_from_another_process():
    import socket
    import subprocess
    import sys

    pytest.importorskip("msgpack", reason="udp_multicast needs msgpack (the devices extra)")
    with socket.socket() as s:  # a port no other test run is using
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    group = "239.74.163.2"
    try:
        src = open_source(f"can://udp_multicast/{group}?port={port}")
    except ValueError as exc:
        pytest.skip(f"this machine cannot join a multicast group: {exc}")
    with src:
        sender = subprocess.Popen([sys.executable, "-c", _SENDER, group, str(port)], stderr=subprocess.PIPE)
        try:
            while sender.poll() is None and not src.poll():
                time.sleep(0.01)
            src.poll()
        finally:
            sender.kill()
            _, err = sender.communicate()
        if src.status().accepted == 0:
            pytest.skip(f"multicast on this machine delivered nothing to the same host ({err.decode()[-200:]!r})")
        assert src.latest().pitch == 0.25
        assert sum(src.status().rejected.values()) == 0
