"""Frame publication with the synchronous frame lock (docs/frame-lock.md), without a network.

The host publishes frame n, then waits until every channel of the rig has acknowledged n (or the
sync timeout passes) before it publishes n + 1, paced one of two ways (PACES):

- ticks: n + 1 goes at the next tick of a fixed rate, with simulation time tick / rate.
  Rendering slower than the rate slows the simulation down, as CIGI's synchronous mode does;
  replays and tests get the same simulation times on every run.
- acks: n + 1 goes as soon as the acknowledgements are in (never faster than the rate, which
  is then a cap), with simulation time taken from the wall clock: the flight flies in real time
  at whatever rate the rig renders, and an input waits at most for the frame in flight instead
  of that frame and then a tick.

Either way the controls are sampled (the source called) immediately before the frame is
built and published, and the frame's control sample time is that moment.
"""

from __future__ import annotations

import logging
import math
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ig.v1 import frame_pb2
from services.rig.environment import Environment, environment_to_proto
from services.rig.frame import Eyepoint, check_eyepoint
from services.rig.grpc_util import clip
from services.rig.mailbox import Mailbox
from services.rig.rigfile import PACES
from services.rig.wire import eyepoint_to_proto

log = logging.getLogger("ig.host")

#: Frames a subscriber may have waiting before the oldest is dropped (counted). In synchronous
#: mode a channel never has more than one; the bound protects the host from a stalled observer.
QUEUE_DEPTH = 8

#: Longest a wait of the publisher goes without looking at the stop event, seconds: SIGTERM
#: must not wait out a start or sync timeout.
_STOP_POLL_S = 0.1

#: How often the missing channels' workers are asked for their health before the first frame,
#: and how often the wait is logged, seconds.
_HEALTH_POLL_S = 0.5
_START_LOG_S = 10.0

#: How a run ended (FramePublisher.end_reason): it published its last frame, or the stop event
#: (SIGTERM) ended it first.
COMPLETED = "completed"
STOPPED = "stopped"


class UnknownChannel(ValueError):
    """A subscription or acknowledgement named a channel that is not in the rig."""


class ChannelTaken(ValueError):
    """A second subscriber asked for a channel that already has one (two workers for one window)."""


class RunOver(ValueError):
    """A subscription after the run has ended: the host publishes nothing more and exits after
    its linger."""


class FrameOutOfRange(ValueError):
    """An acknowledgement of a frame number this run has not published."""


class OtherRun(ValueError):
    """An acknowledgement that names another run than the host's."""


@dataclass(frozen=True)
class FrameInput:
    """What an external host gives a frame beyond the eyepoint (a source may return this
    instead of a bare Eyepoint).

    Attributes:
        eyepoint: the frame's eyepoint; None publishes nothing this tick (no host yet, or the
            host keeps the IG in reset): the channels hold their last picture.
        host_frame_number: the external host's frame number the eyepoint came from.
        environment: weather, visibility and sun set by the host (None: the scene's).
        views: per channel, the view the host set (ig.v1.ChannelView messages).
        new_run: the host started again (its frame counter went back): this frame starts a
            new run, numbered from 0, so nothing of the previous run is overwritten.
        sample_time: UNIX seconds when the host's data arrived (the frame's control sample
            time, where latency is counted from); None: now.
    """

    eyepoint: Eyepoint | None
    host_frame_number: int | None = None
    environment: Environment | None = None
    views: tuple[frame_pb2.ChannelView, ...] = ()
    new_run: bool = False
    sample_time: float | None = None


class Subscription(Mailbox[frame_pb2.Frame]):
    """One subscriber's frame queue: bounded (QUEUE_DEPTH), drop-oldest, closed at the end of
    the run."""

    def __init__(self, subscriber: str, channel_name: str) -> None:
        super().__init__(QUEUE_DEPTH)
        self.subscriber = subscriber
        self.channel_name = channel_name


@dataclass
class HostStatus:
    """Counters of the publisher (mirrors GetHostStatusResponse)."""

    run_id: str
    frames_published: int = 0
    eyepoints_rejected: int = 0
    subscriptions_rejected: int = 0
    ack_timeouts: dict[str, int] = field(default_factory=dict)
    ack_failures: dict[str, int] = field(default_factory=dict)
    queue_drops: dict[str, int] = field(default_factory=dict)
    subscribers: list[str] = field(default_factory=list)
    finished: bool = False
    last_error: str = ""
    channel_absent: dict[str, int] = field(default_factory=dict)
    requests_refused: dict[str, int] = field(default_factory=dict)
    late_acks: dict[str, int] = field(default_factory=dict)
    runs: int = 1
    idle_ticks: int = 0


class FramePublisher:
    """Publishes frames of an eyepoint source, frame-locked to the channels, paced by ticks or
    by the channels' acknowledgements (module doc).

    With pace "ticks", tick k of the run has simulation time k / rate_hz seconds. With pace
    "acks", a frame's simulation time is the time since the first frame on the monotonic clock,
    read just before the frame is sampled, and the frame due at or past duration_s is the last,
    with simulation time duration_s. Frame numbers count published frames, so they equal the
    tick unless an eyepoint was refused: a refused tick publishes nothing and leaves no gap, so
    that a gap seen by a worker always means a skipped frame.

    Args:
        source: eyepoint at a simulation time in seconds, or a FrameInput (an external host's
            frame: its frame number, environment and views, a new run, or nothing to publish).
        channels: names of the rig's channels; each must acknowledge every frame.
        rate_hz: publication rate, Hz (pace "ticks"), or the most frames a second (pace "acks").
        duration_s: simulated seconds to run.
        sync_timeout_s: longest wait for the acknowledgements of one frame, seconds.
        observers: observers (e.g. the compositor) to wait for before the first frame.
        start_timeout_s: longest wait for all channels and observers to subscribe, seconds;
            with starting, counted for each missing channel from the last time its worker
            said it was still starting, so a worker compiling its kernels is waited for as
            long as it takes, and a silent one, or one that serves but never subscribes
            (e.g. pointed at another host), is given up on.
        starting: whether the worker of a channel says now that it is still starting (its
            health NOT_SERVING); None: the start timeout alone decides.
        clock: wall clock, UNIX seconds (time stamps in the frames).
        run_id: identity of the run; a random one by default.
        pace: "ticks" or "acks" (PACES).
        monotonic: the clock of the pace (ticks, the cap) and of pace "acks"' simulation time,
            seconds.
    """

    def __init__(self, *, source: Callable[[float], Eyepoint | FrameInput], channels: Sequence[str],
                 rate_hz: float = 60.0, duration_s: float = 20.0, sync_timeout_s: float = 10.0,
                 observers: int = 0, start_timeout_s: float = 120.0,
                 clock: Callable[[], float] = time.time, run_id: str | None = None,
                 starting: Callable[[str], bool] | None = None, pace: str = "ticks",
                 monotonic: Callable[[], float] = time.monotonic) -> None:
        if pace not in PACES:
            raise ValueError(f"pace: {pace!r} is not one of {', '.join(PACES)}")
        # `not x > 0` rather than `x <= 0` so that NaN is refused too.
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise ValueError(f"rate_hz: {rate_hz} must be a finite number > 0")
        if not (duration_s >= 0 and math.isfinite(duration_s)):
            raise ValueError(f"duration_s: {duration_s} must be a finite number >= 0")
        if not sync_timeout_s > 0:
            raise ValueError(f"sync_timeout_s: {sync_timeout_s} must be > 0")
        if not start_timeout_s >= 0:
            raise ValueError(f"start_timeout_s: {start_timeout_s} must be >= 0")
        if observers < 0:
            raise ValueError(f"observers: {observers} must be >= 0")
        self.source = source
        self.channels = tuple(channels)
        self.rate_hz = float(rate_hz)
        self.duration_s = float(duration_s)
        self.sync_timeout_s = sync_timeout_s
        self.observers = observers
        self.start_timeout_s = start_timeout_s
        self.clock = clock
        self.pace = pace
        self.monotonic = monotonic
        self.starting = starting
        self.status = HostStatus(run_id=run_id or uuid.uuid4().hex[:12])
        self.status.ack_timeouts = dict.fromkeys(self.channels, 0)
        self.status.ack_failures = dict.fromkeys(self.channels, 0)
        self.status.channel_absent = dict.fromkeys(self.channels, 0)
        self.status.late_acks = dict.fromkeys(self.channels, 0)
        self._subs: list[Subscription] = []
        self._acks: dict[str, int] = {}
        #: Runs this publisher has ended (an external host restarted): their late
        #: acknowledgements are counted late, not refused.
        self._ended_runs: set[str] = set()
        #: Number of the last frame published (-1 before the first) and of the frame the swap
        #: barrier waits for.
        self._published = -1
        #: How the run ended (COMPLETED or STOPPED), "" while it runs.
        self.end_reason = ""
        self._lock = threading.Condition()

    @property
    def tick_count(self) -> int:
        """Ticks in the run with pace "ticks": one per 1 / rate_hz of simulated time, both ends
        included."""
        return int(round(self.duration_s * self.rate_hz)) + 1

    def subscribe(self, subscriber: str, channel_name: str) -> Subscription:
        """Register a subscriber; channel_name "" makes it an observer.

        Raises:
            UnknownChannel: channel_name is neither "" nor a rig channel.
            RunOver: the run has ended (counted in requests_refused as run_ended).
            ChannelTaken: channel_name already has an open subscription.
        """
        if channel_name and channel_name not in self.channels:
            message = f"channel_name: {channel_name!r} is not a channel of the rig ({', '.join(self.channels)})"
            with self._lock:
                self.status.subscriptions_rejected += 1
                self.status.last_error = message
            raise UnknownChannel(message)
        sub = Subscription(subscriber, channel_name)
        with self._lock:
            if self.status.finished:
                # A stream opened now would end at once, and its subscriber, taking that for the
                # end of a run, would come straight back: refused instead, with a status that says
                # why (services/rig/resubscribe.py). Counted; last_error keeps the last real problem.
                refused = self.status.requests_refused
                refused["run_ended"] = refused.get("run_ended", 0) + 1
                raise RunOver(f"run_id {self.status.run_id!r} has ended ({self.status.frames_published} frames "
                              f"published): this host takes no new subscription and exits shortly; "
                              f"subscribe to the next run")
            taken = [s for s in self._subs if channel_name and s.channel_name == channel_name]
            if taken:
                message = f"channel_name: {channel_name!r} already has a subscriber ({taken[0].subscriber})"
                self.status.subscriptions_rejected += 1
                self.status.last_error = message
                raise ChannelTaken(message)
            self._subs.append(sub)
            self._lock.notify_all()
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        """Forget a subscriber whose stream ended; the host stops waiting for its channel."""
        with self._lock:
            if sub in self._subs:
                self._subs.remove(sub)
                self.status.queue_drops[sub.subscriber] = sub.dropped
                self._lock.notify_all()

    def wait_streams_ended(self, timeout_s: float) -> bool:
        """Wait until no subscription is open (each stream has delivered the end of the run and
        ended), at most timeout_s seconds; whether none is."""
        with self._lock:
            return self._lock.wait_for(lambda: not self._subs, timeout=timeout_s)

    def refuse(self, cause: str, message: str) -> None:
        """Count a refused request (GetHostStatus.requests_refused) and keep its message."""
        with self._lock:
            self.status.requests_refused[cause] = self.status.requests_refused.get(cause, 0) + 1
            self.status.last_error = clip(message)

    def ack(self, channel_name: str, frame_number: int, *, ok: bool = True, error: str = "",
            run_id: str = "") -> None:
        """A channel reports it has handled frame_number (of run_id, when given).

        Only a frame this run has published can be acknowledged: an acknowledgement of a later
        one would release the swap barrier for frames the channel has never seen.

        Raises:
            UnknownChannel: channel_name is not a rig channel.
            OtherRun: run_id is given and is not this run's.
            FrameOutOfRange: frame_number has not been published.
            Each is counted in requests_refused before it is raised.
        """
        if channel_name not in self.channels:
            message = (f"channel_name: {clip(channel_name, 64)!r} is not a channel of the rig "
                       f"({', '.join(self.channels)})")
            self.refuse("unknown_channel", message)
            raise UnknownChannel(message)
        with self._lock:
            published = self._published
        if run_id and run_id in self._ended_runs:
            with self._lock:
                self.status.late_acks[channel_name] += 1
            return
        if run_id and run_id != self.status.run_id:
            message = f"run_id: {clip(run_id, 64)!r} is not the host's run {self.status.run_id!r}"
            self.refuse("other_run", message)
            raise OtherRun(message)
        if frame_number > published:
            message = (f"frame_number: {frame_number} has not been published (the last is "
                       f"{published if published >= 0 else 'none yet'})")
            self.refuse("out_of_range", f"{channel_name}: {message}")
            raise FrameOutOfRange(message)
        with self._lock:
            if not ok:
                self.status.ack_failures[channel_name] += 1
                self.status.last_error = clip(f"{channel_name}: frame {frame_number}: {error}")
                log.warning("channel %s failed frame %d: %s", channel_name, frame_number, clip(error))
            if frame_number < self._published:
                # The barrier has moved on without this channel: the frame is shown late, if at all.
                self.status.late_acks[channel_name] += 1
            self._acks[channel_name] = max(self._acks.get(channel_name, -1), frame_number)
            self._lock.notify_all()

    def snapshot(self) -> HostStatus:
        """A copy of the counters."""
        with self._lock:
            s = self.status
            drops = dict(s.queue_drops)
            drops.update({sub.subscriber: sub.dropped for sub in self._subs})
            return HostStatus(s.run_id, s.frames_published, s.eyepoints_rejected, s.subscriptions_rejected,
                              dict(s.ack_timeouts), dict(s.ack_failures), drops,
                              [sub.subscriber for sub in self._subs], s.finished, s.last_error,
                              dict(s.channel_absent), dict(s.requests_refused), dict(s.late_acks),
                              s.runs, s.idle_ticks)

    def run(self, stop: threading.Event) -> None:
        """Publish the whole run (blocking), then close every subscription.

        Returns early, still closing the subscriptions, when stop is set.
        """
        try:
            self._wait_for_subscribers(stop)
            if self.pace == "ticks":
                self._run_ticks(stop)
            else:
                self._run_acks(stop)
        finally:
            with self._lock:
                self.status.finished = True
                self.end_reason = STOPPED if stop.is_set() else COMPLETED
                subs = list(self._subs)
            for sub in subs:
                sub.close()

    def _run_ticks(self, stop: threading.Event) -> None:
        log.info("pace ticks: a frame every 1 / %g s of simulated time, each at its tick", self.rate_hz)
        period = 1.0 / self.rate_hz
        next_tick = self.monotonic()
        number = 0
        for tick in range(self.tick_count):
            # Never faster than the rate. When the channels took longer than a period the
            # frame goes at once and the schedule restarts from now: the host never bursts
            # frames to catch up with the wall clock (the simulation runs slow instead).
            if not self._sleep_until(next_tick, stop):
                return
            next_tick = max(next_tick, self.monotonic()) + period
            number = self._frame(number, tick / self.rate_hz, stop)

    def _run_acks(self, stop: threading.Event) -> None:
        # The acknowledgements of the previous frame are in when _frame returns: the next one
        # goes now, unless that would be faster than the cap.
        log.info("pace acks: each frame as soon as the last one is acknowledged, at most %g a second; "
                 "simulation time in real time", self.rate_hz)
        period = 1.0 / self.rate_hz
        due = self.monotonic()
        start = None
        number = 0
        while self._sleep_until(due, stop):
            now = self.monotonic()
            start = now if start is None else start
            last = now - start >= self.duration_s
            due = now + period
            number = self._frame(number, self.duration_s if last else now - start, stop)
            if last:
                return

    def _sleep_until(self, due: float, stop: threading.Event) -> bool:
        """Wait until the monotonic clock reaches due; False if stop was set meanwhile."""
        while (delay := due - self.monotonic()) > 0:
            if stop.wait(delay):
                return False
        return not stop.is_set()

    def _frame(self, number: int, sim_time: float, stop: threading.Event) -> int:
        """Sample the source at sim_time, publish its frame as number and wait for the
        acknowledgements; the number of the next frame.

        The wall clock is read right before the source, which polls the controls: that is the
        frame's control sample time (unless the source says when its data arrived), and nothing
        but the source runs between it and the publication.
        """
        sample_time = self.clock()
        given = self.source(sim_time)
        extras = given if isinstance(given, FrameInput) else FrameInput(given)
        if extras.new_run and number > 0:
            self._new_run()
            number = 0
        eyepoint = extras.eyepoint
        if extras.sample_time is not None:
            sample_time = extras.sample_time
        if eyepoint is None:
            with self._lock:
                self.status.idle_ticks += 1
            return number
        try:
            check_eyepoint(eyepoint)
        except ValueError as exc:
            with self._lock:
                self.status.eyepoints_rejected += 1
                self.status.last_error = f"t={sim_time:.3f}s: {exc}"
            log.error("eyepoint refused at t=%.3f s: %s", sim_time, exc)
            return number
        frame = self._publish(number, sim_time, sample_time, eyepoint, extras)
        self._wait_for_acks(number, frame.channels, stop)
        return number + 1

    def _new_run(self) -> None:
        """Start a new run: a new id, frame numbers from 0, the barrier forgotten."""
        with self._lock:
            self._ended_runs.add(self.status.run_id)
            self.status.run_id = uuid.uuid4().hex[:12]
            self.status.runs += 1
            self._published = -1
            self._acks = {}
        log.info("new run %s: the external host started again", self.status.run_id)

    def _publish(self, number: int, sim_time: float, sample_time: float, eyepoint: Eyepoint,
                 extras: FrameInput | None = None) -> frame_pb2.Frame:
        """Send frame number to every subscriber; the frame lists the channels subscribed at that
        moment, the ones that receive it (one snapshot under the lock, so the list and the
        receivers agree)."""
        with self._lock:
            subs = list(self._subs)
            present = {s.channel_name for s in subs if s.channel_name}
            frame = make_frame(number, sim_time, sample_time, eyepoint, self.status.run_id, self.clock(),
                               channels=[c for c in self.channels if c in present])
            if extras is not None:
                if extras.host_frame_number is not None:
                    frame.host_frame_number = extras.host_frame_number
                if extras.environment is not None:
                    frame.environment.CopyFrom(environment_to_proto(extras.environment))
                frame.views.extend(extras.views)
            self.status.frames_published += 1
            self._published = number
        for sub in subs:
            sub.put(frame)
        return frame

    def _wait(self, predicate: Callable[[], bool], timeout_s: float, stop: threading.Event) -> bool:
        """Wait (lock held) until predicate() holds, stop is set or timeout_s passes.

        Returns predicate() at the end, so a stop is not mistaken for success.
        """
        deadline = time.monotonic() + timeout_s
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0 or stop.is_set():
                return False
            self._lock.wait(min(remaining, _STOP_POLL_S))
        return True

    def _subscribed_channels(self) -> set[str]:
        return {s.channel_name for s in self._subs if s.channel_name}

    def _wait_for_subscribers(self, stop: threading.Event) -> None:
        started = time.monotonic()
        heard = dict.fromkeys(self.channels, started)
        said = started
        while not stop.is_set():
            with self._lock:
                missing = [c for c in self.channels if c not in self._subscribed_channels()]
                observers = sum(1 for s in self._subs if not s.channel_name)
            if not missing and observers >= self.observers:
                return
            # The health probes go over the network: never with the lock held, so that
            # subscriptions are not kept waiting.
            now = time.monotonic()
            if self.starting is not None:
                for c in missing:
                    if self.starting(c):
                        heard[c] = now
            if missing:
                gone = all(now - heard[c] > self.start_timeout_s for c in missing)
            else:
                gone = now - started > self.start_timeout_s
            if gone:
                log.warning("starting without channels %s (not subscribed, not starting, for %.0f s), "
                            "with %d of %d observers",
                            missing, self.start_timeout_s, observers, self.observers)
                return
            if now - said >= _START_LOG_S:
                said = now
                log.info("waiting for channels %s (their workers are still starting) and %d of %d "
                         "observers", missing, observers, self.observers)
            with self._lock:
                self._lock.wait(_STOP_POLL_S if self.starting is None else _HEALTH_POLL_S)

    def _wait_for_acks(self, number: int, sent_to: Sequence[str], stop: threading.Event) -> None:
        # Only channels that received the frame and still have an open subscription can
        # acknowledge it: waiting for a worker that is down, or that subscribed after the frame
        # went out (it never got it), would stall the frame by the whole sync timeout.
        # Re-evaluated on every wake-up, so a worker that dies during the wait is dropped from it.
        def waiting_for() -> list[str]:
            present = self._subscribed_channels()
            return [c for c in sent_to if c in present and self._acks.get(c, -1) < number]

        with self._lock:
            absent = [c for c in self.channels if c not in sent_to]
            if not self._wait(lambda: not waiting_for(), self.sync_timeout_s, stop) and not stop.is_set():
                for c in waiting_for():
                    self.status.ack_timeouts[c] += 1
                    log.warning("channel %s did not acknowledge frame %d within %.1f s",
                                c, number, self.sync_timeout_s)
            absent += [c for c in self.channels if c not in self._subscribed_channels() and c not in absent]
            for c in absent:
                if self._acks.get(c, -1) < number:
                    self.status.channel_absent[c] += 1
                    log.warning("channel %s is not subscribed; frame %d goes on without it", c, number)


def make_frame(number: int, sim_time: float, sample_time: float, eyepoint: Eyepoint, run_id: str,
               publish_time: float, *, channels: Sequence[str] = ()) -> frame_pb2.Frame:
    """The Frame message of one eyepoint; channels: those the host waits for on it."""
    return frame_pb2.Frame(
        frame_number=number, sim_time_s=sim_time, publish_time_unix_s=publish_time,
        control_sample_time_unix_s=sample_time, run_id=run_id, eyepoint=eyepoint_to_proto(eyepoint),
        channels=list(channels))
