"""The IG side of a CIGI session: what the host's messages do to the rig, frame by frame.

No sockets here (endpoint.py has them): `receive` takes a datagram as it arrives, `begin_frame`
is called once at the start of every IG frame and returns what the frame shows (a FrameInput
for the publisher) and the queries to answer, and `start_of_frame` encodes the Start of Frame
with the answers ready by then, in the host's version and byte order.

Frame sync (docs/cigi.md):
- synchronous: the IG is the clock. The host answers each Start of Frame with one message;
  each IG frame consumes at most one host message, the oldest waiting (more than
  SYNC_BACKLOG waiting: the oldest are dropped, counted), so a host frame is never used twice
  and never skipped while the host keeps pace.
- asynchronous: the host sends at its own rate; every frame takes all messages waiting, and
  with IG Control's extrapolation bit the ownship is extrapolated from its last two poses to
  the frame's time through the host's 10 microsecond timestamps (at most MAX_EXTRAPOLATION_S
  ahead).

A host whose frame counter goes back (it restarted) starts a new run; one silent for
stale_after_s is reported stale and the last eyepoint is held.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from host_sim.publisher import FrameInput
from host_sim.replay.attitude import hpr_of_matrix
from ig.v1 import frame_pb2
from services.rig.environment import Environment, WeatherLayer
from services.rig.frame import ChannelSpec, Eyepoint, check_channel, hpr_matrix
from services.rig.grpc_util import clip

from . import packets as pk
from .codec import decode, encode, name_of, packet_size
from .geometry import Origin, WorldPose, pose_of_geodetic, world_of_body
from .packets import V3_3, CigiError, Message, Version
from .queries import Job, height_job, sight_job

log = logging.getLogger("ig.host.cigi")

#: Host messages a synchronous frame may find waiting before the oldest are dropped: a host a
#: frame or two ahead (a burst after a network stall) catches up without losing messages.
SYNC_BACKLOG = 4

#: Messages waiting in asynchronous mode before the oldest are dropped.
ASYNC_BACKLOG = 64

#: CigiStatus.ownship: what the eyepoint follows (docs/cigi.md, "The ownship").
OWNSHIP_WAITING = "waiting for the ownship"
OWNSHIP_FOLLOWING = "following the ownship"

#: Longest the ownship is extrapolated past the host's last pose, seconds: beyond, a late host
#: would send the eye flying off along a stale velocity.
MAX_EXTRAPOLATION_S = 0.1

#: Largest IG -> host datagram, bytes. Responses that do not fit wait for the next frame
#: (counted): hosts built on the CIGI Class Library receive into fixed buffers of a few KiB to
#: 32 KiB, and 8 KiB stays well inside every one seen and inside jumbo-free UDP over Ethernet
#: after IP fragmentation.
MAX_REPLY_BYTES = 8192

#: Responses that may wait for later frames; beyond, the oldest are dropped (counted): a host
#: asking more each frame than a datagram takes would otherwise grow the wait without end, and
#: an answer many frames old is worth less than a fresh one.
MAX_PENDING_REPLIES = 2048

#: The host's 10 microsecond timestamps wrap at 2^32 ticks (about 11.9 hours).
_TICKS_PER_S = 100_000
_WRAP = 1 << 32

#: Entities may be attached to parents; a chain longer than this is refused (a loop).
_MAX_ATTACH_DEPTH = 16

IG_MODES = {0: "reset", 1: "operate", 2: "debug"}

#: The CIGI default date when Celestial Sphere Control's date is not valid: the March equinox.
_DEFAULT_DATE = (2026, 3, 20)


@dataclass
class EntityState:
    """One entity as the host last set it (geodetic, or relative to its parent when attached)."""

    entity_id: int
    state: int
    attached: bool
    parent_id: int
    entity_type: int
    values: tuple[float, float, float, float, float, float]  # lat/x, lon/y, alt/z, yaw, pitch, roll


@dataclass
class Counters:
    """What the session counts (mirrors ig.v1.CigiStatus)."""

    messages: int = 0
    refused: dict[str, int] = field(default_factory=dict)
    packets: dict[str, int] = field(default_factory=dict)
    unused: dict[str, int] = field(default_factory=dict)
    skipped: int = 0
    ig_frames: int = 0
    stale_events: int = 0
    restarts: int = 0
    queries_answered: int = 0
    queries_invalid: int = 0
    queries_failed: int = 0
    messages_dropped: int = 0
    responses_deferred: int = 0
    responses_dropped: int = 0
    last_error: str = ""
    #: What the query service said of its database ("": nothing wrong), e.g. that it holds no terrain.
    query_database: str = ""


@dataclass
class _Received:
    message: Message
    sender: tuple[str, int]
    at: float


class CigiSession:
    """The IG's state of one CIGI host (module doc).

    Args:
        origin: WGS-84 (lat deg, lon deg, height m) of the world's (0, 0, 0).
        channels: the rig's channels by CIGI view id (their rig-file views).
        mode: "sync" or "async".
        stale_after_s: the host is stale after this long without a message.
        clock: monotonic seconds; wall: UNIX seconds.
        solar: sun_direction(year, month, day, hour, minute, lat, lon) -> (e, n, u); None
            ignores Celestial Sphere Control's sun.
        announce: send Start of Frame before the host's first message too (in CIGI 3.3,
            little-endian), for hosts that wait for the IG to speak first.
        initial_pose: WGS-84 (lat deg, lon deg, height m, heading, pitch, roll deg) rendered
            while no ownship pose is known (before the host's first Entity Control or Entity
            Position of entity 0, and after a restart or reset forgot it), so that a host that
            only sends requests, or a CIGI 4.0 host without Entity Position, still gets a
            picture; None: no frame until the ownship.
    """

    def __init__(self, *, origin: Origin, channels: Mapping[int, ChannelSpec], mode: str = "sync",
                 stale_after_s: float = 1.0, clock: Callable[[], float] = time.monotonic,
                 wall: Callable[[], float] = time.time,
                 solar: Callable[..., tuple[float, float, float]] | None = None, announce: bool = False,
                 initial_pose: tuple[float, float, float, float, float, float] | None = None) -> None:
        if mode not in ("sync", "async"):
            raise ValueError(f"mode: {mode!r} is not 'sync' or 'async'")
        self.origin = origin
        self.channels = dict(channels)
        self.mode = mode
        self.stale_after_s = stale_after_s
        self.clock = clock
        self.wall = wall
        self.solar = solar
        self.announce = announce
        self.initial = None if initial_pose is None else pose_of_geodetic(*initial_pose, origin).eyepoint()
        self.counters = Counters()
        self._lock = threading.Lock()
        self._inbox: deque[_Received] = deque()
        self._start = clock()
        # Host-facing state; touched by begin_frame only (the publisher's thread).
        self.version: Version | None = None
        self.byte_order = "<"
        self.sender: tuple[str, int] | None = None
        self.ig_mode = 0
        self.database_number = 0
        self.last_host_frame: int | None = None
        self.extrapolate = False
        self.entities: dict[int, EntityState] = {}
        self.views: dict[int, ChannelSpec] = {}
        self.visibility_m: float | None = None
        self.layers: dict[int, WeatherLayer] = {}
        self.sun: tuple[float, float, float] | None = None
        #: (kind, id) -> (IG frame it was made in, update period, the request)
        self.periodic: dict[tuple[str, int], tuple[int, int, object]] = {}
        self._last_message_at: float | None = None
        self.stale = False
        self._ownship_samples: deque[tuple[float, WorldPose]] = deque(maxlen=2)
        self._ts_offset: float | None = None
        self._ig_frame = 0
        self._restarted = False
        self._pending_replies: deque[object] = deque()
        #: The timestamp of the host message being applied, 10 us ticks (None: not valid).
        self._host_time: int | None = None

    # -- the socket's side ------------------------------------------------------------------

    def receive(self, datagram: bytes, sender: tuple[str, int]) -> bool:
        """Take one datagram from the host; a message that cannot be decoded is refused and
        counted and changes nothing. Returns whether it was taken."""
        try:
            message = decode(datagram, sender="host")
        except CigiError as exc:
            self._refuse(exc.cause, str(exc))
            return False
        now = self.clock()
        with self._lock:
            last = self._inbox[-1].message if self._inbox else None
            if self.mode == "sync" and last is not None and _host_frame(last) == _host_frame(message):
                # A host repeating its message while it waits for our first Start of Frame (or
                # a duplicated datagram): the newer replaces it, and nothing is dropped.
                self._inbox.pop()
            self._inbox.append(_Received(message, sender, now))
            limit = SYNC_BACKLOG if self.mode == "sync" else ASYNC_BACKLOG
            while len(self._inbox) > limit:
                self._inbox.popleft()
                self.counters.messages_dropped += 1
        return True

    def _refuse(self, cause: str, message: str) -> None:
        with self._lock:
            self.counters.refused[cause] = self.counters.refused.get(cause, 0) + 1
            self.counters.last_error = clip(f"{cause}: {message}")
        log.warning("CIGI message refused: %s", message)

    # -- the frame's side -------------------------------------------------------------------

    def begin_frame(self):
        """Start an IG frame: consume the host's message(s) (module doc), and return
        (FrameInput for the publisher, the queries due this frame)."""
        now = self.clock()
        with self._lock:
            if self.mode == "sync":
                taken = [self._inbox.popleft()] if self._inbox else []
            else:
                taken = list(self._inbox)
                self._inbox.clear()
        jobs: list[Job] = []
        self._restarted = False
        for received in taken:
            jobs += self._apply(received)
        self._ig_frame += 1
        self.counters.ig_frames += 1
        # Periodic requests: answered every n frames after the frame that made them.
        for made_at, period, request in self.periodic.values():
            if self._ig_frame != made_at and (self._ig_frame - made_at) % period == 0:
                jobs += self._jobs_of(request)
        sample_time = None
        if taken:
            # Latency counts from the arrival of the host's data the frame shows.
            sample_time = self.wall() - (now - taken[-1].at)
        stale = self._last_message_at is not None and now - self._last_message_at > self.stale_after_s
        if stale and not self.stale:
            self.counters.stale_events += 1
            log.warning("CIGI host stale: nothing for %.2f s; holding the last eyepoint",
                        now - self._last_message_at)
        self.stale = stale
        eyepoint = None
        if self.ig_mode != 0:
            eyepoint = self._ownship_eyepoint(now)
        # No ownship yet: the initial pose, in operate or debug mode, and before the host's
        # first message (its IG mode unknown): a rig that waits for entity 0 shows nothing to
        # a host that only asks questions. In reset mode the channels hold their picture.
        if eyepoint is None and (self.ig_mode != 0 or self.version is None):
            eyepoint = self.initial
        views = tuple(self._view_messages())
        env = self._environment()
        return FrameInput(eyepoint=eyepoint, host_frame_number=self.last_host_frame, environment=env,
                          views=views, new_run=self._restarted, sample_time=sample_time), jobs

    def start_of_frame(self, answers: list) -> list[bytes]:
        """The Start of Frame datagram of the frame begun, with as many answers as fit (the
        rest wait for the next frame); [] before the host's first message (its version and byte
        order unknown) unless announcing."""
        self._pending_replies.extend(answers)
        while len(self._pending_replies) > MAX_PENDING_REPLIES:
            self._pending_replies.popleft()
            self.counters.responses_dropped += 1
        if self.version is None and not self.announce:
            return []
        version = self.version or V3_3
        elapsed = self.clock() - self._start
        sof = pk.StartOfFrame(
            database_number=self.database_number, ig_status=0, ig_mode=self.ig_mode, timestamp_valid=True,
            earth_ref_model=0, ig_frame=self._ig_frame % _WRAP,
            timestamp=int(elapsed * _TICKS_PER_S) % _WRAP,
            last_host_frame=(self.last_host_frame or 0) % _WRAP, condition_flags=0)
        packets: list = [sof]
        size = packet_size(sof, version)
        while self._pending_replies:
            n = packet_size(self._pending_replies[0], version)
            if size + n > MAX_REPLY_BYTES:
                self.counters.responses_deferred += len(self._pending_replies)
                break
            packets.append(self._pending_replies.popleft())
            size += n
        return [encode(packets, version, self.byte_order)]

    @property
    def ig_frame(self) -> int:
        return self._ig_frame

    def silent_for(self) -> float | None:
        """Seconds since the host's last message by the session's clock; None before its first."""
        last = self._last_message_at
        return None if last is None else self.clock() - last

    # -- applying a message -----------------------------------------------------------------

    def _apply(self, received: _Received) -> list[Job]:
        msg = received.message
        self.version, self.byte_order, self.sender = msg.version, msg.byte_order, received.sender
        self._last_message_at = received.at
        self.counters.messages += 1
        self.counters.skipped += sum(msg.skipped.values())
        jobs: list[Job] = []
        for packet in msg.packets:
            name = name_of(packet, msg.version)
            handler = _HANDLERS.get(type(packet))
            if handler is None:
                self.counters.unused[name] = self.counters.unused.get(name, 0) + 1
                continue
            try:
                used = handler(self, packet, received)
            except ValueError as exc:
                self._refuse("bad_value", f"{name}: {exc}")
                continue
            if used is False:
                self.counters.unused[name] = self.counters.unused.get(name, 0) + 1
                continue
            self.counters.packets[name] = self.counters.packets.get(name, 0) + 1
            if isinstance(used, list):
                jobs += used
        return jobs

    def _ig_control(self, p: pk.IGControl, received: _Received) -> bool:
        host_frame = p.host_frame
        if self.last_host_frame is not None:
            back = (self.last_host_frame - host_frame) % _WRAP
            # The counter went back (not forward around the wrap): the host started again.
            if 0 < back < _WRAP // 2:
                self._restart(f"host frame {host_frame} after {self.last_host_frame}")
        if p.ig_mode == 0 and self.ig_mode != 0:
            self._reset()
        self.ig_mode = p.ig_mode
        self.database_number = p.database_number
        self.last_host_frame = host_frame
        self.extrapolate = bool(p.extrapolation)
        if p.timestamp_valid:
            # The host's clock against ours: the smallest difference seen is the one with the
            # least network delay in it.
            offset = received.at - p.timestamp / _TICKS_PER_S
            if self._ts_offset is None or offset < self._ts_offset:
                self._ts_offset = offset
            self._host_time = p.timestamp
        else:
            self._host_time = None
        return True

    def _restart(self, why: str) -> None:
        self.counters.restarts += 1
        self._restarted = True
        self._reset()
        self._ts_offset = None
        log.info("CIGI host restarted (%s): a new run", why)

    def _reset(self) -> None:
        """IG reset: the host's entities, requests and environment are forgotten."""
        self.entities.clear()
        self.periodic.clear()
        self.views.clear()
        self.layers.clear()
        self.visibility_m = None
        self.sun = None
        self._ownship_samples.clear()

    def _entity_control(self, p, received: _Received) -> bool:
        if p.entity_state == 2 or (p.entity_state == 0 and p.entity_id != 0):
            self.entities.pop(p.entity_id, None)
            return True
        values = (p.lat_x, p.lon_y, p.alt_z, p.yaw, p.pitch, p.roll)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"entity {p.entity_id}: pose {values} is not finite")
        self.entities[p.entity_id] = EntityState(p.entity_id, p.entity_state, bool(p.attach), p.parent_id,
                                                 p.entity_type, values)
        if p.entity_id == 0:
            self._ownship_moved(received)
        return True

    def _entity_position_v4(self, p, received: _Received) -> bool:
        # CIGI 4.0 splits Entity Control: the pose comes in Entity Position.
        known = self.entities.get(p.entity_id)
        values = (p.lat_x, p.lon_y, p.alt_z, p.yaw, p.pitch, p.roll)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"entity {p.entity_id}: pose {values} is not finite")
        self.entities[p.entity_id] = EntityState(p.entity_id, 1 if known is None else known.state, bool(p.attach),
                                                 p.parent_id, 0 if known is None else known.entity_type, values)
        if p.entity_id == 0:
            self._ownship_moved(received)
        return True

    def _ownship_moved(self, received: _Received) -> None:
        """Record the ownship's new pose (the eyepoint is the newest; the two newest give the
        velocity asynchronous mode extrapolates with)."""
        pose = self.pose_of(0)
        if pose is None:
            self.entities.pop(0)
            raise ValueError("entity 0 (the ownship) cannot be attached to another entity")
        self._ownship_samples.append((self._sample_time(received), pose))

    def _entity_control_v4(self, p, received: _Received) -> bool:
        if p.entity_state == 2:
            self.entities.pop(p.entity_id, None)
        elif p.entity_id in self.entities:
            self.entities[p.entity_id] = replace(self.entities[p.entity_id], state=p.entity_state,
                                                 entity_type=getattr(p, "entity_type", 0))
        return True

    def _sample_time(self, received: _Received) -> float:
        """When the host computed its pose, on our clock: its timestamp through the offset in
        asynchronous mode, else the arrival."""
        host_time = self._host_time
        if host_time is not None and self._ts_offset is not None:
            return self._ts_offset + host_time / _TICKS_PER_S
        return received.at

    def pose_of(self, entity_id: int, depth: int = 0) -> WorldPose | None:
        """The world pose of an entity (through its parents when attached); None if unknown."""
        e = self.entities.get(entity_id)
        if e is None or depth > _MAX_ATTACH_DEPTH:
            return None
        lat, lon, alt, yaw, pitch, roll = e.values
        if not e.attached:
            return pose_of_geodetic(lat, lon, alt, yaw, pitch, roll, self.origin)
        parent = self.pose_of(e.parent_id, depth + 1)
        if parent is None:
            return None
        position = world_of_body(parent, np.array([lat, lon, alt]))[0]
        # Relative attitude: yaw right, pitch up, roll right-wing-down in the parent's body.
        rotation = parent.rotation @ hpr_matrix(yaw, pitch, roll)
        h, p, r = hpr_of_matrix(rotation[None])[0]
        return WorldPose(position, rotation, float(h), float(p), float(r))

    def _ownship_eyepoint(self, now: float) -> Eyepoint | None:
        if not self._ownship_samples:
            return None
        newest = self._ownship_samples[-1][1]
        if self.mode != "async" or not self.extrapolate or len(self._ownship_samples) < 2 or self.stale:
            return newest.eyepoint()
        (t0, a), (t1, b) = self._ownship_samples
        dt = t1 - t0
        if not dt > 1e-6:  # guard: two poses of one instant give no velocity
            return newest.eyepoint()
        ahead = min(max(now - t1, 0.0), MAX_EXTRAPOLATION_S)
        f = ahead / dt
        position = b.position + (b.position - a.position) * f
        def turn(x: float, y: float) -> float:
            return y + ((y - x + 180.0) % 360.0 - 180.0) * f
        return Eyepoint(position, turn(a.heading_deg, b.heading_deg) % 360.0,
                        max(-90.0, min(90.0, turn(a.pitch_deg, b.pitch_deg))), turn(a.roll_deg, b.roll_deg))

    def _view_control(self, p, received: _Received) -> bool:
        spec = self.channels.get(p.view_id)
        if spec is None or p.entity_id != 0:
            return False
        current = self.views.get(p.view_id, spec)
        changed: dict[str, Any] = {}
        for flag, name, value in (("yaw_enable", "yaw_deg", p.yaw), ("pitch_enable", "pitch_deg", p.pitch),
                                  ("roll_enable", "roll_deg", p.roll)):
            if getattr(p, flag):
                changed[name] = float(value)
        moved = [a for a in ("x", "y", "z") if getattr(p, f"{a}_enable") and getattr(p, a) != 0.0]
        if moved:
            # Every channel renders the one eyepoint the compositor checks; a per-view eye
            # offset would break that, so only the angles are taken.
            self.counters.unused["View Control eye offset"] = self.counters.unused.get(
                "View Control eye offset", 0) + 1
        view = replace(current, **changed)
        check_channel(view)
        self.views[p.view_id] = view
        return True

    def _view_definition(self, p, received: _Received) -> bool:
        spec = self.channels.get(p.view_id)
        if spec is None:
            return False
        current = self.views.get(p.view_id, spec)
        changed: dict[str, Any] = {}
        for flag, name, value in (("left_enable", "left_deg", p.left), ("right_enable", "right_deg", p.right),
                                  ("bottom_enable", "bottom_deg", p.bottom), ("top_enable", "top_deg", p.top)):
            if getattr(p, flag):
                changed[name] = float(value)
        view = replace(current, **changed)
        check_channel(view)
        self.views[p.view_id] = view
        return True

    def _view_messages(self):
        for view_id, view in self.views.items():
            base = self.channels[view_id]
            msg = frame_pb2.ChannelView(channel=base.name)
            for name in ("yaw_deg", "pitch_deg", "roll_deg", "left_deg", "right_deg", "bottom_deg", "top_deg"):
                if getattr(view, name) != getattr(base, name):
                    setattr(msg, name, getattr(view, name))
            yield msg

    def _celestial(self, p, received: _Received) -> bool:
        if self.solar is None or not p.sun_enable:
            self.sun = None
            return bool(self.solar is not None)
        year, month, day = _DEFAULT_DATE
        if p.date_valid:
            month, day, year = p.date // 1_000_000, (p.date // 10_000) % 100, p.date % 10_000
            if not (1 <= month <= 12 and 1 <= day <= 31):
                raise ValueError(f"date: {p.date} is not MMDDYYYY")
        if not (0 <= p.hour <= 23 and 0 <= p.minute <= 59):
            raise ValueError(f"time: {p.hour}:{p.minute} is not a time of day")
        e, n, u = self.solar(year=year, month=month, day=day, hour=p.hour, minute=p.minute,
                             lat_deg=self.origin[0], lon_deg=self.origin[1])
        self.sun = (float(e), float(n), float(u))
        return True

    def _atmosphere(self, p, received: _Received) -> bool:
        if not (math.isfinite(p.visibility) and p.visibility > 0):
            raise ValueError(f"visibility: {p.visibility} is not a number > 0")
        self.visibility_m = float(p.visibility)
        return True

    def _weather(self, p, received: _Received) -> bool:
        if p.scope != 0:
            return False  # regional and entity weather: not modelled
        if not p.weather_enable:
            self.layers.pop(p.layer_id, None)
            return True
        for name in ("base_elevation", "thickness", "visibility", "coverage"):
            if not math.isfinite(getattr(p, name)):
                raise ValueError(f"{name}: {getattr(p, name)} is not finite")
        if not p.visibility > 0:
            raise ValueError(f"visibility: {p.visibility} is not > 0")
        if p.thickness < 0:
            raise ValueError(f"thickness: {p.thickness} is < 0")
        self.layers[p.layer_id] = WeatherLayer(
            layer_id=p.layer_id, base_m=float(p.base_elevation) - self.origin[2], thickness_m=float(p.thickness),
            visibility_m=float(p.visibility), coverage=min(1.0, max(0.0, float(p.coverage) / 100.0)),
            cloud=p.cloud_type != 0)
        return True

    def _environment(self) -> Environment | None:
        if self.visibility_m is None and not self.layers and self.sun is None:
            return None
        return Environment(visibility_m=self.visibility_m,
                           layers=tuple(self.layers[k] for k in sorted(self.layers)), sun=self.sun)

    def _request(self, p, received: _Received) -> list[Job]:
        kind = "hot" if isinstance(p, pk.HatHotRequest) else "los"
        key = (kind, p.request_id if kind == "hot" else p.los_id)
        # A request replaces any earlier one of its id; period 0 is answered once.
        self.periodic.pop(key, None)
        if p.update_period > 0:
            self.periodic[key] = (self._ig_frame + 1, p.update_period, p)
        return self._jobs_of(p)

    def _jobs_of(self, p) -> list[Job]:
        lsn = (self.last_host_frame or 0) & 0xF
        if isinstance(p, pk.HatHotRequest):
            pose = self.pose_of(p.entity_id) if p.coord_system == 1 else None
            return [height_job(p, lsn, pose, self.origin)]
        pose = self.pose_of(p.entity_id)
        return [sight_job(p, lsn, pose, self.origin)]

    def count_answers(self, answered: int, invalid: int, failed: int) -> None:
        """Count answers to queries (from the endpoint's query thread)."""
        with self._lock:
            self.counters.queries_answered += answered
            self.counters.queries_invalid += invalid
            self.counters.queries_failed += failed

    # -- status -----------------------------------------------------------------------------

    def status(self) -> dict:
        """The fields of ig.v1.CigiStatus."""
        with self._lock:
            c = self.counters
            return dict(
                host_address="" if self.sender is None else f"{self.sender[0]}:{self.sender[1]}",
                version="" if self.version is None else f"{self.version.major}.{self.version.minor}",
                byte_order={"<": "little", ">": "big"}[self.byte_order] if self.version else "",
                mode=self.mode, ig_mode=IG_MODES.get(self.ig_mode, str(self.ig_mode)), messages=c.messages,
                refused=dict(c.refused), packets=dict(c.packets), unused=dict(c.unused), skipped=c.skipped,
                last_host_frame=(self.last_host_frame or 0) % _WRAP, ig_frames=c.ig_frames, stale=self.stale,
                stale_events=c.stale_events, restarts=c.restarts, entities=len(self.entities),
                queries_answered=c.queries_answered, queries_invalid=c.queries_invalid,
                queries_failed=c.queries_failed, periodic_requests=len(self.periodic),
                messages_dropped=c.messages_dropped, responses_deferred=c.responses_deferred,
                responses_dropped=c.responses_dropped,
                last_error=c.last_error, ownship=self.ownship_state,
                query_database=c.query_database)

    @property
    def ownship_state(self) -> str:
        """"following the ownship" once entity 0 has a pose, else "waiting for the ownship"
        (with what is rendered meanwhile)."""
        if self._ownship_samples:
            return OWNSHIP_FOLLOWING
        return OWNSHIP_WAITING + (" (rendering the initial pose)" if self.initial is not None else " (no frame)")

    def query_database_is(self, note: str) -> None:
        """Record what the query service said of its database ("" : it holds terrain), from the
        endpoint's query thread; logged once per change."""
        with self._lock:
            changed = note != self.counters.query_database
            self.counters.query_database = note
        if changed and note:
            log.warning("CIGI queries: %s", note)


def _host_frame(message: Message) -> int | None:
    first = message.packets[0] if message.packets else None
    return first.host_frame if isinstance(first, pk.IGControl) else None


_HANDLERS: dict[type, Callable] = {
    pk.IGControl: CigiSession._ig_control,
    pk.EntityControl: CigiSession._entity_control,
    pk.ViewControl: CigiSession._view_control,
    pk.ViewDefinition: CigiSession._view_definition,
    pk.CelestialSphereControl: CigiSession._celestial,
    pk.AtmosphereControl: CigiSession._atmosphere,
    pk.WeatherControl: CigiSession._weather,
    pk.HatHotRequest: CigiSession._request,
    pk.LosSegmentRequest: CigiSession._request,
    pk.LosVectorRequest: CigiSession._request,
}
if hasattr(pk, "EntityPosition"):
    _HANDLERS[pk.EntityPosition] = CigiSession._entity_position_v4
if hasattr(pk, "EntityControlV4"):
    _HANDLERS[pk.EntityControlV4] = CigiSession._entity_control_v4
