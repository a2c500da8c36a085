"""A query service whose database holds no terrain says so: once in the worker's log, and in
every answer (query.proto database_warning), which the CIGI host shows in `ig status`."""

from __future__ import annotations

import logging
from concurrent import futures

import grpc
import pytest

from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
from channel_worker.query.service import NO_TERRAIN, add_query_service
from ig.v1 import query_pb2, query_pb2_grpc


def serve(database):
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    add_query_service(server, database, warm=False)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    return server, grpc.insecure_channel(f"127.0.0.1:{port}")


@pytest.fixture(scope="module")
def flat():
    """The bundled airfield: polygons and no terrain (what a worker without --scene loads)."""
    database = load_scene(bundled_scene_path())
    assert database.terrain is None
    return database


def test_a_database_without_terrain_is_named_once_in_the_log_and_in_every_answer(flat, caplog):
    server, channel = serve(flat)
    stub = query_pb2_grpc.QueryServiceStub(channel)
    try:
        with caplog.at_level(logging.WARNING, logger="ig.worker.query"):
            answers = [stub.HeightOfTerrain(query_pb2.HeightOfTerrainRequest(x=[x], y=[0.0], z_max=[1e4]))
                       for x in (0.0, 50_000.0, 60_000.0)]
            sight = stub.LineOfSight(query_pb2.LineOfSightRequest(x0=[0.0], y0=[0.0], z0=[100.0], x1=[0.0],
                                                                  y1=[0.0], z1=[-100.0], min_opacity=[0.5]))
    finally:
        channel.close()
        server.stop(None)
    assert [a.valid[0] for a in answers] == [True, False, False]
    assert all(a.database_warning == NO_TERRAIN for a in answers) and sight.database_warning == NO_TERRAIN
    warned = [r for r in caplog.records if "holds no terrain" in r.getMessage()]
    assert len(warned) == 1


def test_a_database_with_terrain_has_no_warning(bundled):
    server, channel = serve(bundled)
    try:
        answer = query_pb2_grpc.QueryServiceStub(channel).HeightOfTerrain(
            query_pb2.HeightOfTerrainRequest(x=[0.0], y=[0.0], z_max=[1e4]))
    finally:
        channel.close()
        server.stop(None)
    assert answer.database_warning == ""
