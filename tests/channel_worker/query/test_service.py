"""QueryService over a real gRPC server on port 0 with the bundled scene."""

from __future__ import annotations

import math
import re
from concurrent import futures

import grpc
import numpy as np
import pytest

from channel_worker.query._query_kernels import MATERIAL_GROUND, MATERIAL_POLYGON
from channel_worker.query.heights import height_of_terrain
from channel_worker.query.service import MAX_QUERIES, add_query_service
from ig.v1 import query_pb2, query_pb2_grpc


@pytest.fixture(scope="module")
def stub(bundled):
    refusals: list[tuple[str, str]] = []
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    add_query_service(server, bundled, refused=lambda cause, message: refusals.append((cause, message)))
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    channel = grpc.insecure_channel(f"127.0.0.1:{port}")
    yield query_pb2_grpc.QueryServiceStub(channel), refusals
    channel.close()
    server.stop(None)


def test_height_of_terrain(stub, bundled):
    client, _ = stub
    x, y, z = [0.0, 5000.0, 1.0e7], [0.0, 3000.0, 0.0], [math.inf, math.inf, math.inf]
    reply = client.HeightOfTerrain(query_pb2.HeightOfTerrainRequest(x=x, y=y, z_max=z), timeout=10)
    assert list(reply.valid) == [True, True, False]
    assert reply.material[0] >= MATERIAL_POLYGON and reply.material[1] == MATERIAL_GROUND
    direct = height_of_terrain(bundled, np.array(x), np.array(y), np.array(z))
    assert list(reply.height_m[:2]) == direct.height_m[:2].tolist()
    assert reply.normal_z[0] == pytest.approx(1.0)


def test_line_of_sight(stub):
    client, _ = stub
    request = query_pb2.LineOfSightRequest(x0=[0.0, 0.0], y0=[0.0, 0.0], z0=[100.0, 100.0], x1=[0.0, 0.0],
                                           y1=[0.0, 0.0], z1=[-100.0, 50.0], min_opacity=[0.0, 0.0])
    reply = client.LineOfSight(request, timeout=10)
    assert list(reply.hit) == [True, False]
    assert 99.0 < reply.range_m[0] < 100.5 and reply.z[0] == pytest.approx(100.0 - reply.range_m[0])
    assert reply.material[0] >= MATERIAL_POLYGON and reply.rgba[0] & 0xFF == 255


@pytest.mark.parametrize(("rpc", "fields", "match"), [
    ("HeightOfTerrain", dict(x=[0.0, 1.0], y=[0.0], z_max=[0.0]), "unequal lengths \\(x 2, y 1, z_max 1\\)"),
    ("HeightOfTerrain", dict(x=[0.0] * (MAX_QUERIES + 1), y=[0.0] * (MAX_QUERIES + 1),
                             z_max=[0.0] * (MAX_QUERIES + 1)), f"{MAX_QUERIES + 1} queries"),
    ("HeightOfTerrain", dict(x=[0.0], y=[math.nan], z_max=[0.0]), "y\\[0\\]: nan is not finite"),
    ("HeightOfTerrain", dict(x=[0.0], y=[0.0], z_max=[-math.inf]), "z_max\\[0\\]: -inf"),
    ("LineOfSight", dict(x0=[0.0], y0=[0.0], z0=[0.0], x1=[0.0], y1=[0.0], z1=[math.inf], min_opacity=[0.0]),
     "z1\\[0\\]: inf is not finite"),
    ("LineOfSight", dict(x0=[0.0], y0=[0.0], z0=[0.0], x1=[0.0], y1=[0.0], z1=[0.0], min_opacity=[1.5]),
     "min_opacity\\[0\\]: 1.5 is not within 0..1"),
    ("LineOfSight", dict(x0=[0.0], y0=[0.0], z0=[0.0], x1=[0.0], y1=[0.0], z1=[0.0], min_opacity=[]),
     "min_opacity 0"),
])
def test_bad_requests_are_refused(stub, rpc, fields, match):
    client, refusals = stub
    request = getattr(query_pb2, f"{rpc}Request")(**fields)
    before = len(refusals)
    with pytest.raises(grpc.RpcError) as info:
        getattr(client, rpc)(request, timeout=10)
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert re.search(match, info.value.details()), info.value.details()
    assert len(refusals) == before + 1 and refusals[-1][1] == info.value.details()


def test_an_empty_request_has_an_empty_answer(stub):
    client, _ = stub
    assert list(client.HeightOfTerrain(query_pb2.HeightOfTerrainRequest(), timeout=10).valid) == []
    assert list(client.LineOfSight(query_pb2.LineOfSightRequest(), timeout=10).hit) == []
