"""X-Plane's RPOS stream (and its DATA output as a fallback): `xplane://XPHOST:49000`.

X-Plane receives on port 49000 and answers a request from the address it came from (Laminar
Research, "Exchanging Data with X-Plane", in X-Plane's Instructions folder). This side binds a
socket (`listen=HOST:PORT`, default any free port), sends X-Plane `RPOS\\0` + the rate as a
NUL-terminated ASCII string (`60\\0`) at start and again every REQUEST_EVERY_S (an X-Plane that
restarts forgets the request), and `RPOS\\0` + `0\\0` at close to stop the stream.
X-Plane 12 ignores requests unless Settings > Network > "Accept incoming connections" is on.

RPOS reply, 69 bytes, little-endian (Laminar's document; the Wireshark X-Plane dissector
packet-xplane.c has the same offsets), struct '<4sxddd10f':

    off  type       field
    0    char[4]+1  "RPOS" and one byte X-Plane uses itself (only the 4 letters are matched)
    5    double     longitude, deg
    13   double     latitude, deg
    21   double     elevation above mean sea level, m
    29   float      height above ground, m
    33   float      pitch, true heading, roll, deg (that order), against X-Plane's local
    37   float        frame, which is north-east-down at the aircraft to within the curvature
    41   float        between the aircraft and that frame's origin
    45.. float      velocities east, up, south (m/s) and P, Q, R (rad/s): not used

DATA output (Settings > Data Output, "Network via UDP" to this side's listen address): "DATA",
one byte, then 36-byte records of an int32 index and eight float32 (-999: unused). Row 17
gives pitch, roll and true heading (deg), row 20 latitude, longitude (deg) and altitude (ft
above mean sea level). Its latitude and longitude are float32, about 1 m apart: the eyepoint
jitters by that much (RPOS's are doubles). A pose needs both rows: one datagram with a row
and the other from an earlier one is enough.
"""

from __future__ import annotations

import logging
import struct

from .receiver import UdpPoseSource
from .stream import Malformed, Pose, PoseStream

log = logging.getLogger("ig.host.simhost")

#: X-Plane's receive port.
XPLANE_PORT = 49000

#: How often the RPOS request is sent again, seconds.
REQUEST_EVERY_S = 5.0

RPOS = struct.Struct("<4sxddd10f")
DATA_RECORD = struct.Struct("<i8f")
#: DATA's "unused" value.
UNUSED = -999.0
FT_M = 0.3048


def rpos_request(rate_hz: float) -> bytes:
    """X-Plane's RPOS request: "RPOS\\0" then the rate, whole datagrams a second, as a
    NUL-terminated ASCII string ("0" stops the stream)."""
    return b"RPOS\x00" + str(max(0, round(rate_hz))).encode("ascii") + b"\x00"


def decode_rpos(datagram: bytes) -> Pose:
    """The pose of one RPOS reply.

    Raises:
        Malformed: not 69 bytes (truncated, oversized) or a value that cannot be placed.
    """
    n = len(datagram)
    if n != RPOS.size:
        raise Malformed("truncated" if n < RPOS.size else "oversized", f"RPOS of {n} bytes, not {RPOS.size}")
    _, lon, lat, elev, _agl, pitch, heading, roll, *_ = RPOS.unpack(datagram)
    return Pose(lat, lon, elev, heading, pitch, roll).check()


class DataRows:
    """X-Plane DATA datagrams into poses: the last attitude (row 17) and position (row 20)."""

    def __init__(self) -> None:
        self.attitude: tuple[float, float, float] | None = None  # heading, pitch, roll
        self.position: tuple[float, float, float] | None = None  # lat, lon, alt m

    def decode(self, datagram: bytes) -> Pose | None:
        """The pose after one DATA datagram; None while a row has never come, or when this
        datagram holds neither row.

        Raises:
            Malformed: a body that is not whole records (truncated), or a used row with an
                unused (-999) or unplaceable value.
        """
        body = datagram[5:]
        if len(datagram) < 5 or len(body) % DATA_RECORD.size:
            raise Malformed("truncated", f"DATA of {len(datagram)} bytes: not 5 + n x {DATA_RECORD.size}")
        used = False
        for off in range(0, len(body), DATA_RECORD.size):
            index, *v = DATA_RECORD.unpack_from(body, off)
            if index == 17:
                _check_used(v[:3], "DATA row 17 pitch, roll, heading")
                self.attitude = (v[2], v[0], v[1])
                used = True
            elif index == 20:
                _check_used(v[:3], "DATA row 20 lat, lon, alt")
                self.position = (v[0], v[1], v[2] * FT_M)
                used = True
        if not used or self.attitude is None or self.position is None:
            return None
        return Pose(*self.position, *self.attitude).check()


def _check_used(values: list[float], what: str) -> None:
    if any(v == UNUSED for v in values):
        raise Malformed("missing", f"{what} has the unused value -999: {values}")


class XPlaneSource(UdpPoseSource):
    """`xplane://XPHOST:PORT`: requests RPOS from X-Plane at XPHOST:PORT, reads RPOS and DATA.

    Args:
        bind: this side's (host, port); port 0: any free port.
        stream: where the poses go.
        xplane: X-Plane's (host, port) the requests go to; None sends none (DATA output only).
        rate_hz: the datagrams a second asked for.
    """

    scheme = "xplane"

    def __init__(self, bind: tuple[str, int], stream: PoseStream, *, xplane: tuple[str, int] | None,
                 rate_hz: float = 60.0) -> None:
        super().__init__(bind, stream)
        self.xplane = xplane
        self.rate_hz = rate_hz
        self.data = DataRows()
        self._next_request = float("-inf")

    def decode(self, datagram: bytes) -> Pose | None:
        head = datagram[:4]
        if head == b"RPOS":
            return decode_rpos(datagram)
        if head == b"DATA":
            return self.data.decode(datagram)
        raise Malformed("garbage", f"{len(datagram)} bytes starting {datagram[:8]!r}: neither RPOS nor DATA")

    def tick(self, now: float) -> None:
        if self.xplane is None or now < self._next_request:
            return
        self._next_request = now + REQUEST_EVERY_S
        self._send(rpos_request(self.rate_hz))

    def close(self) -> None:
        if self.xplane is not None:
            self._send(rpos_request(0))
        super().close()

    def _send(self, request: bytes) -> None:
        assert self.xplane is not None
        try:
            self.sock.sendto(request, self.xplane)
            self.stream.count_request()
        except OSError as exc:
            log.warning("%s: RPOS request to %s:%d failed: %s", self.stream.name, *self.xplane, exc)
