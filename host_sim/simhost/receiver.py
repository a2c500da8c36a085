"""The UDP socket and thread every pose-stream protocol shares.

A UdpPoseSource binds its socket when it is made, reads datagrams on its own thread from
`start()` until `close()`, and hands each to its protocol's `decode`: a Pose goes to the
PoseStream, a refusal (Malformed) is counted by cause, and nothing a datagram holds stops the
reader. The publisher reads the stream through `frame_input`.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import ClassVar

from .stream import Malformed, Pose, PoseStream, SimHostStatus

log = logging.getLogger("ig.host.simhost")

#: The largest datagram read whole (the UDP maximum); one longer is refused as oversized anyway.
MAX_DATAGRAM = 65507

#: How often the reader looks at the stop event, seconds (close() waits at most this long).
_POLL_S = 0.2


def parse_address(value: str, where: str, *, default_port: int | None = None) -> tuple[str, int]:
    """(host, port) of HOST:PORT (port 0: any free port).

    Raises:
        ValueError: not HOST:PORT with a port in [0, 65535], naming where and the value.
    """
    host, sep, port = value.rpartition(":")
    if not sep and default_port is not None:
        host, port = value, str(default_port)
    host = host.strip("[]")
    if not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"{where}: {value!r} is not HOST:PORT with a port in [0, 65535]")
    return host, int(port)


class UdpPoseSource(ABC):
    """One simulator's pose stream on a bound UDP socket (see the module doc).

    Subclasses name their URL scheme and decode one datagram; X-Plane also sends requests
    (`tick`, called by the reader about every _POLL_S).

    Args:
        bind: (host, port) to bind; port 0 takes a free port (`address` says which).
        stream: where the poses go.
    """

    scheme: ClassVar[str] = ""

    def __init__(self, bind: tuple[str, int], stream: PoseStream) -> None:
        self.stream = stream
        family = socket.AF_INET6 if ":" in bind[0] else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            self.sock.bind(bind)
        except OSError:
            self.sock.close()
            raise
        self.sock.settimeout(_POLL_S)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name=f"simhost-{self.scheme}", daemon=True)

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) the socket is bound to."""
        host, port = self.sock.getsockname()[:2]
        return host, port

    @abstractmethod
    def decode(self, datagram: bytes) -> Pose | None:
        """The pose one datagram carries; None: a datagram of the protocol without one (counted
        unused).

        Raises:
            Malformed: the datagram is refused (its cause and what was wrong).
        """

    def tick(self, now: float) -> None:  # noqa: B027 - a protocol without requests has nothing to do
        """Called by the reader about every _POLL_S (monotonic seconds): periodic requests."""

    def start(self) -> UdpPoseSource:
        self._thread.start()
        log.info("%s: reading %s poses on udp://%s:%d", self.stream.name, self.scheme, *self.address)
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self.sock.close()

    def __enter__(self) -> UdpPoseSource:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def frame_input(self, sim_time_s: float = 0.0):
        """The publisher's source (PoseStream.frame_input)."""
        return self.stream.frame_input(sim_time_s)

    def status(self) -> SimHostStatus:
        return self.stream.status()

    def receive(self, datagram: bytes, arrival: float | None = None) -> None:
        """Decode one datagram into the stream (the reader's step; tests call it directly)."""
        try:
            pose = self.decode(datagram)
        except Malformed as exc:
            self.stream.refuse(exc.cause, exc.detail)
            return
        if pose is None:
            self.stream.ignore()
        else:
            self.stream.accept(pose, arrival=arrival)

    def _read(self, clock: Callable[[], float] = time.monotonic) -> None:
        while not self._stop.is_set():
            self.tick(clock())
            try:
                data = self.sock.recv(MAX_DATAGRAM + 1)
            except TimeoutError:
                continue
            except OSError as exc:
                if self._stop.is_set():
                    return
                # An ICMP port-unreachable from an earlier request lands here on some systems:
                # the next datagram still comes.
                log.debug("%s: socket: %s", self.stream.name, exc)
                continue
            arrival = clock()
            try:
                self.receive(data, arrival)
            except Exception as exc:  # the reader must outlive any datagram
                self.stream.refuse("garbage", f"{len(data)} bytes the decoder could not read ({exc!r})")
