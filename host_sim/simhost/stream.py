"""A simulator's pose stream turned into the rig's eyepoint, one frame at a time.

Every protocol module decodes a datagram into a Pose (the simulator's reference point,
geodetic, with its attitude against the local north-east-down frame) or refuses it with a
cause. PoseStream takes the poses as they arrive, stamped with their arrival time, and answers
the publisher's frame_input at the rig's own rate:

- the pose becomes the eyepoint at arrival: the aircraft's eye offset (body axes) added, the
  position carried through ECEF into the world around the origin and the attitude turned from
  the local horizontal at the aircraft to the world's, as a CIGI ownship is
  (host_sim.cigi.geometry.pose_of_geodetic);
- "interpolate" timing shows the eyepoint a fixed delay behind the newest arrival,
  interpolated between the two arrivals around that moment, so that the jitter of a 20-120 Hz
  host is smoothed at the cost of the delay; "extrapolate" shows it now, carried forward
  from the last two arrivals (SIMHOST_TIMINGS, docs/sim-hosts.md);
- heading and roll are interpolated along the shorter arc (a heading of 359.9 degrees followed
  by 0.1 passes north, not south);
- a silent simulator is reported stale after stale_after_s and its last eyepoint is held.
"""

from __future__ import annotations

import itertools
import logging
import math
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from host_sim.cigi.geometry import Origin, pose_of_geodetic, world_of_body
from host_sim.publisher import FrameInput
from services.rig.frame import Eyepoint
from services.rig.rigfile import SIMHOST_TIMINGS

log = logging.getLogger("ig.host.simhost")

#: Why a datagram was refused (counted by cause, each named once in the log).
CAUSES = ("truncated", "oversized", "version", "garbage", "missing", "not_finite", "out_of_range", "out_of_order")

#: Arrivals kept for interpolation and for the interval estimate (two seconds at 120 Hz).
HISTORY = 256

#: Datagram intervals the interval estimate takes the median of: long enough that a late
#: datagram and the early one after it do not move it, short enough to follow a rate change.
INTERVAL_WINDOW = 32

#: The default interpolation delay, in measured datagram intervals: one interval for the
#: datagram to be due, half of one for its jitter.
DEFAULT_DELAY_INTERVALS = 1.5

#: A simulator clock that goes back by more than this is a restart, not a reordered datagram.
RESTART_S = 1.0


class Malformed(ValueError):
    """A datagram that gives no pose; cause is one of CAUSES, detail says what was wrong."""

    def __init__(self, cause: str, detail: str) -> None:
        super().__init__(f"{cause}: {detail}")
        self.cause = cause
        self.detail = detail


@dataclass(frozen=True)
class Pose:
    """One pose as a simulator sends it.

    Attributes:
        lat_deg, lon_deg: WGS-84 geodetic latitude and longitude of the simulator's reference
            point (its flight model's reference point or centre of gravity), degrees.
        alt_m: its height above mean sea level, metres.
        heading_deg, pitch_deg, roll_deg: true heading, pitch and roll against the local
            north-east-down frame at that point (aerospace Z-Y-X Euler angles), degrees.
        host_time_s: the simulator's own clock where the protocol carries a usable one, seconds
            (orders the datagrams); None: arrival order.
        extra: other values the protocol carries that the status shows (a view offset), by name.
    """

    lat_deg: float
    lon_deg: float
    alt_m: float
    heading_deg: float
    pitch_deg: float
    roll_deg: float
    host_time_s: float | None = None
    extra: tuple[tuple[str, float], ...] = ()

    def check(self) -> Pose:
        """self, if every field can be placed.

        Raises:
            Malformed: a value that is not finite (not_finite) or off the earth (out_of_range),
                named with its value.
        """
        for name in ("lat_deg", "lon_deg", "alt_m", "heading_deg", "pitch_deg", "roll_deg"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise Malformed("not_finite", f"{name} {v}")
        if self.host_time_s is not None and not math.isfinite(self.host_time_s):
            raise Malformed("not_finite", f"host_time_s {self.host_time_s}")
        for name, v, lo, hi in (("lat_deg", self.lat_deg, -90.0, 90.0), ("lon_deg", self.lon_deg, -360.0, 360.0),
                                ("alt_m", self.alt_m, -2000.0, 1e6), ("pitch_deg", self.pitch_deg, -90.0, 90.0),
                                ("heading_deg", self.heading_deg, -720.0, 720.0),
                                ("roll_deg", self.roll_deg, -720.0, 720.0)):
            if not lo <= v <= hi:
                raise Malformed("out_of_range", f"{name} {v:g} is outside [{lo:g}, {hi:g}]")
        return self


def eyepoint_of_pose(pose: Pose, *, origin: Origin, eye_offset_m: tuple[float, float, float]) -> Eyepoint:
    """The rig's eyepoint of a simulator pose.

    Args:
        pose: the simulator's reference point and attitude (local north-east-down).
        origin: the world's (0, 0, 0): latitude, longitude (degrees), height (metres).
        eye_offset_m: the eye from the reference point in body axes: x forward, y right, z down,
            metres (turned with the aircraft: a rolled aircraft's raised eye moves sideways).

    Returns:
        The eye's world position (east, north, up metres from the origin) and its heading, pitch
        and roll in the world frame, degrees.
    """
    world = pose_of_geodetic(pose.lat_deg, pose.lon_deg, pose.alt_m, pose.heading_deg, pose.pitch_deg,
                             pose.roll_deg, origin)
    eye = world_of_body(world, np.asarray(eye_offset_m, np.float64))[0]
    return Eyepoint(eye, world.heading_deg, world.pitch_deg, world.roll_deg)


@dataclass(frozen=True)
class _Arrival:
    t: float  # monotonic arrival, seconds
    wall: float  # UNIX arrival, seconds (the frame's sample time)
    eyepoint: Eyepoint


@dataclass
class SimHostStatus:
    """Counters of a pose stream (`ig status` shows them as an input source; docs/sim-hosts.md).

    Attributes:
        name: the URL the stream was opened with.
        accepted: datagrams that gave a pose.
        refused: datagrams refused, by cause (CAUSES), and stale: times the simulator went silent.
        unused: datagrams of the protocol that carry no pose (an X-Plane DATA packet without
            rows 17 and 20), counted and otherwise ignored.
        stale: no datagram for stale_after_s (the last eyepoint is held), or none yet.
        last_input_age_s: seconds since the last pose; -1 before the first.
        last_rejection: the last refusal, "cause: detail".
        late: frames whose moment lay past the newest arrival in "interpolate" timing (the
            delay was shorter than that datagram's lateness): carried forward instead.
        extrapolated: frames carried forward past the newest arrival.
        held: frames that wanted more than max_extrapolate_s past it (held at that bound).
        restarts: the simulator's clock went back by more than RESTART_S.
        requests_sent: stream requests sent to the simulator (X-Plane's RPOS).
        interval_s: the median datagram interval; delay_s: the interpolation delay in use.
        values: the last pose (lat_deg, lon_deg, alt_m, heading_deg, pitch_deg, roll_deg) and
            the protocol's extra values.
    """

    name: str
    accepted: int = 0
    refused: dict[str, int] = field(default_factory=dict)
    unused: int = 0
    stale: bool = True
    stale_events: int = 0
    last_input_age_s: float = -1.0
    last_rejection: str = ""
    late: int = 0
    extrapolated: int = 0
    held: int = 0
    restarts: int = 0
    requests_sent: int = 0
    interval_s: float = 0.0
    delay_s: float = 0.0
    values: dict[str, float] = field(default_factory=dict)

    def counters(self) -> dict[str, int]:
        """The frame and request counts, by name (InputSourceStatus.counters)."""
        return {"unused": self.unused, "late": self.late, "extrapolated": self.extrapolated, "held": self.held,
                "restarts": self.restarts, "requests_sent": self.requests_sent}


class PoseStream:
    """Poses in from a receiver thread, eyepoints out to the publisher (module doc).

    Thread-safe: `accept`, `refuse` and `ignore` are called by the receiver as datagrams arrive,
    `frame_input` by the publisher once a frame.

    Args:
        name: what the status calls the stream (its URL).
        origin: the world's (0, 0, 0): latitude, longitude (degrees), height (metres).
        eye_offset_m: the eye from the simulator's reference point, x forward, y right, z down, m.
        timing: a name of SIMHOST_TIMINGS.
        delay_s: the interpolation delay, seconds; 0 takes DEFAULT_DELAY_INTERVALS measured
            datagram intervals.
        max_extrapolate_s: the longest an eyepoint is carried past the newest arrival, seconds.
        stale_after_s: silence after which the simulator is reported stale, seconds.
        clock: monotonic clock, seconds; wall: UNIX clock, seconds (tests inject both).

    Raises:
        ValueError: an unknown timing or a negative time, named.
    """

    def __init__(self, name: str, *, origin: Origin, eye_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 timing: str = "interpolate", delay_s: float = 0.0, max_extrapolate_s: float = 0.1,
                 stale_after_s: float = 1.0, clock: Callable[[], float] = time.monotonic,
                 wall: Callable[[], float] = time.time) -> None:
        if timing not in SIMHOST_TIMINGS:
            raise ValueError(f"timing: {timing!r} is not one of {', '.join(SIMHOST_TIMINGS)}")
        for key, v in (("delay_s", delay_s), ("max_extrapolate_s", max_extrapolate_s)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{key}: {v} is not a time >= 0")
        if not (math.isfinite(stale_after_s) and stale_after_s > 0.0):
            raise ValueError(f"stale_after_s: {stale_after_s} is not a time > 0")
        self.name = name
        self.origin = origin
        self.eye_offset_m = eye_offset_m
        self.timing = timing
        self.delay_s = delay_s
        self.max_extrapolate_s = max_extrapolate_s
        self.stale_after_s = stale_after_s
        self._clock = clock
        self._wall = wall
        self._lock = threading.Condition()
        self._arrivals: deque[_Arrival] = deque(maxlen=HISTORY)
        self._poses: deque[Pose] = deque(maxlen=HISTORY)
        self._host_time: float | None = None
        self._named: set[str] = set()
        self.counters = SimHostStatus(name, stale=False)  # before the first pose: status() says stale

    # -- the receiver's side

    def accept(self, pose: Pose, *, arrival: float | None = None) -> bool:
        """Take one decoded pose that arrived at `arrival` (monotonic seconds; None: now).

        Returns:
            True if it was used; False if it was refused (counted: its values cannot be placed,
            or its simulator time went back by less than RESTART_S).
        """
        t = self._clock() if arrival is None else arrival
        wall = self._wall() - (self._clock() - t)
        try:
            pose.check()
        except Malformed as exc:
            self.refuse(exc.cause, exc.detail)
            return False
        eyepoint = eyepoint_of_pose(pose, origin=self.origin, eye_offset_m=self.eye_offset_m)
        with self._lock:
            if pose.host_time_s is not None and self._host_time is not None and pose.host_time_s < self._host_time:
                if self._host_time - pose.host_time_s <= RESTART_S:
                    self._refuse_locked("out_of_order", f"simulator time {pose.host_time_s:.3f} s after "
                                                        f"{self._host_time:.3f} s")
                    return False
                # The simulator started again: what came before is no guide to what comes next.
                self.counters.restarts += 1
                log.info("%s: simulator time went back from %.3f to %.3f s: restarted", self.name,
                         self._host_time, pose.host_time_s)
                self._arrivals.clear()
            if pose.host_time_s is not None:
                self._host_time = pose.host_time_s
            if self._arrivals and t < self._arrivals[-1].t:
                t = self._arrivals[-1].t  # a clock read on another thread a hair earlier
            self._arrivals.append(_Arrival(t, wall, eyepoint))
            self._poses.append(pose)
            self.counters.accepted += 1
            self._lock.notify_all()
        return True

    def refuse(self, cause: str, detail: str) -> None:
        """Count a datagram refused for cause (one of CAUSES); the first of each cause is logged."""
        with self._lock:
            self._refuse_locked(cause, detail)

    def ignore(self) -> None:
        """Count a datagram of the protocol that carries no pose."""
        with self._lock:
            self.counters.unused += 1

    def count_request(self) -> None:
        """Count a stream request sent to the simulator."""
        with self._lock:
            self.counters.requests_sent += 1

    def _refuse_locked(self, cause: str, detail: str) -> None:
        self.counters.refused[cause] = self.counters.refused.get(cause, 0) + 1
        self.counters.last_rejection = f"{cause}: {detail}"
        if cause not in self._named:
            self._named.add(cause)
            log.warning("%s: datagram refused, %s: %s (counted; further ones are not logged)", self.name, cause,
                        detail)

    # -- the publisher's side

    def frame_input(self, sim_time_s: float = 0.0) -> FrameInput:
        """The publisher's source: the eyepoint for a frame drawn now (sim_time_s is not used:
        the simulator is the clock). Before the first pose: nothing to publish."""
        eyepoint, sample_time = self.eyepoint_now()
        return FrameInput(eyepoint, sample_time=sample_time)

    def eyepoint_now(self) -> tuple[Eyepoint | None, float | None]:
        """(the eyepoint for now, the UNIX arrival time of the newest datagram it used); (None,
        None) before the first pose."""
        now = self._clock()
        with self._lock:
            if not self._arrivals:
                return None, None
            newest = self._arrivals[-1]
            self._check_stale(now, newest)
            if self.counters.stale:
                return newest.eyepoint, newest.wall
            if self.timing == "extrapolate":
                return self._forward(now), newest.wall
            target = now - self._delay()
            if target >= newest.t:
                self.counters.late += 1
                return self._forward(target), newest.wall
            arrivals = self._arrivals
            if target <= arrivals[0].t:
                return arrivals[0].eyepoint, arrivals[0].wall
            # The first arrival after target (few steps back from the newest: target is a delay
            # of about 1.5 intervals behind it).
            i = len(arrivals) - 1
            while arrivals[i - 1].t > target:
                i -= 1
            a, b = arrivals[i - 1], arrivals[i]
            return blend(a.eyepoint, b.eyepoint, (target - a.t) / (b.t - a.t)), b.wall

    def _delay(self) -> float:
        if self.delay_s > 0.0:
            return self.delay_s
        return DEFAULT_DELAY_INTERVALS * self._interval()

    def _interval(self) -> float:
        times = [a.t for a in list(self._arrivals)[-INTERVAL_WINDOW - 1:]]
        if len(times) < 2:
            return 0.0
        return statistics.median(b - a for a, b in itertools.pairwise(times))

    def _forward(self, target: float) -> Eyepoint:
        """The newest eyepoint carried forward to target along the motion of the last two
        arrivals at least half an interval apart (two datagrams that arrived together say nothing
        about the speed), at most max_extrapolate_s."""
        b = self._arrivals[-1]
        ahead = target - b.t
        if ahead <= 0.0:
            return b.eyepoint
        self.counters.extrapolated += 1
        if ahead > self.max_extrapolate_s:
            self.counters.held += 1
            ahead = self.max_extrapolate_s
        gap = 0.5 * self._interval()
        for a in reversed(list(self._arrivals)[:-1]):
            if b.t - a.t > max(gap, 1e-6):
                return blend(a.eyepoint, b.eyepoint, 1.0 + ahead / (b.t - a.t))
        return b.eyepoint

    def _check_stale(self, now: float, newest: _Arrival) -> None:
        stale = now - newest.t > self.stale_after_s
        if stale and not self.counters.stale:
            self.counters.stale_events += 1
            log.warning("%s: simulator stale: nothing for %.2f s; holding the last eyepoint", self.name,
                        now - newest.t)
        elif not stale and self.counters.stale and self.counters.stale_events:
            log.info("%s: simulator back after being stale", self.name)
        self.counters.stale = stale

    # -- for status and tests

    def status(self) -> SimHostStatus:
        """A snapshot of the counters, staleness as of now."""
        now = self._clock()
        with self._lock:
            c = self.counters
            if self._arrivals:
                self._check_stale(now, self._arrivals[-1])
            refused = dict(c.refused)
            if c.stale_events:
                refused["stale"] = c.stale_events
            values: dict[str, float] = {}
            if self._poses:
                p = self._poses[-1]
                values = {"lat_deg": p.lat_deg, "lon_deg": p.lon_deg, "alt_m": p.alt_m, "heading_deg": p.heading_deg,
                          "pitch_deg": p.pitch_deg, "roll_deg": p.roll_deg, **dict(p.extra)}
            interval = self._interval()
            return SimHostStatus(
                name=c.name, accepted=c.accepted, refused=refused, unused=c.unused, stale=c.stale or not self._arrivals,
                stale_events=c.stale_events,
                last_input_age_s=now - self._arrivals[-1].t if self._arrivals else -1.0,
                last_rejection=c.last_rejection, late=c.late, extrapolated=c.extrapolated, held=c.held,
                restarts=c.restarts, requests_sent=c.requests_sent, interval_s=interval,
                delay_s=self._delay() if self.timing == "interpolate" else 0.0, values=values)

    def latest_pose(self) -> Pose | None:
        """The newest pose accepted, as decoded (None before the first)."""
        with self._lock:
            return self._poses[-1] if self._poses else None

    def poses(self, timeout_s: float) -> Iterator[Pose]:
        """Every pose accepted from this call on, as it arrives, until none has come for
        timeout_s (for tests that drive a simulator into the receiver)."""
        with self._lock:
            seen = self.counters.accepted  # now, not at the first next(): nothing is missed
        return self._poses_after(seen, timeout_s)

    def _poses_after(self, seen: int, timeout_s: float) -> Iterator[Pose]:
        while True:
            with self._lock:
                if not self._lock.wait_for(partial(self._accepted_past, seen), timeout_s):
                    return
                fresh = min(self.counters.accepted - seen, len(self._poses))
                batch = list(self._poses)[len(self._poses) - fresh:]
                seen = self.counters.accepted
            yield from batch

    def _accepted_past(self, count: int) -> bool:
        return self.counters.accepted > count

    def wait_for(self, count: int, timeout_s: float) -> bool:
        """Whether `count` poses in all have been accepted within timeout_s."""
        with self._lock:
            return self._lock.wait_for(lambda: self.counters.accepted >= count, timeout_s)


def blend(a: Eyepoint, b: Eyepoint, f: float) -> Eyepoint:
    """The eyepoint a fraction f of the way from a to b (f > 1 carries on past b): positions
    linearly, heading and roll along the shorter arc, pitch linearly.

    Euler angles rather than a quaternion slerp: between two datagrams 8-50 ms apart the
    attitude turns by a few degrees at most, where the two agree to well under a pixel, except
    within a few degrees of pitch +-90, where heading and roll are ill-defined.
    """
    position = a.position + (b.position - a.position) * f
    heading = (a.heading_deg + f * _arc(a.heading_deg, b.heading_deg)) % 360.0
    roll = a.roll_deg + f * _arc(a.roll_deg, b.roll_deg)
    roll = (roll + 180.0) % 360.0 - 180.0
    pitch = max(-90.0, min(90.0, a.pitch_deg + f * (b.pitch_deg - a.pitch_deg)))
    return Eyepoint(position, heading, pitch, roll)


def _arc(a_deg: float, b_deg: float) -> float:
    """b - a along the shorter way round, degrees in [-180, 180)."""
    return (b_deg - a_deg + 180.0) % 360.0 - 180.0
