"""The CIGI endpoint over real UDP against the scripted host, with a fake query service: Start
of Frame each frame, answers in the next one with the host frame's nibble, values converted
from the world and back, a failed query service answered invalid, and a restart."""

from __future__ import annotations

import socket
import threading
import time
from concurrent import futures

import grpc
import numpy as np
import pytest

from host_sim.cigi import packets as pk
from host_sim.cigi.codec import V3_3, V4_0
from host_sim.cigi.endpoint import CigiEndpoint, QueryClient, parse_udp_url
from host_sim.cigi.geometry import world_of_geodetic
from host_sim.cigi.scripted_host import Keyframe, Query, Script, ScriptedHost
from host_sim.cigi.session import CigiSession
from ig.v1 import query_pb2, query_pb2_grpc
from services.rig.frame import ChannelSpec

ORIGIN = (36.6089, -84.1708, 349.2)
GROUND_Z = 12.5  # the fake world's flat ground, world metres


class FlatGround(query_pb2_grpc.QueryServiceServicer):
    """A plane at GROUND_Z everywhere within 5 km of the origin (the surface under z_max only)."""

    def __init__(self) -> None:
        self.calls = 0

    def HeightOfTerrain(self, request, context):
        self.calls += 1
        inside = [abs(x) < 5000 and abs(y) < 5000 and z_max >= GROUND_Z
                  for x, y, z_max in zip(request.x, request.y, request.z_max, strict=True)]
        n = len(request.x)
        return query_pb2.HeightOfTerrainResponse(valid=inside, height_m=[GROUND_Z] * n, normal_x=[0.0] * n,
                                                 normal_y=[0.0] * n, normal_z=[1.0] * n, material=[1] * n)

    def LineOfSight(self, request, context):
        self.calls += 1
        out = query_pb2.LineOfSightResponse()
        for x0, y0, z0, x1, y1, z1 in zip(request.x0, request.y0, request.z0, request.x1, request.y1, request.z1,
                                          strict=True):
            hit = z0 > GROUND_Z >= z1
            f = (z0 - GROUND_Z) / (z0 - z1) if hit else 0.0
            p = np.array([x0, y0, z0]) + f * (np.array([x1, y1, z1]) - np.array([x0, y0, z0]))
            out.hit.append(hit)
            out.range_m.append(float(np.linalg.norm(p - [x0, y0, z0])) if hit else 0.0)
            out.x.append(p[0])
            out.y.append(p[1])
            out.z.append(p[2])
            out.normal_x.append(0.0)
            out.normal_y.append(0.0)
            out.normal_z.append(1.0)
            out.material.append(1)
            out.rgba.append(0x336699FF)
        return out


@pytest.fixture
def ground():
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    servicer = FlatGround()
    query_pb2_grpc.add_QueryServiceServicer_to_server(servicer, server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    yield f"127.0.0.1:{port}", servicer
    server.stop(0)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def endpoint(query_address: str | None, host_port: int, **kw) -> CigiEndpoint:
    session = CigiSession(origin=ORIGIN, channels={0: ChannelSpec.symmetric("centre", 64, 48, 60.0)}, **kw)
    client = None if query_address is None else QueryClient(query_address, origin=ORIGIN, timeout_s=2.0)
    return CigiEndpoint(session, ("127.0.0.1", 0), host_port=host_port, queries=client)


def level_script(frames_per_query: int = 3) -> Script:
    lat, lon, h = ORIGIN
    path = (Keyframe(0.0, lat, lon, h + 300.0), Keyframe(10.0, lat + 0.01, lon, h + 300.0))
    return Script(path=path, queries=(
        Query(host_frame=2, kind="hot", every=frames_per_query),
        Query(host_frame=2, kind="hot_extended", every=frames_per_query),
        Query(host_frame=3, kind="los_vector", every=frames_per_query),
        Query(host_frame=3, kind="hat", every=frames_per_query)), frame_rate_hz=60.0)


def drive(ep: CigiEndpoint, host: ScriptedHost, frames: int, stop_after: int = 400) -> list:
    """Play the host in a thread and tick the IG until the host is done."""
    inputs = []
    thread = threading.Thread(target=host.run, kwargs={"frames": frames, "sof_timeout_s": 3.0})
    thread.start()
    for _ in range(stop_after):
        inputs.append(ep.frame_input(0.0))
        thread.join(0.01)
        if not thread.is_alive():
            break
    thread.join()
    return inputs


@pytest.mark.parametrize(("version", "order"), [(V3_3, "<"), (V3_3, ">"), (V4_0, "<"), (V4_0, ">")])
def test_heights_and_sight_lines_come_back_with_the_host_frame_nibble(ground, version, order):
    address, _servicer = ground
    port = free_udp_port()
    ep = endpoint(address, port)
    try:
        with ScriptedHost(level_script(), ig_address=ep.listen, bind=("127.0.0.1", port), byte_order=order,
                          origin=ORIGIN, version=version) as host:
            inputs = drive(ep, host, frames=30)
    finally:
        ep.close()
    assert any(i.eyepoint is not None for i in inputs)
    assert len(host.sofs) >= 30
    # Every frame the host sent was used, in order, once.
    used = [i.host_frame_number for i in inputs if i.host_frame_number is not None]
    assert sorted(set(used)) == list(range(30))
    by_kind: dict[type, list] = {}
    for r in host.responses:
        by_kind.setdefault(type(r.packet), []).append(r)
    hot = [r.packet for r in by_kind[pk.HatHotResponse] if r.packet.response_type == 1]
    hat = [r.packet for r in by_kind[pk.HatHotResponse] if r.packet.response_type == 0]
    ext = [r.packet for r in by_kind[pk.HatHotExtendedResponse]]
    los = [r.packet for r in by_kind[pk.LosResponse]]
    assert hot and hat and ext and los
    ground_h = ORIGIN[2] + GROUND_Z  # within a kilometre of the origin the curvature is millimetres
    for p in hot:
        assert p.valid and p.height == pytest.approx(ground_h, abs=0.05)
    for p in hat:
        assert p.valid and p.height == pytest.approx(300.0 - GROUND_Z, abs=0.05)
    for p in ext:
        assert p.valid and p.hot == pytest.approx(ground_h, abs=0.05) and p.material == 1
        assert p.normal_elevation == pytest.approx(90.0, abs=0.01)
    for p in los:
        assert p.valid and not p.visible and p.range == pytest.approx(300.0 - GROUND_Z, abs=0.05)
    # The nibble is the host frame whose message carried (or re-armed) the request.
    for r in by_kind[pk.HatHotResponse]:
        assert r.packet.host_frame_lsn in {f & 0xF for f in range(30)}
    status = ep.session.status()
    assert status["version"] == f"{version.major}.{version.minor}"
    assert status["byte_order"] == {"<": "little", ">": "big"}[order]
    assert status["queries_failed"] == 0 and status["refused"] == {}


def test_a_dead_query_service_is_answered_invalid_and_counted():
    port = free_udp_port()
    ep = endpoint("127.0.0.1:1", port)  # nothing listens on port 1
    ep.queries.timeout_s = 0.2
    try:
        with ScriptedHost(level_script(), ig_address=ep.listen, bind=("127.0.0.1", port), origin=ORIGIN) as host:
            drive(ep, host, frames=12)
    finally:
        ep.close()
    responses = [r.packet for r in host.responses]
    assert responses and not any(p.valid for p in responses)
    assert ep.session.status()["queries_failed"] > 0


def test_a_point_outside_the_database_is_invalid(ground):
    address, _ = ground
    port = free_udp_port()
    ep = endpoint(address, port)
    far = (ORIGIN[0] + 0.2, ORIGIN[1], 0.0)  # 22 km north: outside the fake ground
    script = Script(path=(Keyframe(0.0, ORIGIN[0], ORIGIN[1], ORIGIN[2] + 300.0),),
                    queries=(Query(host_frame=1, kind="hot", params={"lat": far[0], "lon": far[1]}),))
    try:
        with ScriptedHost(script, ig_address=ep.listen, bind=("127.0.0.1", port), origin=ORIGIN) as host:
            drive(ep, host, frames=5)
    finally:
        ep.close()
    [r] = [r.packet for r in host.responses]
    assert not r.valid


def test_a_restarted_host_starts_a_new_run(ground):
    address, _ = ground
    port = free_udp_port()
    ep = endpoint(address, port)
    try:
        with ScriptedHost(level_script(), ig_address=ep.listen, bind=("127.0.0.1", port), origin=ORIGIN) as h1:
            first = drive(ep, h1, frames=10)
        with ScriptedHost(level_script(), ig_address=ep.listen, bind=("127.0.0.1", port), origin=ORIGIN) as h2:
            second = drive(ep, h2, frames=5)
    finally:
        ep.close()
    assert not any(i.new_run for i in first)
    assert sum(i.new_run for i in second) == 1
    assert ep.session.status()["restarts"] == 1


def test_the_ownship_lands_where_the_geodetic_conversion_puts_it(ground):
    address, _ = ground
    port = free_udp_port()
    ep = endpoint(address, port)
    try:
        with ScriptedHost(level_script(), ig_address=ep.listen, bind=("127.0.0.1", port), origin=ORIGIN) as host:
            inputs = drive(ep, host, frames=20)
    finally:
        ep.close()
    last = next(i for i in inputs if i.host_frame_number == 19)
    pose = host.script.pose(host.time_s(19))
    expected = world_of_geodetic(np.array([pose.lat]), np.array([pose.lon]), np.array([pose.alt_m]), ORIGIN)[0]
    np.testing.assert_allclose(last.eyepoint.position, expected, atol=1e-6)


def test_udp_urls():
    assert parse_udp_url("udp://0.0.0.0:8000") == ("0.0.0.0", 8000)
    assert parse_udp_url("127.0.0.1:9") == ("127.0.0.1", 9)
    for bad in ("tcp://x:1", "udp://:8000", "udp://h:99999", "udp://h:port"):
        with pytest.raises(ValueError, match="--cigi"):
            parse_udp_url(bad)


def test_entity_relative_requests_are_placed_by_the_entitys_pose(ground):
    from host_sim.cigi.codec import V3_3, encode

    address, _ = ground
    session = CigiSession(origin=ORIGIN, channels={0: ChannelSpec.symmetric("centre", 64, 48, 60.0)})
    client = QueryClient(address, origin=ORIGIN, timeout_s=2.0)
    alt = ORIGIN[2] + 300.0
    packets = [pk.IGControl(ig_mode=1, host_frame=1),
               pk.EntityControl(entity_id=0, entity_state=1, lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=alt, yaw=90.0),
               # A tanker 50 m ahead of the ownship (attached: body offsets), 20 m above it.
               pk.EntityControl(entity_id=7, entity_state=1, attach=True, parent_id=0, lat_x=50.0, alt_z=-20.0),
               # HAT 100 m ahead of entity 7, and a sight line straight down from it.
               pk.HatHotRequest(request_id=1, request_type=0, coord_system=1, entity_id=7, lat_x=100.0),
               pk.LosVectorRequest(los_id=2, request_type=1, source_coord=1, response_coord=1, entity_id=7,
                                   elevation=-90.0, max_range=1000.0),
               # An entity nobody declared.
               pk.HatHotRequest(request_id=3, request_type=1, coord_system=1, entity_id=99)]
    session.receive(encode(packets, V3_3, "<"), ("127.0.0.1", 1))
    _, jobs = session.begin_frame()
    try:
        (hat, los, unknown), invalid, failed = client.answer(jobs)
    finally:
        client.close()
    assert failed == 0 and invalid == 1 and not unknown.valid
    # 150 m east of the ownship and 320 m up: the flat ground is GROUND_Z below the origin's
    # height there, less the earth's drop over 150 m (under 2 mm).
    assert hat.valid and hat.height == pytest.approx(320.0 - GROUND_Z, abs=0.01)
    assert los.valid and los.range == pytest.approx(320.0 - GROUND_Z, abs=0.01)
    # The hit in the entity's body axes: straight below it (z down).
    assert (los.lat_x, los.lon_y) == pytest.approx((0.0, 0.0), abs=1e-6)
    assert los.alt_z == pytest.approx(320.0 - GROUND_Z, abs=0.01)
    assert los.material == 1 and (los.red, los.green, los.blue, los.alpha) == (0x33, 0x66, 0x99, 0xFF)


def test_a_point_inside_the_terrain_has_a_negative_height_above_it(ground):
    from host_sim.cigi.codec import V3_3, encode

    address, _ = ground
    session = CigiSession(origin=ORIGIN, channels={0: ChannelSpec.symmetric("centre", 64, 48, 60.0)})
    client = QueryClient(address, origin=ORIGIN, timeout_s=2.0)
    sunk = ORIGIN[2] + GROUND_Z - 0.3  # a wheel 30 cm into the ground
    packets = [pk.IGControl(ig_mode=1, host_frame=1),
               pk.EntityControl(entity_id=0, entity_state=1, lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=sunk),
               pk.HatHotRequest(request_id=1, request_type=0, lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=sunk),
               pk.HatHotRequest(request_id=2, request_type=2, lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=sunk + 1.0)]
    session.receive(encode(packets, V3_3, "<"), ("127.0.0.1", 1))
    _, jobs = session.begin_frame()
    try:
        (hat, extended), invalid, _ = client.answer(jobs)
    finally:
        client.close()
    assert invalid == 0
    assert hat.valid and hat.height == pytest.approx(-0.3, abs=1e-6)
    assert extended.valid and extended.hat == pytest.approx(0.7, abs=1e-6)
    assert extended.hot == pytest.approx(ORIGIN[2] + GROUND_Z, abs=1e-6)


def test_an_asynchronous_host_is_followed_at_its_own_rate(ground):
    address, _ = ground
    port = free_udp_port()
    ep = endpoint(address, port, mode="async")
    try:
        with ScriptedHost(level_script(), ig_address=ep.listen, bind=("127.0.0.1", port), origin=ORIGIN,
                          async_rate_hz=50.0) as host:
            inputs = drive(ep, host, frames=25)
        time.sleep(0.1)  # the host's last datagram, sent as its thread ended
        inputs.append(ep.frame_input(0.0))
    finally:
        ep.close()
    used = [i.host_frame_number for i in inputs if i.host_frame_number is not None]
    # Every message taken (several a frame when the IG is slower, none when faster), in order.
    assert used == sorted(used) and used[-1] == 25
    status = ep.session.status()
    assert status["mode"] == "async" and status["messages_dropped"] == 0 and status["messages"] == 26
    assert host.sofs  # the IG still sends Start of Frame every frame
