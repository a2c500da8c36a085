"""A QueryService whose heights come from a function: the rig's ground for flight-model tests
without a worker (host_sim.fdm.ground asks it as it would ask a channel worker)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from concurrent import futures
from contextlib import contextmanager

import grpc
import numpy as np

from ig.v1 import query_pb2, query_pb2_grpc


def sloped(x, y):
    """A ground that is a plane (bilinear interpolation holds it exactly)."""
    return 5.0 + 0.02 * x - 0.01 * y


class AnalyticGround(query_pb2_grpc.QueryServiceServicer):
    """Heights from height(x, y); no surface (invalid) at x > 400; counts its requests."""

    def __init__(self, height: Callable = sloped) -> None:
        self.height = height
        self.requests = 0
        self.lock = threading.Lock()

    def HeightOfTerrain(self, request, context):
        with self.lock:
            self.requests += 1
        x, y = np.asarray(request.x), np.asarray(request.y)
        n = x.size
        return query_pb2.HeightOfTerrainResponse(valid=(x <= 400.0).tolist(), height_m=self.height(x, y).tolist(),
                                                 normal_x=[0.0] * n, normal_y=[0.0] * n, normal_z=[1.0] * n,
                                                 material=[1] * n)


@contextmanager
def serving(servicer: AnalyticGround, port: int = 0) -> Iterator[str]:
    """The servicer on 127.0.0.1:port (0: any free port) for the with block; yields its address."""
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    query_pb2_grpc.add_QueryServiceServicer_to_server(servicer, server)
    bound = server.add_insecure_port(f"127.0.0.1:{port}")
    server.start()
    try:
        yield f"127.0.0.1:{bound}"
    finally:
        server.stop(0)
