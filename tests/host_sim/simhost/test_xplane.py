"""X-Plane: the RPOS request, RPOS replies and DATA rows 17/20.

X-Plane cannot run here: every packet in these tests is synthetic, built from the layout in
Laminar Research's "Exchanging Data with X-Plane" (the Wireshark dissector packet-xplane.c
has the same offsets), and a local socket plays X-Plane.
"""

from __future__ import annotations

import socket
import struct

import pytest

from host_sim.simhost import open_simhost
from host_sim.simhost.stream import Malformed, PoseStream
from host_sim.simhost.xplane import DataRows, XPlaneSource, decode_rpos, rpos_request

ORIGIN = (47.0, 8.0, 400.0)


def rpos(lon=8.01, lat=47.02, elev=1200.0, pitch=3.0, heading=271.0, roll=-10.0, flag=b"4") -> bytes:
    """An RPOS reply laid out field by field: header, 3 doubles, 10 floats, little-endian."""
    return (b"RPOS" + flag + struct.pack("<ddd", lon, lat, elev) + struct.pack("<f", 35.0)
            + struct.pack("<fff", pitch, heading, roll) + struct.pack("<3f", 50.0, -1.0, 2.0)
            + struct.pack("<3f", 0.01, 0.02, 0.03))


def data(*rows: tuple[int, list[float]], flag=b"*") -> bytes:
    return b"DATA" + flag + b"".join(struct.pack("<i8f", i, *(v + [-999.0] * (8 - len(v)))) for i, v in rows)


def test_rpos_request_is_the_rate_as_nul_terminated_ascii():
    assert rpos_request(60) == b"RPOS\x0060\x00"
    assert rpos_request(0) == b"RPOS\x000\x00"


def test_rpos_reply_fields():
    packet = rpos()
    assert len(packet) == 69
    pose = decode_rpos(packet)
    assert (pose.lon_deg, pose.lat_deg, pose.alt_m) == (8.01, 47.02, 1200.0)
    assert (pose.pitch_deg, pose.heading_deg, pose.roll_deg) == (3.0, 271.0, -10.0)


@pytest.mark.parametrize("packet,cause", [(rpos()[:64], "truncated"), (rpos() + b"\0", "oversized"),
                                          (rpos(lat=91.0), "out_of_range")])
def test_bad_rpos(packet, cause):
    with pytest.raises(Malformed) as exc:
        decode_rpos(packet)
    assert exc.value.cause == cause


def test_data_rows_17_and_20_make_a_pose_with_altitude_in_feet():
    rows = DataRows()
    assert rows.decode(data((17, [3.0, -10.0, 271.0, 268.0]))) is None  # no position yet
    pose = rows.decode(data((20, [47.02, 8.01, 1000.0, 20.0])))
    assert pose is not None
    assert pose.lat_deg == pytest.approx(47.02) and pose.lon_deg == pytest.approx(8.01)
    assert pose.alt_m == pytest.approx(304.8)
    assert (pose.heading_deg, pose.pitch_deg, pose.roll_deg) == (271.0, 3.0, -10.0)
    assert rows.decode(data((3, [100.0]))) is None  # a row the rig does not read


@pytest.mark.parametrize("packet,cause", [(data((17, [3.0, -10.0, 271.0]))[:-4], "truncated"),
                                          (data((20, [-999.0, 8.0, 1000.0])), "missing")])
def test_bad_data(packet, cause):
    with pytest.raises(Malformed) as exc:
        DataRows().decode(packet)
    assert exc.value.cause == cause


def test_requests_rpos_and_reads_the_replies_from_the_request_s_source():
    """A socket playing X-Plane receives the request and answers the address it came from."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as xplane:
        xplane.bind(("127.0.0.1", 0))
        xplane.settimeout(10.0)
        url = f"xplane://127.0.0.1:{xplane.getsockname()[1]}?listen=127.0.0.1:0&rate=30"
        with open_simhost(url, origin=ORIGIN) as source:
            request, reply_to = xplane.recvfrom(100)
            assert request == b"RPOS\x0030\x00"
            assert reply_to[1] == source.address[1]
            xplane.sendto(b"BECN\0garbage", reply_to)
            xplane.sendto(rpos(), reply_to)
            assert source.stream.wait_for(1, timeout_s=10.0)
            status = source.status()
        assert xplane.recvfrom(100)[0] == b"RPOS\x000\x00"  # stopped at close
    assert status.accepted == 1 and status.refused == {"garbage": 1} and status.requests_sent == 1


def test_the_request_is_sent_again():
    stream = PoseStream("x", origin=ORIGIN)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as xplane:
        xplane.bind(("127.0.0.1", 0))
        source = XPlaneSource(("127.0.0.1", 0), stream, xplane=xplane.getsockname(), rate_hz=60)
        try:
            for now in (0.0, 1.0, 4.9, 5.0, 9.0, 10.0):
                source.tick(now)  # the reader's clock, driven by hand
        finally:
            source.sock.close()
    assert stream.status().requests_sent == 3  # at 0, 5 and 10 s
