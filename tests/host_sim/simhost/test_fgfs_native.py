"""FGNetFDM datagrams: golden v24 packets built field by field from the offset table of
FlightGear's net_fdm.hxx (as JSBSim's FGOutputFG fills it), v25 recognised, bad ones counted."""

from __future__ import annotations

import math
import socket
import struct

import pytest

from host_sim.simhost import open_simhost
from host_sim.simhost.fgfs_native import decode_fgnetfdm
from host_sim.simhost.stream import Malformed

ORIGIN = (36.6089, -84.1708, 349.2)


def v24(*, lon_deg=-84.17, lat_deg=36.61, alt_m=450.0, phi_deg=0.0, theta_deg=0.0, psi_deg=0.0,
        version=24, size=408) -> bytes:
    """An FGNetFDM datagram laid out by hand, one struct.pack_into per row of the offset table
    (not through the decoder's struct), every other field filled with a distinct value so that a
    decoder reading the wrong offset reads the wrong number."""
    pkt = bytearray(size)
    struct.pack_into(">I", pkt, 0, version)
    struct.pack_into(">I", pkt, 4, 0xDEADBEEF)  # padding
    struct.pack_into(">d", pkt, 8, math.radians(lon_deg))
    struct.pack_into(">d", pkt, 16, math.radians(lat_deg))
    struct.pack_into(">d", pkt, 24, alt_m)
    struct.pack_into(">f", pkt, 32, 12.5)  # agl
    struct.pack_into(">f", pkt, 36, math.radians(phi_deg))
    struct.pack_into(">f", pkt, 40, math.radians(theta_deg))
    struct.pack_into(">f", pkt, 44, math.radians(psi_deg))
    for off in range(48, 120, 4):  # alpha .. slip_deg: none of them is a pose
        struct.pack_into(">f", pkt, off, 1000.0 + off)
    struct.pack_into(">I", pkt, 120, 1)  # num_engines
    struct.pack_into(">I", pkt, 356, 1234567890)  # cur_time, JSBSim's constant
    return bytes(pkt)


def test_every_pose_field_of_a_hand_built_v24():
    pose = decode_fgnetfdm(v24(lon_deg=-95.163839, lat_deg=29.759526, alt_m=271.2, phi_deg=-7.3, theta_deg=16.8,
                               psi_deg=206.1))
    assert pose.lat_deg == pytest.approx(29.759526, abs=1e-12)
    assert pose.lon_deg == pytest.approx(-95.163839, abs=1e-12)
    assert pose.alt_m == 271.2
    # The angles are float32 radians: about 1e-7 rad.
    assert pose.roll_deg == pytest.approx(-7.3, abs=1e-5)
    assert pose.pitch_deg == pytest.approx(16.8, abs=1e-5)
    assert pose.heading_deg == pytest.approx(206.1, abs=1e-5)
    assert pose.host_time_s is None  # cur_time is not a clock (JSBSim's constant)


def test_v25_is_read_with_the_same_header():
    pose = decode_fgnetfdm(v24(version=25, size=552, lat_deg=10.0, psi_deg=45.0))
    assert pose.lat_deg == pytest.approx(10.0) and pose.heading_deg == pytest.approx(45.0, abs=1e-5)


@pytest.mark.parametrize("datagram,cause,words", [
    (v24()[:300], "truncated", "version 24 of 300 bytes, not 408"),
    (v24() + b"\0", "oversized", "version 24 of 409 bytes, not 408"),
    (v24(version=25), "truncated", "version 25 of 408 bytes, not 552"),
    (v24(version=23), "version", "FGNetFDM version 23 (408 bytes)"),
    (b"\x00\x00", "truncated", "2 bytes"),
    (b"hello, world", "garbage", "12 bytes"),
    (v24(lat_deg=95.0), "out_of_range", "lat_deg 95"),
    (v24(alt_m=float("nan")), "not_finite", "alt_m nan"),
])
def test_bad_datagrams_are_refused_by_cause(datagram, cause, words):
    with pytest.raises(Malformed) as exc:
        decode_fgnetfdm(datagram)
    assert exc.value.cause == cause and words in exc.value.detail


def test_a_udp_round_trip_counts_the_bad_and_keeps_reading(caplog):
    with open_simhost("fgfs://127.0.0.1:0", origin=ORIGIN) as source, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        for datagram in (b"junk", v24(version=23), v24()[:100], v24()[:100], v24(psi_deg=90.0)):
            sender.sendto(datagram, source.address)
        assert source.stream.wait_for(1, timeout_s=10.0)
        status = source.status()
    assert status.accepted == 1
    assert status.refused == {"garbage": 1, "version": 1, "truncated": 2}
    assert status.values["heading_deg"] == pytest.approx(90.0, abs=1e-5)
    # Each cause named once in the log, however often it comes.
    assert sum("truncated" in r.getMessage() for r in caplog.records) == 1
