"""What every service of the rig does the same way: servers, channels, health, deadlines, SIGTERM."""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterable
from concurrent import futures

import grpc
from grpc_health.v1 import health, health_pb2, health_pb2_grpc

#: Large enough for a 4096 x 4096 half-float RGB image (96 MiB) plus headers.
MAX_MESSAGE_BYTES = 128 * 1024 * 1024

#: Deadline of every unary RPC, seconds.
RPC_DEADLINE_S = 5.0

#: Deadline of a frame subscription, seconds. A stream lives as long as the run, whose length
#: the subscriber cannot know (frame-locked runs slow down with the slowest channel), so its
#: deadline is a long session; keepalive pings detect a dead peer long before. A subscriber
#: whose stream hits the deadline subscribes again.
STREAM_DEADLINE_S = 24 * 3600.0

_OPTIONS = [
    ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
    ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
    ("grpc.keepalive_time_ms", 10_000),
    ("grpc.keepalive_timeout_ms", 5_000),
    ("grpc.keepalive_permit_without_calls", 1),
    ("grpc.http2.max_pings_without_data", 0),
]
_SERVER_OPTIONS = _OPTIONS + [("grpc.http2.min_ping_interval_without_data_ms", 5_000)]

log = logging.getLogger("ig")


def make_server(*, max_workers: int = 16) -> grpc.Server:
    """A gRPC server with the rig's message-size and keepalive settings."""
    return grpc.server(futures.ThreadPoolExecutor(max_workers=max_workers), options=_SERVER_OPTIONS)


def make_channel(address: str) -> grpc.Channel:
    """An insecure client channel to address (host:port) with the rig's settings."""
    return grpc.insecure_channel(address, options=_OPTIONS)


def add_health(server: grpc.Server, services: Iterable[str], *,
               serving: bool = True) -> health.HealthServicer:
    """Register the standard gRPC health service for "" and services, reporting SERVING, or
    NOT_SERVING until set_serving (a worker still compiling its kernels)."""
    servicer = health.HealthServicer()
    health_pb2_grpc.add_HealthServicer_to_server(servicer, server)
    set_serving(servicer, services, serving)
    return servicer


def set_serving(servicer: health.HealthServicer, services: Iterable[str], serving: bool = True) -> None:
    """Report SERVING (or NOT_SERVING) for "" and services."""
    status = (health_pb2.HealthCheckResponse.SERVING if serving
              else health_pb2.HealthCheckResponse.NOT_SERVING)
    for name in ("", *services):
        servicer.set(name, status)


def set_not_serving(servicer: health.HealthServicer, services: Iterable[str]) -> None:
    """Tell health checkers the service is going away before it stops answering."""
    set_serving(servicer, services, False)


def bind(server: grpc.Server, address: str) -> int:
    """Listen on address; returns the bound port (useful with port 0).

    Raises:
        OSError: the address cannot be bound (in use, not local).
    """
    try:
        port = server.add_insecure_port(address)
    except RuntimeError as exc:
        raise OSError(f"cannot listen on {address}: {exc}") from exc
    if port == 0:
        raise OSError(f"cannot listen on {address} (address in use or not on this machine)")
    return port


def stop_on_signals(stop: threading.Event) -> None:
    """Set stop on SIGTERM and SIGINT so the main loop can shut down cleanly."""
    def handler(signum, _frame):
        log.info("signal %s: shutting down", signal.Signals(signum).name)
        stop.set()
    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def check_health(address: str, *, timeout_s: float = RPC_DEADLINE_S) -> str:
    """The health status name of the server at address ("SERVING", ...)."""
    with make_channel(address) as ch:
        stub = health_pb2_grpc.HealthStub(ch)
        resp = stub.Check(health_pb2.HealthCheckRequest(service=""), timeout=timeout_s)
        return health_pb2.HealthCheckResponse.ServingStatus.Name(resp.status)


def configure_logging(verbose: bool) -> None:
    """Log to stderr with time stamps; DEBUG with verbose, else INFO."""
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
