"""How the host paces its frames: a fixed rate (ticks) or the rig's acknowledgements (acks).

The clocks are injected: a fake monotonic clock that the test (or the publisher's own waits)
moves on, and a wall clock that records when it is read, so that the order of the
acknowledgements, the control sample and the publication is checked without any wall-clock
figure.
"""

from __future__ import annotations

import itertools
import threading

import pytest

from host_sim.publisher import PACES, FramePublisher
from services.rig.frame import Eyepoint


class FakeMonotonic:
    """A monotonic clock that only moves when told to."""

    def __init__(self) -> None:
        self.t = 1000.0
        self.lock = threading.Lock()

    def __call__(self) -> float:
        with self.lock:
            return self.t

    def advance(self, dt: float) -> None:
        with self.lock:
            self.t += dt


class ClockStop(threading.Event):
    """A stop event whose timed waits move the fake clock on instead of sleeping, and are recorded
    (the publisher waits on its stop event only to pace its frames)."""

    def __init__(self, clock: FakeMonotonic) -> None:
        super().__init__()
        self.clock = clock
        self.waits: list[float] = []

    def wait(self, timeout: float | None = None) -> bool:
        if timeout is None or self.is_set():
            return super().wait(timeout)
        self.waits.append(timeout)
        self.clock.advance(timeout)
        return False


class Log:
    """What happened, in order, from every thread."""

    def __init__(self) -> None:
        self.events: list[tuple] = []
        self.lock = threading.Lock()
        self.wall = 0.0

    def add(self, *event) -> None:
        with self.lock:
            self.events.append(event)

    def clock(self) -> float:
        """The wall clock: each read returns a new time and is logged."""
        with self.lock:
            self.wall += 1.0
            self.events.append(("clock", self.wall))
            return self.wall


def run_rig(pub, stop, channels, *, on_frame=None):
    """Run pub with fake channels that acknowledge each frame at once (after on_frame(channel,
    frame), if given); the frames an observer saw."""
    subs = {c: pub.subscribe(f"w-{c}", c) for c in channels}
    observer = pub.subscribe("obs", "")
    seen = []

    def channel(c):
        sub = subs[c]
        while (f := sub.get(0.05)) is not None or not sub.closed:
            if f is not None:
                if on_frame:
                    on_frame(c, f)
                pub.ack(c, f.frame_number)

    def watch():
        while (f := observer.get(0.05)) is not None or not observer.closed:
            if f is not None:
                seen.append(f)

    threads = [threading.Thread(target=channel, args=(c,)) for c in channels] + [threading.Thread(target=watch)]
    for t in threads:
        t.start()
    pub.run(stop)
    for t in threads:
        t.join()
    return seen


def eyepoint(t):
    return Eyepoint.of(t, 0.0, 10.0, 0.0, 0.0, 0.0)


def test_the_acks_pace_publishes_as_soon_as_every_channel_acknowledged():
    mono = FakeMonotonic()
    stop = ClockStop(mono)
    acked: dict[str, list[int]] = {"a": [], "b": []}
    sampled_after: list[dict[str, int]] = []

    def source(t):
        sampled_after.append({c: max(n, default=-1) for c, n in acked.items()})
        return eyepoint(t)

    def on_frame(c, f):
        # Channel b takes a quarter of a second (of the fake clock) to render; a acks at once.
        if c == "b":
            mono.advance(0.25)
        acked[c].append(f.frame_number)

    pub = FramePublisher(source=source, channels=["a", "b"], pace="acks", rate_hz=60.0, duration_s=2.0,
                         observers=1, monotonic=mono)
    seen = run_rig(pub, stop, ["a", "b"], on_frame=on_frame)
    # Frame n was sampled only once both channels had acknowledged n - 1 ...
    assert sampled_after == [{"a": n - 1, "b": n - 1} for n in range(len(seen))]
    # ... and then at once: the cap (60 Hz) was long past, so the host never waited for a tick.
    assert stop.waits == []
    # Simulation time is the clock's time since the first frame: the flight flies in real time at
    # whatever rate the rig renders; the last frame is the run's end.
    assert [f.sim_time_s for f in seen] == pytest.approx([0.25 * k for k in range(9)])
    assert seen[-1].sim_time_s == 2.0
    assert [f.frame_number for f in seen] == list(range(9))


def test_the_acks_pace_never_goes_faster_than_its_cap():
    mono = FakeMonotonic()
    stop = ClockStop(mono)
    sample_times: list[float] = []

    def source(t):
        sample_times.append(mono())
        return eyepoint(t)

    # The channels acknowledge at once (no time passes): only the cap holds the host back.
    pub = FramePublisher(source=source, channels=["a"], pace="acks", rate_hz=10.0, duration_s=0.95,
                         observers=1, monotonic=mono)
    seen = run_rig(pub, stop, ["a"])
    gaps = [b - a for a, b in itertools.pairwise(sample_times)]
    assert len(gaps) == 10 and all(g >= 0.1 - 1e-9 for g in gaps)
    assert all(w > 0 for w in stop.waits) and len(stop.waits) == len(gaps)
    # The frame due past the end shows the end.
    assert seen[-1].sim_time_s == 0.95
    assert [f.sim_time_s for f in seen[:-1]] == pytest.approx([0.1 * k for k in range(10)])


@pytest.mark.parametrize("pace", PACES)
def test_the_controls_are_sampled_after_the_acknowledgements_and_just_before_publishing(pace):
    log = Log()
    mono = FakeMonotonic()
    stop = ClockStop(mono)

    def source(t):
        log.add("source", t)
        return eyepoint(t)

    def on_frame(c, f):
        mono.advance(0.05)
        log.add("ack", f.frame_number)

    pub = FramePublisher(source=source, channels=["a"], pace=pace, rate_hz=10.0, duration_s=0.5, observers=1,
                         clock=log.clock, monotonic=mono)
    seen = run_rig(pub, stop, ["a"], on_frame=on_frame)
    events = log.events
    sources = [i for i, e in enumerate(events) if e[0] == "source"]
    assert len(sources) == len(seen) > 2
    for n, (i, frame) in enumerate(zip(sources, seen, strict=True)):
        # The wall clock read right before the source is the frame's control sample time, the
        # one right after it the publication: nothing runs between them but the source.
        assert events[i - 1] == ("clock", frame.control_sample_time_unix_s)
        assert events[i + 1] == ("clock", frame.publish_time_unix_s)
        if n:
            # The previous frame's acknowledgement came before the sample.
            assert ("ack", n - 1) in events[:i - 1]
            assert ("ack", n) not in events[:i]


def test_the_ticks_pace_keeps_its_fixed_simulation_times_and_waits_for_the_tick():
    mono = FakeMonotonic()
    stop = ClockStop(mono)

    def on_frame(c, f):
        mono.advance(0.03)  # a channel faster than the rate

    pub = FramePublisher(source=eyepoint, channels=["a"], rate_hz=10.0, duration_s=0.5, observers=1,
                         monotonic=mono)
    assert pub.pace == "ticks"
    seen = run_rig(pub, stop, ["a"], on_frame=on_frame)
    assert [f.sim_time_s for f in seen] == [k / 10.0 for k in range(pub.tick_count)]
    # After each acknowledgement the host waited out the rest of its period.
    assert stop.waits == pytest.approx([0.07] * (pub.tick_count - 1))


def test_stop_ends_the_wait_for_the_cap():
    stop = threading.Event()
    published = []

    def source(t):
        published.append(t)
        stop.set()  # stopped while the frame is out: the wait for the cap must not publish again
        return eyepoint(t)

    pub = FramePublisher(source=source, channels=["a"], pace="acks", rate_hz=0.001, duration_s=10.0,
                         observers=0, start_timeout_s=0.0)
    pub.run(stop)
    assert published == [0.0]
    assert pub.snapshot().finished


def test_an_unknown_pace_is_named():
    with pytest.raises(ValueError, match=r"pace: 'fast' is not one of ticks, acks"):
        FramePublisher(source=eyepoint, channels=["a"], pace="fast")
