"""`ig host --cigi udp://HOST:PORT`: the rig as a CIGI image generator on a UDP socket.

The endpoint owns the socket and two threads around a CigiSession (session.py):
- the receiver hands every datagram to the session as it arrives;
- the query thread sends each frame's height-of-terrain and line-of-sight queries to the
  worker that holds the databases (ig.v1.QueryService, over gRPC with a deadline) and keeps
  the response packets for the next Start of Frame.
The publisher calls `frame_input` once per frame from its own thread: the session begins the
frame, the Start of Frame goes to the host, and the frame's queries go to the query thread, so
a slow query never holds a frame.
"""

from __future__ import annotations

import logging
import queue
import socket
import threading
from collections.abc import Sequence
from typing import Any

import grpc
import numpy as np

from ig.v1 import query_pb2, query_pb2_grpc
from services.rig.grpc_util import Security, make_channel

from .geometry import SCALAR_POINTS, Origin, geodetic_of_world, height_of_world
from .queries import (
    MAX_QUERIES,
    HeightJob,
    Job,
    SightJob,
    Surface,
    height_response,
    heights_request,
    sight_request,
    sight_response,
    vertical_lines,
)
from .session import CigiSession

log = logging.getLogger("ig.host.cigi")

#: Largest datagram a host may send (the UDP maximum); anything longer arrives truncated.
MAX_DATAGRAM = 65507

#: Frames of queries that may wait for the query thread before the oldest frame's are answered
#: invalid (a query service slower than the frame rate must not grow a backlog without end).
QUERY_BACKLOG = 8


def parse_udp_url(url: str, default_port: int = 8000) -> tuple[str, int]:
    """(host, port) of udp://HOST:PORT (or HOST:PORT).

    Raises:
        ValueError: not such a URL (named).
    """
    rest = url[len("udp://"):] if url.startswith("udp://") else url
    if "://" in rest or not rest:
        raise ValueError(f"--cigi: {url!r} is not udp://HOST:PORT")
    host, sep, port = rest.rpartition(":")
    if not sep:
        host, port = rest, str(default_port)
    if not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"--cigi: {url!r} is not udp://HOST:PORT with a port in [0, 65535]")
    return host, int(port)


class QueryClient:
    """Answers jobs through ig.v1.QueryService (one RPC per kind per batch of MAX_QUERIES)."""

    def __init__(self, address: str, *, origin: Origin, timeout_s: float, security: Security | None = None,
                 channel: grpc.Channel | None = None) -> None:
        self.origin = origin
        self.timeout_s = timeout_s
        self._channel = channel or make_channel(address, security)
        self._stub = query_pb2_grpc.QueryServiceStub(self._channel)
        self.address = address
        #: The last answer's database_warning (query.proto); None before any answer.
        self.database_warning: str | None = None

    def close(self) -> None:
        self._channel.close()

    def answer(self, jobs: Sequence[Job]) -> tuple[list, int, int]:
        """(response packets, in the jobs' order; answered invalid; failed RPCs' queries).

        The heights and the sight lines go out at once, one RPC per kind and batch of
        MAX_QUERIES: a frame's answers cost one round trip."""
        heights = [j for j in jobs if isinstance(j, HeightJob) and j.known]
        sights = [j for j in jobs if isinstance(j, SightJob) and j.known]
        batches: list[tuple[str, list, Any, Any]] = []  # kind, jobs, request, vertical lines
        # A height above terrain asks twice: the surface under the point, and, should there be
        # none (the point is inside the terrain: a wheel sunk into a hill between two frames),
        # the surface above it, for a negative height. Half a batch of jobs fills a batch.
        for start in range(0, len(heights), MAX_QUERIES // 2):
            h_part = heights[start:start + MAX_QUERIES // 2]
            base, up, z_max = vertical_lines(h_part, self.origin)
            under = np.isfinite(z_max)
            rows = (np.concatenate([base, base[under]]), np.concatenate([up, up[under]]),
                    np.concatenate([z_max, np.full(int(under.sum()), np.inf)]))
            batches.append(("height", h_part, heights_request(*rows), (rows[0], rows[1], under)))
        for start in range(0, len(sights), MAX_QUERIES):
            s_part = sights[start:start + MAX_QUERIES]
            batches.append(("sight", s_part, sight_request(s_part), None))
        # Every batch but the last goes out as a future and the last as a plain call, so they
        # overlap; a lone batch (the usual frame) is a plain call: gRPC's futures cost a
        # thread hand-off, 0.4 ms a call measured against 0.44 ms for the whole round trip.
        futures = [self._method(kind).future(request, timeout=self.timeout_s)
                   for kind, _, request, _ in batches[:-1]]
        out: dict[int, Any] = {}
        failed = 0
        for n, (kind, part, request, lines) in enumerate(batches):
            try:
                if n < len(futures):
                    result = futures[n].result()
                else:
                    result = self._method(kind)(request, timeout=self.timeout_s)
            except grpc.RpcError as exc:
                log.warning("%s queries to %s failed: %s", kind, self.address, exc.code().name)
                result = None
                failed += len(part)
            else:
                self.database_warning = result.database_warning
            if kind == "height":
                surfaces = self._surfaces(result, *lines) if result is not None else {}
                for i, h_job in enumerate(part):
                    out[id(h_job)] = height_response(h_job, surfaces.get(i, Surface(False)), self.origin)
            else:
                for i, s_job in enumerate(part):
                    out[id(s_job)] = sight_response(s_job, result, i, self.origin)
        for job in jobs:
            if id(job) not in out:  # an unknown entity or a request no geometry can place
                out[id(job)] = _invalid(job, self.origin)
        packets = [out[id(j)] for j in jobs]
        invalid = sum(1 for p in packets if not p.valid)
        return packets, invalid, failed

    def _method(self, kind: str):
        return self._stub.HeightOfTerrain if kind == "height" else self._stub.LineOfSight

    def _surfaces(self, answer: query_pb2.HeightOfTerrainResponse, base: np.ndarray, up: np.ndarray,
                  under: np.ndarray) -> dict[int, Surface]:
        """Each job's surface, by job index: its point on the vertical as a geodetic height.

        The answer has a row per job, then a second row (the highest surface) for each job that
        asked for the surface under its point (under); that row is taken when the first found
        none."""
        valid = list(answer.valid)
        chosen: dict[int, int] = {}  # job -> the row answering it
        second = len(under)
        for job, asked in enumerate(under):
            row = job
            if asked:
                if not valid[job] and valid[second]:
                    row = second
                second += 1
            if valid[row]:
                chosen[job] = row
        if not chosen:
            return {}
        rows = np.array(list(chosen.values()))
        z = np.array(answer.height_m, np.float64)[rows]
        points = base[rows] + (z / up[rows, 2])[:, None] * up[rows]
        h = ([height_of_world(p, self.origin) for p in points] if len(points) <= SCALAR_POINTS
             else geodetic_of_world(points, self.origin)[2].tolist())
        return {job: Surface(True, float(h[k]), (answer.normal_x[r], answer.normal_y[r], answer.normal_z[r]),
                             int(answer.material[r])) for k, (job, r) in enumerate(chosen.items())}


class CigiEndpoint:
    """The session on a UDP socket (module doc).

    Args:
        session: the session.
        listen: (host, port) to bind; port 0 takes a free one (tests).
        host_port: the UDP port replies go to, on the address the host sends from.
        queries: answers the queries; None answers every one invalid.
        host: where Start of Frame goes before the host's first message ("": nowhere; the
            session announces itself then: CigiSession(announce=True)).
    """

    def __init__(self, session: CigiSession, listen: tuple[str, int], *, host_port: int = 8001,
                 queries: QueryClient | None = None, host: str = "") -> None:
        self.session = session
        self.host_port = host_port
        self.host = host
        self.queries = queries
        self.sock = socket.socket(socket.AF_INET6 if ":" in listen[0] else socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind(listen)
        except OSError:
            self.sock.close()
            raise
        self.sock.settimeout(0.2)
        self.listen = self.sock.getsockname()[:2]
        self._stop = threading.Event()
        self._answers: list = []
        self._answers_lock = threading.Lock()
        self._jobs: queue.Queue[list[Job] | None] = queue.Queue()
        self._receiver = threading.Thread(target=self._receive, name="cigi-receive", daemon=True)
        self._querier = threading.Thread(target=self._query, name="cigi-query", daemon=True)
        self._receiver.start()
        self._querier.start()
        log.info("CIGI IG listening on udp://%s:%d, replying to the host's port %d", *self.listen, host_port)

    def close(self) -> None:
        self._stop.set()
        self._jobs.put(None)
        self._receiver.join(2.0)
        self._querier.join(2.0)
        self.sock.close()
        if self.queries is not None:
            self.queries.close()

    def frame_input(self, sim_time: float):
        """The publisher's source: begin an IG frame, send its Start of Frame, queue its queries."""
        frame, jobs = self.session.begin_frame()
        with self._answers_lock:
            answers, self._answers = self._answers, []
        sender = self.session.sender
        to = sender[0] if sender is not None else self.host
        for datagram in self.session.start_of_frame(answers):
            if to:
                try:
                    self.sock.sendto(datagram, (to, self.host_port))
                except OSError as exc:
                    log.warning("Start of Frame to %s:%d failed: %s", to, self.host_port, exc)
        if jobs:
            if self._jobs.qsize() >= QUERY_BACKLOG:
                dropped = self._jobs.get_nowait()
                if dropped:
                    self._answer(dropped, None)
            self._jobs.put(jobs)
        return frame

    def _receive(self) -> None:
        while not self._stop.is_set():
            try:
                data, sender = self.sock.recvfrom(MAX_DATAGRAM + 1)
            except TimeoutError:
                continue
            except OSError as exc:
                if self._stop.is_set():
                    return
                log.warning("CIGI socket: %s", exc)
                continue
            self.session.receive(data, sender[:2])

    def _query(self) -> None:
        while True:
            jobs = self._jobs.get()
            if jobs is None:
                return
            self._answer(jobs, self.queries)

    def _answer(self, jobs: list[Job], client: QueryClient | None) -> None:
        if client is None:
            packets = [_invalid(j, self.session.origin) for j in jobs]
            invalid, failed = len(packets), len(packets)
        else:
            try:
                packets, invalid, failed = client.answer(jobs)
            except (ValueError, ArithmeticError) as exc:  # a request no geometry can place
                log.warning("CIGI queries refused: %s", exc)
                packets = [_invalid(j, self.session.origin) for j in jobs]
                invalid, failed = len(packets), 0
            if client.database_warning is not None:
                # Told once in the log (by the session) and kept in CigiStatus.query_database.
                warning = client.database_warning
                self.session.query_database_is(
                    f"the query worker {client.address}'s scene database {warning}" if warning else "")
        self.session.count_answers(len(packets), invalid, failed)
        with self._answers_lock:
            self._answers += packets


def _invalid(job: Job, origin: Origin):
    """The response of a job no query answered: invalid (no surface, no sight line)."""
    if isinstance(job, HeightJob):
        return height_response(job, Surface(False), origin)
    return sight_response(job, None, 0, origin)

