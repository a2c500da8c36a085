"""The rig's FlightGear generic protocol: deploy/flightgear/ig.xml and its reader agree."""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from host_sim.simhost.fgfs_generic import CHUNKS, LAYOUT, FgGenericSource, decode_generic
from host_sim.simhost.stream import Malformed, PoseStream

IG_XML = Path(__file__).resolve().parents[3] / "deploy" / "flightgear" / "ig.xml"


def test_ig_xml_is_the_layout_the_reader_reads():
    root = ET.parse(IG_XML).getroot()
    output = root.find("generic/output")
    assert output is not None and output.findtext("binary_mode") == "true"
    assert output.find("byte_order") is None  # the default: network order, as LAYOUT ('>')
    chunks = [(c.findtext("node"), c.findtext("type"), float(c.findtext("factor") or 1.0))
              for c in output.findall("chunk")]
    codes = {"double": "d", "float": "f"}
    assert [(node, codes[kind], factor) for node, kind, factor in chunks] == list(CHUNKS)
    assert LAYOUT.format == ">" + "".join(code for _, code, _ in CHUNKS).replace("dddd", "4d").replace(
        "fffffffff", "9f")
    assert LAYOUT.size == 68


def datagram(t=10.0, lat=36.6, lon=-84.2, alt_m=500.0, roll=1.0, pitch=2.0, heading=3.0, view=(0.0,) * 6) -> bytes:
    return struct.pack(">4d9f", t, lat, lon, alt_m, roll, pitch, heading, *view)


def test_decode_reads_every_field():
    pose = decode_generic(datagram(view=(0.1, 0.2, -0.3, 10.0, -5.0, 0.0)))
    assert (pose.lat_deg, pose.lon_deg, pose.alt_m) == (36.6, -84.2, 500.0)
    assert (pose.roll_deg, pose.pitch_deg, pose.heading_deg) == (1.0, 2.0, 3.0)
    assert pose.host_time_s == 10.0
    assert dict(pose.extra)["view_z_offset_m"] == pytest.approx(-0.3)
    assert dict(pose.extra)["view_heading_offset_deg"] == 10.0


@pytest.mark.parametrize("data,cause", [(datagram()[:-1], "truncated"), (datagram() + b"\0", "oversized"),
                                        (datagram(heading=float("inf")), "not_finite")])
def test_bad_datagrams(data, cause):
    with pytest.raises(Malformed) as exc:
        decode_generic(data)
    assert exc.value.cause == cause


def test_simulation_time_orders_the_datagrams_and_a_jump_back_is_a_restart():
    stream = PoseStream("g", origin=(36.6, -84.2, 349.0), clock=lambda: 0.0, wall=lambda: 0.0)
    source = FgGenericSource(("127.0.0.1", 0), stream)
    try:
        source.receive(datagram(t=10.0), arrival=0.0)
        source.receive(datagram(t=10.05), arrival=0.01)
        source.receive(datagram(t=10.02), arrival=0.02)  # overtaken on the way: refused
        source.receive(datagram(t=2.0), arrival=0.03)  # the simulator was reset
        status = stream.status()
        assert status.accepted == 3 and status.refused == {"out_of_order": 1} and status.restarts == 1
    finally:
        source.close()
