"""ig.v1.QueryService (proto/ig/v1/query.proto): height of terrain and line of sight answered
from the database a channel worker holds, a thin servicer over heights.py and sight.py
(route_guide's shape: the logic in plain functions, the servicer converts and checks).

Every request is checked before anything runs: its repeated fields of one length, at most
MAX_QUERIES queries, every value finite (z_max may be +inf: the highest surface; min_opacity
within 0..1). A refusal is INVALID_ARGUMENT naming the field, the index and the value, and is
reported through refused(cause, message) when the caller gave one.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Sequence

import grpc
import numpy as np

from channel_worker.pipeline.scene.database import Database
from ig.v1 import query_pb2, query_pb2_grpc
from services.rig.grpc_util import add_service

from .heights import height_of_terrain
from .sight import line_of_sight

#: Queries one request may carry: a CIGI host asks for a few per frame; 1024 answers in a few
#: milliseconds (docs/cigi-queries.md), so a request cannot hold the worker past a frame.
MAX_QUERIES = 1024

log = logging.getLogger("ig.worker.query")

#: Sent with every answer from a database without terrain (the flat airfield) and logged once:
#: HOT and LOS over a CIGI origin away from its few polygons then come back invalid with no
#: other sign of why (79 of 81 in one integrator's run).
NO_TERRAIN = ("holds no terrain: heights and lines of sight meet only the scene's polygons (give the "
              "workers a scene with terrain: the rig file's [scene] path or --scene)")

#: Causes passed to refused(cause, message).
LENGTHS = "lengths"
TOO_MANY = "too_many"
NOT_FINITE = "not_finite"


class QueryServicer(query_pb2_grpc.QueryServiceServicer):
    """Answers QueryService from one scene database."""

    def __init__(self, database: Database, *, refused: Callable[[str, str], None] | None = None) -> None:
        self._database = database
        self._refused = refused
        #: "" or what the database lacks, sent with every answer (query.proto database_warning).
        self.warning = "" if database.terrain is not None else NO_TERRAIN
        self._warned = threading.Event()

    def _note(self) -> str:
        """The database's warning, logged at the first query (not at start: a rig that never
        asks a query has nothing to be warned about)."""
        if self.warning and not self._warned.is_set():
            self._warned.set()
            log.warning("query service: the scene database %s", self.warning)
        return self.warning

    def HeightOfTerrain(self, request, context):
        along = len(request.up_x) or len(request.up_y) or len(request.up_z)
        self._check(request, ("x", "y", "z_max", "up_x", "up_y", "up_z") if along else ("x", "y", "z_max"), context)
        for name in ("x", "y", "up_x", "up_y", "up_z"):
            self._finite(request, name, context)
        self._finite(request, "z_max", context, allow_inf=True)
        x, y = np.array(request.x, np.float64), np.array(request.y, np.float64)
        z_max = np.array(request.z_max, np.float64)
        if along:
            up = np.stack([np.array(request.up_x), np.array(request.up_y), np.array(request.up_z)], axis=1)
            for n, u in enumerate(up):
                # Guard of the division by up_z below: a local vertical is within a few degrees
                # of the world's anywhere a database reaches.
                if not (abs(float(np.linalg.norm(u)) - 1.0) < 1e-6 and u[2] > 0.5):
                    self._refuse(NOT_FINITE, f"HeightOfTerrainRequest.up[{n}]: {u.tolist()} is not a unit "
                                 "vector within 60 degrees of the world's up", context)
            heights = _along_vertical(self._database, x, y, up, z_max)
        else:
            heights = height_of_terrain(self._database, x, y, z_max)
        return query_pb2.HeightOfTerrainResponse(
            valid=heights.valid.tolist(), height_m=heights.height_m.tolist(),
            normal_x=heights.normal[:, 0].tolist(), normal_y=heights.normal[:, 1].tolist(),
            normal_z=heights.normal[:, 2].tolist(), material=heights.material.tolist(),
            database_warning=self._note())

    def LineOfSight(self, request, context):
        fields = ("x0", "y0", "z0", "x1", "y1", "z1", "min_opacity")
        self._check(request, fields, context)
        for name in fields:
            self._finite(request, name, context)
        for n, value in enumerate(request.min_opacity):
            if not 0.0 <= value <= 1.0:
                self._refuse(NOT_FINITE, f"LineOfSightRequest.min_opacity[{n}]: {value!r} is not within 0..1",
                             context)
        p0 = np.stack([np.array(request.x0), np.array(request.y0), np.array(request.z0)], axis=1)
        p1 = np.stack([np.array(request.x1), np.array(request.y1), np.array(request.z1)], axis=1)
        sight = line_of_sight(self._database, p0.reshape(-1, 3), p1.reshape(-1, 3),
                              np.array(request.min_opacity, np.float64))
        return query_pb2.LineOfSightResponse(
            hit=sight.hit.tolist(), range_m=sight.range_m.tolist(),
            x=sight.point[:, 0].tolist(), y=sight.point[:, 1].tolist(), z=sight.point[:, 2].tolist(),
            normal_x=sight.normal[:, 0].tolist(), normal_y=sight.normal[:, 1].tolist(),
            normal_z=sight.normal[:, 2].tolist(), material=sight.material.tolist(), rgba=sight.rgba.tolist(),
            database_warning=self._note())

    def _check(self, request, fields: Sequence[str], context) -> None:
        """Refuse fields of unequal lengths or more than MAX_QUERIES queries."""
        kind = type(request).__name__
        lengths = [len(getattr(request, name)) for name in fields]
        if len(set(lengths)) > 1:
            shown = ", ".join(f"{name} {count}" for name, count in zip(fields, lengths, strict=True))
            self._refuse(LENGTHS, f"{kind}: fields of unequal lengths ({shown}); one value per query in each",
                         context)
        if lengths and lengths[0] > MAX_QUERIES:
            self._refuse(TOO_MANY, f"{kind}.{fields[0]}: {lengths[0]} queries, more than the {MAX_QUERIES} allowed",
                         context)

    def _finite(self, request, name: str, context, *, allow_inf: bool = False) -> None:
        for n, value in enumerate(getattr(request, name)):
            if not (math.isfinite(value) or (allow_inf and value == math.inf)):
                self._refuse(NOT_FINITE, f"{type(request).__name__}.{name}[{n}]: {value!r} is not "
                             f"{'finite or +inf' if allow_inf else 'finite'}", context)

    def _refuse(self, cause: str, message: str, context) -> None:
        if self._refused is not None:
            self._refused(cause, message)
        context.abort(grpc.StatusCode.INVALID_ARGUMENT, message)


def add_query_service(server: grpc.Server, database: Database, *,
                      refused: Callable[[str, str], None] | None = None, warm: bool = True) -> QueryServicer:
    """Register QueryService for a database on a server (through grpc_util.add_service, which
    refuses unparseable bytes first).

    Args:
        server: the gRPC server (not yet started, or started: handlers may be added either way).
        database: the scene the queries are answered from.
        refused: called with (cause, message) for every refused request, if given.
        warm: first prepare the database's query index and load the kernels with one query of
            each kind, so the first real query is not the slow one (a worker does it in its
            warm-up instead, while its health says NOT_SERVING: warm_queries).

    Returns:
        The servicer registered.
    """
    servicer = QueryServicer(database, refused=refused)
    if warm:
        warm_queries(database)
    add_service(server, servicer, query_pb2.DESCRIPTOR.services_by_name["QueryService"],
                refused=refused if refused is not None else _ignore)
    return servicer


#: Fixed-point steps of a height along a leaning vertical: the line moves sideways by
#: (change in z) x tan(lean), about 1e-3 of it 10 km out, so each step shrinks the error by
#: that times the slope; three leave nothing a float64 height can show.
_VERTICAL_STEPS = 3

#: A step moving the height less than this ends the search, metres: the stored heights are
#: float32, a tenth of a millimetre at the highest terrain (docs/cigi-queries.md).
_CONVERGED_M = 1e-4


def _along_vertical(database: Database, x: np.ndarray, y: np.ndarray, up: np.ndarray, z_max: np.ndarray):
    """height_of_terrain where the lines (x, y, 0) + s up meet the surface (query.proto)."""
    z = np.zeros(len(x))
    heights = None
    for _ in range(_VERTICAL_STEPS):
        s = z / up[:, 2]  # up_z > 0.5, checked by the servicer
        heights = height_of_terrain(database, x + s * up[:, 0], y + s * up[:, 1], z_max)
        found = np.where(heights.valid, heights.height_m, z)
        if np.all(np.abs(found - z) < _CONVERGED_M):
            break
        z = found
    assert heights is not None
    return heights


def warm_queries(database: Database) -> None:
    """Build the database's query index and compile (or load) the query kernels."""
    height_of_terrain(database, np.zeros(1), np.zeros(1), np.full(1, math.inf))
    line_of_sight(database, np.zeros((1, 3)), np.array([[0.0, 0.0, -1.0]]), np.ones(1))


def _ignore(cause: str, message: str) -> None:
    """refused() for a caller that counts nothing."""
