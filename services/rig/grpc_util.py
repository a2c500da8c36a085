"""What every service of the rig does the same way: servers, channels, health, deadlines, SIGTERM."""

from __future__ import annotations

import ipaddress
import logging
import signal
import threading
from collections.abc import Callable, Iterable
from concurrent import futures
from dataclasses import dataclass
from pathlib import Path

import grpc
from google.protobuf import message, message_factory
from google.protobuf.descriptor import FieldDescriptor, ServiceDescriptor
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

#: What a service that takes no images (host, worker) accepts in one message: the largest
#: legitimate one is an acknowledgement with its error text (MAX_TEXT_CHARS), a few hundred bytes.
SMALL_MESSAGE_BYTES = 64 * 1024

#: The longest text kept from a peer (an acknowledgement's error, a subscriber's name); longer
#: text is refused where it arrives, and what a service stores of its own is cut to it.
MAX_TEXT_CHARS = 1024

#: Longest pause between attempts to reach a peer that is down, milliseconds. gRPC's default
#: grows to two minutes, which made workers take 66-100 s to rejoin a restarted host.
MAX_RECONNECT_BACKOFF_MS = 1000

_KEEPALIVE = [
    ("grpc.keepalive_time_ms", 10_000),
    ("grpc.keepalive_timeout_ms", 5_000),
    ("grpc.keepalive_permit_without_calls", 1),
    ("grpc.http2.max_pings_without_data", 0),
]
_CHANNEL_OPTIONS = _KEEPALIVE + [
    ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
    ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
    ("grpc.initial_reconnect_backoff_ms", 100),
    ("grpc.min_reconnect_backoff_ms", 100),
    ("grpc.max_reconnect_backoff_ms", MAX_RECONNECT_BACKOFF_MS),
]


class PlaintextRefused(OSError):
    """A service without TLS asked to listen on, or connect to, an address off the loopback."""


@dataclass(frozen=True)
class Security:
    """How a service talks to the others: mutual TLS from PEM bytes, or plaintext.

    Plaintext is refused off the loopback unless allow_plaintext (docs/security.md).
    """

    ca: bytes = b""
    cert: bytes = b""
    key: bytes = b""
    allow_plaintext: bool = False

    @property
    def tls(self) -> bool:
        return bool(self.cert)

    @staticmethod
    def from_files(ca: str, cert: str, key: str, *, allow_plaintext: bool = False) -> Security:
        """Mutual TLS from PEM files; all three empty: plaintext.

        Raises:
            ValueError: a file cannot be read or is not PEM; the message names it.
        """
        if not (ca or cert or key):
            return Security(allow_plaintext=allow_plaintext)
        data = {}
        for name, path in (("ca", ca), ("cert", cert), ("key", key)):
            if not path:
                raise ValueError(f"tls.{name}: missing (mutual TLS needs ca, cert and key)")
            try:
                data[name] = Path(path).read_bytes()
            except OSError as exc:
                raise ValueError(f"tls.{name}: {path!r}: cannot read: {exc.strerror or exc}") from None
            if b"-----BEGIN " not in data[name]:
                raise ValueError(f"tls.{name}: {path!r} is not a PEM file")
        return Security(data["ca"], data["cert"], data["key"], allow_plaintext)


def is_loopback(address: str) -> bool:
    """Whether host:port names this machine's loopback (127.0.0.0/8, ::1, localhost)."""
    host = address.rpartition(":")[0].strip("[]")
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _check_plaintext(address: str, security: Security, what: str) -> None:
    if not security.tls and not security.allow_plaintext and not is_loopback(address):
        raise PlaintextRefused(f"{what} {address}: plaintext is refused off the loopback; give the rig file a "
                               f"[tls] table (make certs) or set tls.allow_plaintext = true")

log = logging.getLogger("ig")


def make_server(*, max_workers: int = 16, max_receive_bytes: int = SMALL_MESSAGE_BYTES) -> grpc.Server:
    """A gRPC server with the rig's keepalive settings, receiving messages up to max_receive_bytes
    (larger ones are refused by gRPC with RESOURCE_EXHAUSTED before any handler runs).

    The port is exclusive: gRPC sets SO_REUSEPORT by default on Linux, which let a second
    compositor or worker bind the port of a running one and take half its connections.
    """
    options = _KEEPALIVE + [
        ("grpc.http2.min_ping_interval_without_data_ms", 5_000),
        ("grpc.max_receive_message_length", max_receive_bytes),
        ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
        ("grpc.so_reuseport", 0),
    ]
    return grpc.server(futures.ThreadPoolExecutor(max_workers=max_workers), options=options)


def make_channel(address: str, security: Security | None = None) -> grpc.Channel:
    """A client channel to address (host:port) with the rig's settings: mutual TLS when security
    has a certificate, plaintext otherwise.

    Raises:
        PlaintextRefused: plaintext to an address off the loopback, not allowed.
    """
    security = security or Security()
    _check_plaintext(address, security, "connecting to")
    if security.tls:
        creds = grpc.ssl_channel_credentials(root_certificates=security.ca, private_key=security.key,
                                             certificate_chain=security.cert)
        return grpc.secure_channel(address, creds, options=_CHANNEL_OPTIONS)
    return grpc.insecure_channel(address, options=_CHANNEL_OPTIONS)


#: Causes under which add_service's checks count a refused request.
MALFORMED = "malformed"
TEXT_TOO_LONG = "text_too_long"


@dataclass(frozen=True)
class _Malformed:
    """What the lenient deserialiser hands on for bytes that are not the request message."""

    type_name: str
    detail: str


def add_service(server: grpc.Server, servicer: object, service: ServiceDescriptor, *,
                refused: Callable[[str, str], None]) -> None:
    """Register servicer's methods for service, as the generated add_*_to_server does, with two
    checks before any method runs:

    - bytes that do not parse as the request message are refused with INVALID_ARGUMENT naming
      the message type (the generated code answers them with a bare INTERNAL "Exception
      deserializing request!");
    - a top-level text field longer than MAX_TEXT_CHARS is refused with INVALID_ARGUMENT naming
      the field and its length.

    Each refusal calls refused(cause, message) (cause MALFORMED or TEXT_TOO_LONG) so the service
    counts it, and the service goes on.
    """
    handlers = {}
    for method in service.methods:
        request_class = message_factory.GetMessageClass(method.input_type)
        response_class = message_factory.GetMessageClass(method.output_type)
        texts = [f.name for f in method.input_type.fields
                 if f.type == FieldDescriptor.TYPE_STRING and not _repeated(f)]
        behaviour = getattr(servicer, method.name)
        check = _checker(method.input_type.full_name, texts, refused)
        if method.client_streaming:
            raise ValueError(f"{service.full_name}.{method.name}: client streaming is not used by the rig")
        if method.server_streaming:
            handler = grpc.unary_stream_rpc_method_handler(
                _checked_stream(behaviour, check), request_deserializer=_lenient(request_class),
                response_serializer=response_class.SerializeToString)
        else:
            handler = grpc.unary_unary_rpc_method_handler(
                _checked_unary(behaviour, check), request_deserializer=_lenient(request_class),
                response_serializer=response_class.SerializeToString)
        handlers[method.name] = handler
    server.add_generic_rpc_handlers((grpc.method_handlers_generic_handler(service.full_name, handlers),))
    server.add_registered_method_handlers(service.full_name, handlers)


def _repeated(field: FieldDescriptor) -> bool:
    return bool(field.is_repeated)


def _lenient(request_class):
    def deserialize(data: bytes):
        try:
            return request_class.FromString(data)
        except message.DecodeError as exc:
            return _Malformed(request_class.DESCRIPTOR.full_name, str(exc) or "cannot parse")
    return deserialize


def _checker(type_name: str, texts: list[str], refused: Callable[[str, str], None]):
    def check(request, context) -> None:
        if isinstance(request, _Malformed):
            text = f"malformed {request.type_name}: {request.detail}"
            refused(MALFORMED, text)
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, text)
        for name in texts:
            value = getattr(request, name)
            if len(value) > MAX_TEXT_CHARS:
                text = f"{type_name}.{name}: {len(value)} characters, more than the {MAX_TEXT_CHARS} allowed"
                refused(TEXT_TOO_LONG, text)
                context.abort(grpc.StatusCode.INVALID_ARGUMENT, text)
    return check


def _checked_unary(behaviour, check):
    def handle(request, context):
        check(request, context)
        return behaviour(request, context)
    return handle


def _checked_stream(behaviour, check):
    def handle(request, context):
        check(request, context)
        yield from behaviour(request, context)
    return handle


def add_health(server: grpc.Server, services: Iterable[str], *, serving: bool = True,
               refused: Callable[[str, str], None] | None = None) -> health.HealthServicer:
    """Register the standard gRPC health service for "" and services, reporting SERVING, or
    NOT_SERVING until set_serving (a worker still compiling its kernels). With refused, it is
    registered through add_service: malformed requests are refused with INVALID_ARGUMENT and
    counted like the service's own."""
    servicer = health.HealthServicer()
    if refused is None:
        health_pb2_grpc.add_HealthServicer_to_server(servicer, server)
    else:
        add_service(server, servicer, health_pb2.DESCRIPTOR.services_by_name["Health"], refused=refused)
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


def bind(server: grpc.Server, address: str, security: Security | None = None) -> int:
    """Listen on address, with mutual TLS when security has a certificate (every client must show
    a certificate of the rig's CA); returns the bound port (useful with port 0).

    Raises:
        PlaintextRefused: plaintext off the loopback, not allowed.
        OSError: the address cannot be bound (in use, not local).
    """
    security = security or Security()
    _check_plaintext(address, security, "listening on")
    try:
        if security.tls:
            creds = grpc.ssl_server_credentials([(security.key, security.cert)], root_certificates=security.ca,
                                                require_client_auth=True)
            port = server.add_secure_port(address, creds)
        else:
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


def check_health(address: str, *, timeout_s: float = RPC_DEADLINE_S, security: Security | None = None) -> str:
    """The health status name of the server at address ("SERVING", ...)."""
    with make_channel(address, security) as ch:
        stub = health_pb2_grpc.HealthStub(ch)
        resp = stub.Check(health_pb2.HealthCheckRequest(service=""), timeout=timeout_s)
        return health_pb2.HealthCheckResponse.ServingStatus.Name(resp.status)


def clip(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    """text cut to limit characters, saying how much was cut: what a service keeps of text it
    did not write (an error from a peer), so that its status and logs stay small."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def configure_logging(verbose: bool) -> None:
    """Log to stderr with time stamps; DEBUG with verbose, else INFO."""
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
