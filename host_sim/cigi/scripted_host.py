"""A scripted CIGI host over UDP, to drive an IG in tests and from `ig cigi-host`.

Synchronous mode (the default; the IG is the clock): the host sends an IG Control with
ig_mode=operate before any Start of Frame (CCL hosts do, so an IG waiting for its host sees
something), then answers each SOF with exactly one message: IG Control (host frame, timestamp,
last IG frame = the SOF's IG frame), the ownship's Entity Control along the scripted path, and
the HAT/HOT and LOS requests the script puts at that host frame. Asynchronous mode
(`async_rate_hz`) sends on the host's own clock with Timestamp Valid set.

Every SOF and every response is recorded with the frame it came with, for tests.

Script (JSON or `Script`): "path" is a list of [t_s, lat, lon, alt_m, yaw, pitch, roll]
keyframes interpolated linearly (degrees, metres, seconds since frame 0); "queries" a list of
{"host_frame", "kind" (hot | hat | hot_extended | los_segment | los_vector), "params",
"update_period", "every"}: the request is sent at host_frame and, when every > 0, every that many
frames after. Params left out default to the ownship's position at that frame (and, for
los_vector, straight down: elevation -90, max_range 10 km).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import socket
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from host_sim.cigi.codec import decode, encode
from host_sim.cigi.packets import (
    V3_3,
    CigiError,
    EntityControl,
    EntityControlV4,
    EntityPosition,
    HatHotRequest,
    IGControl,
    LosSegmentRequest,
    LosVectorRequest,
    Packet,
    StartOfFrame,
    Version,
)

#: Before the IG's first Start of Frame, the first message is sent again this often, seconds.
HELLO_EVERY_S = 0.5

QUERY_KINDS = ("hot", "hat", "hot_extended", "los_segment", "los_vector")
_HAT_HOT_TYPE = {"hat": 0, "hot": 1, "hot_extended": 2}
TICKS_PER_S = 100_000  # CIGI timestamps count 10 microsecond ticks
EARTH_RADIUS_M = 6_371_000.0


@dataclass(frozen=True)
class Keyframe:
    """Ownship pose at a time: degrees, metres, seconds."""

    t_s: float
    lat: float
    lon: float
    alt_m: float
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0


@dataclass(frozen=True)
class Query:
    """A HAT/HOT or LOS request at a host frame (and every `every` frames after when > 0)."""

    host_frame: int
    kind: str
    params: dict[str, float] = field(default_factory=dict)
    update_period: int = 0
    every: int = 0

    def due(self, host_frame: int) -> bool:
        if host_frame == self.host_frame:
            return True
        return self.every > 0 and host_frame > self.host_frame and (host_frame - self.host_frame) % self.every == 0


@dataclass(frozen=True)
class Script:
    """The host's script: the ownship path and the queries; `frame_rate_hz` maps host frames to
    path time in synchronous mode."""

    path: tuple[Keyframe, ...]
    queries: tuple[Query, ...] = ()
    frame_rate_hz: float = 60.0

    def __post_init__(self) -> None:
        if not self.path:
            raise ValueError("script: path has no keyframe")
        if any(b.t_s < a.t_s for a, b in zip(self.path, self.path[1:], strict=False)):
            raise ValueError("script: path keyframes are not in time order")
        if self.frame_rate_hz <= 0:
            raise ValueError(f"script: frame_rate_hz {self.frame_rate_hz} is not positive")
        for q in self.queries:
            if q.kind not in QUERY_KINDS:
                raise ValueError(f"script: query kind {q.kind!r} is not one of {', '.join(QUERY_KINDS)}")
            if q.host_frame < 0 or q.every < 0 or not 0 <= q.update_period <= 255:
                raise ValueError(f"script: query {q} has a negative frame or an update_period outside 0..255")

    def pose(self, t_s: float) -> Keyframe:
        """The ownship pose at t_s, linear between keyframes, held before the first and after the last."""
        path = self.path
        if t_s <= path[0].t_s:
            return path[0]
        for a, b in itertools.pairwise(path):
            if t_s <= b.t_s:
                w = 0.0 if b.t_s == a.t_s else (t_s - a.t_s) / (b.t_s - a.t_s)
                return Keyframe(t_s, *(pa + w * (pb - pa) for pa, pb in
                                       zip(_values(a), _values(b), strict=True)))
        return path[-1]

    @property
    def duration_s(self) -> float:
        return self.path[-1].t_s

    @classmethod
    def from_json(cls, text: str) -> Script:
        """Parse the JSON script format (module docstring); raises ValueError naming the problem."""
        try:
            doc = json.loads(text)
            path = tuple(Keyframe(*map(float, k)) for k in doc["path"])
            queries = tuple(Query(host_frame=int(q["host_frame"]), kind=str(q["kind"]),
                                  params={str(k): float(v) for k, v in q.get("params", {}).items()},
                                  update_period=int(q.get("update_period", 0)), every=int(q.get("every", 0)))
                            for q in doc.get("queries", []))
            return cls(path=path, queries=queries, frame_rate_hz=float(doc.get("frame_rate_hz", 60.0)))
        except (KeyError, TypeError, AttributeError, json.JSONDecodeError) as exc:
            raise ValueError(f"script: {type(exc).__name__}: {exc}") from None

    def to_json(self) -> str:
        return json.dumps({
            "frame_rate_hz": self.frame_rate_hz,
            "path": [list(_values(k, with_t=True)) for k in self.path],
            "queries": [{"host_frame": q.host_frame, "kind": q.kind, "params": q.params,
                         "update_period": q.update_period, "every": q.every} for q in self.queries],
        }, indent=1)


def _values(k: Keyframe, *, with_t: bool = False) -> tuple[float, ...]:
    rest = (k.lat, k.lon, k.alt_m, k.yaw, k.pitch, k.roll)
    return (k.t_s, *rest) if with_t else rest


def default_script(origin: tuple[float, float, float], *, speed_mps: float = 100.0,
                   frame_rate_hz: float = 60.0) -> Script:
    """2 km north, straight and level 300 m above the origin (lat deg, lon deg, height m), a HOT
    request below the ownship every 10 frames and a LOS vector straight down every 10 frames
    (offset by 5)."""
    lat, lon, h = origin
    distance_m = 2000.0
    dlat = math.degrees(distance_m / EARTH_RADIUS_M)
    path = (Keyframe(0.0, lat, lon, h + 300.0), Keyframe(distance_m / speed_mps, lat + dlat, lon, h + 300.0))
    queries = (Query(host_frame=10, kind="hot", every=10), Query(host_frame=5, kind="los_vector", every=10))
    return Script(path=path, queries=queries, frame_rate_hz=frame_rate_hz)


@dataclass(frozen=True)
class Received:
    """A packet the IG sent, with the IG frame of its message's SOF and the host frame the host was
    at when it arrived."""

    host_frame: int
    ig_frame: int
    packet: Packet


@dataclass(frozen=True)
class Sent:
    """A message the host sent."""

    host_frame: int
    packets: tuple[Packet, ...]


class ScriptedHost:
    """Plays a CIGI host over UDP (module docstring). Use as a context manager or call close().

    Args:
        script: what to fly and ask (default: `default_script(origin)`).
        ig_address: where the IG listens (host, port).
        bind: this host's address (host, port); port 0 picks a free one.
        byte_order: "<" little-endian (as x86 CCL hosts) or ">" big-endian.
        async_rate_hz: send on the host's own clock at this rate instead of answering SOFs.
        origin: (lat deg, lon deg, height m) of the default script.
        version: the CIGI version to speak (3.3 by default; 3.2 and 4.0 work too).
    """

    def __init__(self, script: Script | None = None, *, ig_address: tuple[str, int] = ("127.0.0.1", 8000),
                 bind: tuple[str, int] = ("127.0.0.1", 8001), byte_order: str = "<",
                 async_rate_hz: float | None = None, origin: tuple[float, float, float] = (36.3, -84.2, 0.0),
                 version: Version = V3_3) -> None:
        if byte_order not in ("<", ">"):
            raise ValueError(f"byte_order {byte_order!r} is neither '<' nor '>'")
        if async_rate_hz is not None and async_rate_hz <= 0:
            raise ValueError(f"async_rate_hz {async_rate_hz} is not positive")
        self.script = script if script is not None else default_script(origin)
        self.ig_address = ig_address
        self.byte_order = byte_order
        self.async_rate_hz = async_rate_hz
        self.version = version
        self.sofs: list[StartOfFrame] = []
        self.responses: list[Received] = []
        self.sent: list[Sent] = []
        self.decode_errors: Counter[str] = Counter()
        self.host_frame = 0
        self._request_id = 0
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(bind)

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port)."""
        host, port = self._sock.getsockname()[:2]
        return host, port

    def close(self) -> None:
        self._sock.close()

    def __enter__(self) -> ScriptedHost:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def last_ig_frame(self) -> int | None:
        return self.sofs[-1].ig_frame if self.sofs else None

    def run(self, *, frames: int, sof_timeout_s: float = 5.0, start_timeout_s: float | None = None) -> None:
        """Send the first IG Control, then `frames` more messages: one per SOF (synchronous) or on
        the host's clock (asynchronous). Synchronous mode stops early when no SOF arrives for
        sof_timeout_s (start_timeout_s for the first, when given)."""
        self._send(self._message(last_ig_frame=0))
        if self.async_rate_hz is None:
            # Until the IG answers, the first IG Control is sent again now and then: an IG
            # started after the host learns of it this way (it replaces a repeat it holds).
            sof = self._wait_sof(start_timeout_s or sof_timeout_s, hello_every_s=HELLO_EVERY_S)
            while sof is not None and self.host_frame < frames:
                self.host_frame += 1
                self._send(self._message(last_ig_frame=sof.ig_frame))
                if self.host_frame < frames:
                    sof = self._wait_sof(sof_timeout_s)
        else:
            period = 1.0 / self.async_rate_hz
            start = time.monotonic()
            while self.host_frame < frames:
                deadline = start + (self.host_frame + 1) * period
                self._drain(until=deadline)
                self.host_frame += 1
                self._send(self._message(last_ig_frame=self.last_ig_frame or 0))

    def _wait_sof(self, timeout_s: float, *, hello_every_s: float | None = None) -> StartOfFrame | None:
        """Receive until a datagram with an SOF arrives (recording it); None after timeout_s or
        once the host is closed. With hello_every_s, the last message is sent again that often
        while nothing arrives."""
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            wait = left if hello_every_s is None else min(left, hello_every_s)
            try:
                self._sock.settimeout(wait)
                data = self._sock.recv(65536)
            except TimeoutError:
                if hello_every_s is not None and self.sent:
                    self._resend()
                continue
            except OSError:  # closed under us: the test or the command is ending
                return None
            sof = self._record(data)
            if sof is not None:
                return sof

    def _drain(self, *, until: float) -> None:
        """Record whatever the IG sends until the monotonic time `until` (asynchronous mode)."""
        while (left := until - time.monotonic()) > 0:
            self._sock.settimeout(left)
            try:
                self._record(self._sock.recv(65536))
            except TimeoutError:
                return

    def _record(self, data: bytes) -> StartOfFrame | None:
        try:
            message = decode(data, sender="ig")
        except CigiError as exc:
            self.decode_errors[exc.cause] += 1
            return None
        sof = message.packets[0]
        assert isinstance(sof, StartOfFrame)
        self.sofs.append(sof)
        self.responses.extend(Received(self.host_frame, sof.ig_frame, p) for p in message.packets[1:])
        return sof

    def _resend(self) -> None:
        """The last message again (not recorded twice)."""
        with contextlib.suppress(OSError):
            self._sock.sendto(encode(list(self.sent[-1].packets), self.version, self.byte_order), self.ig_address)

    def _send(self, packets: list[Packet]) -> None:
        self._sock.sendto(encode(packets, self.version, self.byte_order), self.ig_address)
        self.sent.append(Sent(self.host_frame, tuple(packets)))

    def time_s(self, host_frame: int) -> float:
        """Path time of a host frame: frames over the script's rate (synchronous) or the async rate."""
        return host_frame / (self.async_rate_hz or self.script.frame_rate_hz)

    def _message(self, *, last_ig_frame: int) -> list[Packet]:
        t = self.time_s(self.host_frame)
        pose = self.script.pose(t)
        packets: list[Packet] = [IGControl(
            ig_mode=1, timestamp_valid=self.async_rate_hz is not None, host_frame=self.host_frame,
            timestamp=int(round(t * TICKS_PER_S)) & 0xFFFFFFFF, last_ig_frame=last_ig_frame)]
        if self.version.major >= 4:
            packets += [EntityControlV4(entity_id=0, entity_state=1),
                        EntityPosition(entity_id=0, roll=pose.roll, pitch=pose.pitch, yaw=pose.yaw,
                                       lat_x=pose.lat, lon_y=pose.lon, alt_z=pose.alt_m)]
        else:
            packets.append(EntityControl(entity_id=0, entity_state=1, roll=pose.roll, pitch=pose.pitch,
                                         yaw=pose.yaw, lat_x=pose.lat, lon_y=pose.lon, alt_z=pose.alt_m))
        packets += [self._request(q, pose) for q in self.script.queries if q.due(self.host_frame)]
        return packets

    def _request(self, q: Query, pose: Keyframe) -> Packet:
        self._request_id = (self._request_id + 1) & 0xFFFF
        p = q.params
        if q.kind in _HAT_HOT_TYPE:
            return HatHotRequest(request_id=self._request_id, request_type=_HAT_HOT_TYPE[q.kind],
                                 update_period=q.update_period, lat_x=p.get("lat", pose.lat),
                                 lon_y=p.get("lon", pose.lon), alt_z=p.get("alt", pose.alt_m))
        if q.kind == "los_segment":
            return LosSegmentRequest(
                los_id=self._request_id, update_period=q.update_period,
                src_lat_x=p.get("src_lat", pose.lat), src_lon_y=p.get("src_lon", pose.lon),
                src_alt_z=p.get("src_alt", pose.alt_m), dst_lat_x=p.get("dst_lat", pose.lat),
                dst_lon_y=p.get("dst_lon", pose.lon), dst_alt_z=p.get("dst_alt", pose.alt_m - 10_000.0))
        return LosVectorRequest(
            los_id=self._request_id, update_period=q.update_period, azimuth=p.get("azimuth", 0.0),
            elevation=p.get("elevation", -90.0), min_range=p.get("min_range", 0.0),
            max_range=p.get("max_range", 10_000.0), src_lat_x=p.get("src_lat", pose.lat),
            src_lon_y=p.get("src_lon", pose.lon), src_alt_z=p.get("src_alt", pose.alt_m))

    def report(self) -> dict[str, Any]:
        """What the host received: SOF count, responses by kind, last IG frame, frames sent."""
        return {
            "sof_count": len(self.sofs),
            "responses_by_kind": dict(Counter(type(r.packet).__name__ for r in self.responses)),
            "last_ig_frame": self.last_ig_frame,
            "host_frames_sent": len(self.sent),
            "decode_errors": dict(self.decode_errors),
            "version": str(self.version),
            "byte_order": "little" if self.byte_order == "<" else "big",
            "mode": "synchronous" if self.async_rate_hz is None else f"asynchronous {self.async_rate_hz} Hz",
        }
