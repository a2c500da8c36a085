"""The live view's HTTP server, on a thread of the compositor process (as its Prometheus
endpoint is): the page, the panorama as an MJPEG stream, and the numbers the page polls.

    GET /              page.html: the panorama and the rig's state; no external resources
    GET /stream.mjpg   multipart/x-mixed-replace JPEG frames, at most frames.MAX_RATE_HZ
    GET /frame.jpg     the newest frame alone
    GET /status.json   status.StatusBoard.status()

Every connection has a thread of its own, so a browser that stalls holds nobody up but itself:
its frames are dropped (counted, frames.FrameSource) and, once its socket has taken nothing for
STALL_TIMEOUT_S, it is disconnected. Under the rig's [tls] table it speaks HTTPS with the
compositor's certificate (the handshake too on the connection's thread, never the accepting
one); without it, plaintext is refused off the loopback as every service of the rig refuses it
(docs/security.md).
"""

from __future__ import annotations

import json
import logging
import select
import socket
import socketserver
import ssl
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import urlsplit

from services.rig.grpc_util import PlaintextRefused, is_loopback

from ..watch import Watchers
from .frames import MAX_RATE_HZ, MAX_WIDTH, Client, FrameSource
from .status import StatusBoard

log = logging.getLogger("ig.compositor")

#: Where the view listens unless told otherwise: this machine only.
DEFAULT_BIND = "127.0.0.1"
#: Streams open at once; one more is answered 503 (each holds a thread and a frame).
MAX_STREAMS = 8
#: A connection whose socket takes nothing for this long is closed, seconds.
STALL_TIMEOUT_S = 10.0
#: A stream with no new frame (the run over, the host paused) sends its last one again this
#: often, seconds: a browser whose network vanished (no end of file to see) fails the write
#: or stalls it past STALL_TIMEOUT_S, and its slot is freed.
KEEPALIVE_S = 5.0
#: How often a waiting stream looks whether its browser has gone, seconds.
_POLL_S = 0.5
#: The kernel's send buffer of a stream, bytes: a few frames of the default rig. Linux grows
#: an unset buffer to megabytes, which would hold a slow browser's seconds-old frames in the
#: kernel instead of dropping them here and showing it the newest.
SEND_BUFFER_BYTES = 64 * 1024

_BOUNDARY = b"igframe"
_PAGE = Path(__file__).with_name("page.html")


def view_address(port: int | None, bind: str | None) -> str | None:
    """host:port the view listens on: port (None or 0: no view) on bind (None: DEFAULT_BIND)."""
    if not port:
        return None
    host = bind or DEFAULT_BIND
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


@dataclass(frozen=True)
class ViewSpec:
    """Where and how a compositor serves its live view.

    Attributes:
        address: host:port (view_address).
        certificate: (cert, key) PEM files of the rig's [tls] table: HTTPS; None: HTTP.
        allow_plaintext: HTTP off the loopback too (the rig's tls.allow_plaintext).
    """

    address: str
    certificate: tuple[str, str] | None = None
    allow_plaintext: bool = False


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    # socketserver's 5: a few browsers opening their page, stream and status at once overflowed
    # it, and each connection refused that way waited a second for TCP to try again.
    request_queue_size = 64

    def __init__(self, address: tuple[str, int], view: LiveView, tls: ssl.SSLContext | None) -> None:
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.view = view
        self.tls = tls
        super().__init__(address, _Handler)

    def server_bind(self) -> None:
        # HTTPServer's own asks DNS for the address's name (socket.getfqdn), which a rig's
        # network may not answer quickly: the view has no use for it.
        socketserver.TCPServer.server_bind(self)
        self.server_name, self.server_port = str(self.server_address[0]), int(self.server_address[1])

    def finish_request(self, request, client_address) -> None:
        if self.tls is None:
            super().finish_request(request, client_address)
            return
        request.settimeout(STALL_TIMEOUT_S)
        try:
            conn = self.tls.wrap_socket(request, server_side=True)
        except OSError as exc:  # ssl.SSLError included: a plain-HTTP client, an untrusting browser
            log.debug("live view: TLS handshake with %s failed: %s", client_address, exc)
            return
        try:
            super().finish_request(conn, client_address)
        finally:
            conn.close()


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    timeout = STALL_TIMEOUT_S
    server_version = "ig-live-view"

    def do_GET(self) -> None:
        route = _ROUTES.get(urlsplit(self.path).path)
        if route is None:
            self.send_error(404, "not a page of the live view: /, /stream.mjpg, /frame.jpg, /status.json")
            return
        try:
            route(self)
        except OSError as exc:  # the browser went away, stalled past the timeout, or broke TLS
            log.debug("live view: %s %s: %s", self.client_address, self.path, exc)

    def log_message(self, format: str, *args) -> None:
        log.debug("live view: %s " + format, self.client_address[0], *args)

    def _send(self, content_type: str, body: bytes) -> None:
        self.send_response(200)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self._common_headers()
        self.end_headers()
        self.wfile.write(body)

    def _common_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        # The page loads nothing but itself, its stream and its numbers.
        self.send_header("Content-Security-Policy", "default-src 'self'; style-src 'unsafe-inline'; "
                                                    "script-src 'unsafe-inline'")

    def _page(self) -> None:
        self._send("text/html; charset=utf-8", self.server.view.page)

    def _status(self) -> None:
        self._send("application/json", json.dumps(self.server.view.board.status()).encode())

    def _frame(self) -> None:
        frame = self.server.view.frames.latest
        if frame is None:
            self.send_error(503, "no composite yet")
            return
        self._send("image/jpeg", frame.jpeg)

    def _stream(self) -> None:
        frames = self.server.view.frames
        client = frames.join(limit=MAX_STREAMS)
        if client is None:
            self.send_error(503, f"{MAX_STREAMS} live views are open already")
            return
        try:
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
            self.send_response(200)
            self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=" + _BOUNDARY.decode())
            self._common_headers()
            self.end_headers()
            self._frames(client)
        finally:
            frames.leave(client)

    def _frames(self, client: Client) -> None:
        last, sent = None, time.monotonic()
        while True:
            frame = client.get(_POLL_S)
            if frame is None:
                if client.closed or _peer_gone(self.connection):
                    return
                if time.monotonic() - sent < KEEPALIVE_S:
                    continue
                frame = last  # nothing new for a while: the last again (a vanished network shows)
            if frame is not None:
                self.wfile.write(b"--%s\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n%s\r\n"
                                 % (_BOUNDARY, len(frame.jpeg), frame.jpeg))
                last, sent = frame, time.monotonic()


def _peer_gone(connection: socket.socket) -> bool:
    """Whether a stream's browser has closed its end: it sends nothing after its request, so a
    readable socket is its end of file (or something no stream answers)."""
    readable, _, _ = select.select([connection], [], [], 0)
    return bool(readable)


_ROUTES: dict[str, Callable[[_Handler], None]] = {
    "/": _Handler._page, "/index.html": _Handler._page, "/stream.mjpg": _Handler._stream,
    "/frame.jpg": _Handler._frame, "/status.json": _Handler._status,
}


class LiveView:
    """A compositor's live view, serving from construction until close().

    Args:
        report: the compositor's report of its current run (Compositor.report).
        channels: rig channel names, in display order.
        watchers: the compositor's watchers: the view takes every composite from them.
        address: host:port to listen on; port 0 takes a free one (tests), see port.
        certificate: (cert, key) PEM files of the rig's [tls] table: HTTPS; None: HTTP.
        allow_plaintext: HTTP off the loopback too (the rig's tls.allow_plaintext).
        max_rate_hz, max_width: the frames' rate and width at most.

    Raises:
        PlaintextRefused: HTTP asked for off the loopback without allow_plaintext.
        OSError: the address cannot be bound, or the certificate not loaded; the message says which.
    """

    def __init__(self, report: Callable[[], dict], channels: Sequence[str], watchers: Watchers, address: str, *,
                 certificate: tuple[str, str] | None = None, allow_plaintext: bool = False,
                 max_rate_hz: float = MAX_RATE_HZ, max_width: int = MAX_WIDTH) -> None:
        if certificate is None and not allow_plaintext and not is_loopback(address):
            raise PlaintextRefused(f"view: {address}: plaintext is refused off the loopback; give the rig file a "
                                   f"[tls] table (make certs) or set tls.allow_plaintext = true")
        tls = None
        if certificate is not None:
            tls = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
            tls.minimum_version = ssl.TLSVersion.TLSv1_2
            try:
                tls.load_cert_chain(*certificate)
            except (OSError, ssl.SSLError) as exc:
                raise OSError(f"view: cannot load tls.cert {certificate[0]!r} and tls.key {certificate[1]!r}: "
                              f"{exc}") from exc
        self.page = _PAGE.read_bytes()
        self.frames = FrameSource(max_rate_hz=max_rate_hz, max_width=max_width)
        self.board = StatusBoard(report, channels, self.frames)
        host, _, port = address.rpartition(":")
        try:
            # Bound before anything starts: a port in use leaves nothing behind.
            self._server = _Server((host.strip("[]"), int(port)), self, tls)
        except OSError as exc:
            raise OSError(f"view: cannot listen on {address}: {exc.strerror or exc}") from exc
        #: The bound port (the one asked for, or the free one port 0 took).
        self.port: int = self._server.server_address[1]
        scheme = "https" if tls is not None else "http"
        self.url = f"{scheme}://{host}:{self.port}/"
        self.frames.start()
        watchers.attach(self.frames.feed)
        # A tenth of a second between looks at the stop flag: close() returns within it.
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.1,), name="live-view-http",
                                        daemon=True)
        self._thread.start()
        log.info("live view on %s", self.url)

    def close(self) -> None:
        """Stop serving: every stream ends, the port is released."""
        self.frames.close()
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5.0)

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
