"""Frame publication and the synchronous frame lock, without a network."""

import threading
import time

import pytest

from host_sim.publisher import COMPLETED, STOPPED, ChannelTaken, FramePublisher, RunOver, UnknownChannel
from services.rig.frame import Eyepoint


def source(t):
    return Eyepoint.of(t, 2 * t, 10.0, (350 + 10 * t) % 360, 0.0, 0.0)


def drain(sub, ack=None):
    """Every frame of a subscription until it closes; with ack=(publisher, channel), each
    acknowledged as it comes."""
    frames = []
    while True:
        f = sub.get(0.05 if ack else 0.01)
        if f is None:
            if sub.closed:
                return frames
            continue
        frames.append(f)
        if ack:
            ack[0].ack(ack[1], f.frame_number)


def run_with_channels(pub, channels, *, fail_on=None, skip_acks=()):
    """Run pub with fake channels that acknowledge every frame they receive."""
    subs = {c: pub.subscribe(f"w-{c}", c) for c in channels}
    observer = pub.subscribe("obs", "")
    received = {c: [] for c in channels}

    def channel(c):
        sub = subs[c]
        while True:
            f = sub.get(0.05)
            if f is None:
                if sub.closed:
                    return
                continue
            received[c].append(f.frame_number)
            if c not in skip_acks:
                ok = fail_on is None or f.frame_number != fail_on
                pub.ack(c, f.frame_number, ok=ok, error="" if ok else "boom")

    seen = []
    threads = [threading.Thread(target=channel, args=(c,)) for c in channels]
    threads.append(threading.Thread(target=lambda: seen.extend(drain(observer))))
    for t in threads:
        t.start()
    pub.run(threading.Event())
    for t in threads:
        t.join()
    return received, seen


def test_frames_are_numbered_strictly_increasing_and_timed():
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=200.0, duration_s=0.1, observers=1)
    received, seen = run_with_channels(pub, ["a", "b"])
    numbers = [f.frame_number for f in seen]
    assert numbers == list(range(pub.tick_count))
    assert received["a"] == received["b"] == numbers
    assert all(f.run_id == pub.status.run_id for f in seen)
    assert [round(f.sim_time_s, 9) for f in seen] == [round(k / 200.0, 9) for k in range(pub.tick_count)]
    assert all(f.control_sample_time_unix_s <= f.publish_time_unix_s for f in seen)
    assert pub.snapshot().frames_published == pub.tick_count
    assert pub.snapshot().finished


def test_nan_eyepoint_is_rejected_and_counted_and_the_run_goes_on():
    def bad_at_3(t):
        e = source(t)
        if abs(t - 3 / 100) < 1e-9:
            return Eyepoint.of(float("nan"), 0, 0, 0, 0, 0)
        return e
    pub = FramePublisher(source=bad_at_3, channels=["a"], rate_hz=100.0, duration_s=0.09, observers=1)
    _, seen = run_with_channels(pub, ["a"])
    status = pub.snapshot()
    assert status.eyepoints_rejected == 1
    assert "eyepoint.position[0]: nan is not finite" in status.last_error
    assert len(seen) == pub.tick_count - 1
    numbers = [f.frame_number for f in seen]
    assert numbers == sorted(set(numbers))  # still strictly increasing


def test_unknown_channel_is_refused_naming_it():
    pub = FramePublisher(source=source, channels=["left", "right"], duration_s=0.0)
    with pytest.raises(UnknownChannel, match=r"channel_name: 'middle' is not a channel of the rig \(left, right\)"):
        pub.subscribe("x", "middle")
    with pytest.raises(UnknownChannel, match="'middle'"):
        pub.ack("middle", 0)
    assert pub.snapshot().subscriptions_rejected == 1


def test_sync_waits_for_acks_and_counts_timeouts():
    pub = FramePublisher(source=source, channels=["a", "slow"], rate_hz=1000.0, duration_s=0.002,
                         sync_timeout_s=0.05, observers=0)
    received, _ = run_with_channels(pub, ["a", "slow"], skip_acks={"slow"})
    status = pub.snapshot()
    assert status.ack_timeouts == {"a": 0, "slow": pub.tick_count}
    assert received["slow"] == list(range(pub.tick_count))


def test_failed_ack_is_counted():
    pub = FramePublisher(source=source, channels=["a"], rate_hz=1000.0, duration_s=0.003, observers=0)
    run_with_channels(pub, ["a"], fail_on=1)
    status = pub.snapshot()
    assert status.ack_failures == {"a": 1}
    assert "frame 1: boom" in status.last_error


def test_a_stalled_subscriber_drops_oldest_and_never_blocks_others():
    pub = FramePublisher(source=source, channels=["a"], rate_hz=1000.0, duration_s=0.05, observers=0)
    stalled = pub.subscribe("stalled", "")
    received, _ = run_with_channels(pub, ["a"])
    assert received["a"] == list(range(pub.tick_count))
    assert stalled.dropped > 0
    left = drain(stalled)
    assert left[-1].frame_number == pub.tick_count - 1  # the newest frames are kept


@pytest.mark.parametrize("kw,pattern", [
    (dict(rate_hz=0.0), "rate_hz: 0.0 must be a finite number > 0"),
    (dict(rate_hz=float("nan")), "rate_hz: nan must be"),
    (dict(duration_s=-1.0), "duration_s: -1.0 must be"),
    (dict(sync_timeout_s=0.0), "sync_timeout_s: 0.0 must be > 0"),
])
def test_bad_options_are_named(kw, pattern):
    with pytest.raises(ValueError, match=pattern):
        FramePublisher(source=source, channels=["a"], **kw)


def test_a_second_subscriber_for_a_channel_is_refused():
    pub = FramePublisher(source=source, channels=["a"], duration_s=0.0)
    pub.subscribe("first", "a")
    with pytest.raises(ChannelTaken, match=r"channel_name: 'a' already has a subscriber \(first\)"):
        pub.subscribe("second", "a")
    pub.subscribe("obs1", "")
    pub.subscribe("obs2", "")  # any number of observers
    assert pub.snapshot().subscriptions_rejected == 1


def test_stop_interrupts_the_wait_for_subscribers():
    # Nobody subscribes and the start timeout is far away: only stop can end run().
    pub = FramePublisher(source=source, channels=["a"], duration_s=1.0, start_timeout_s=3600.0)
    stop = threading.Event()
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    stop.set()
    runner.join()
    status = pub.snapshot()
    assert status.finished and status.frames_published == 0
    assert pub.end_reason == STOPPED


def test_a_subscription_after_the_run_is_refused_and_counted_not_opened():
    # A stream opened after the end would close at once, and its subscriber come straight back
    # (issue 33): the host refuses it instead, saying the run has ended.
    pub = FramePublisher(source=source, channels=["a"], rate_hz=100.0, duration_s=0.02, start_timeout_s=0.0)
    pub.run(threading.Event())
    assert pub.end_reason == COMPLETED
    for _ in range(2):
        with pytest.raises(RunOver, match=rf"run_id '{pub.status.run_id}' has ended \(3 frames published\)"):
            pub.subscribe("worker-a", "a")
    status = pub.snapshot()
    assert status.requests_refused == {"run_ended": 2} and status.subscribers == []
    assert status.last_error == ""  # the last real problem is kept
    with pytest.raises(UnknownChannel):  # a wrong name is still said first: it never goes away
        pub.subscribe("worker-z", "z")


def test_stop_interrupts_the_wait_for_acks():
    pub = FramePublisher(source=source, channels=["a"], rate_hz=100.0, duration_s=1.0, sync_timeout_s=3600.0)
    sub = pub.subscribe("silent", "a")
    stop = threading.Event()
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    assert sub.get(60.0).frame_number == 0  # published, and now waiting for an ack that never comes
    stop.set()
    runner.join()
    status = pub.snapshot()
    assert status.frames_published == 1 and status.ack_timeouts == {"a": 0}  # a stop is not a timeout
    assert sub.get(0.0) is None and sub.closed


def test_an_absent_channel_is_not_waited_for_and_is_counted():
    # "b" never subscribes: the start timeout passes, then every frame goes without it and
    # without waiting the (long) sync timeout for it.
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.004,
                         sync_timeout_s=3600.0, start_timeout_s=0.0)
    received, _ = run_with_channels(pub, ["a"])
    status = pub.snapshot()
    assert received["a"] == list(range(pub.tick_count))
    assert status.channel_absent == {"a": 0, "b": pub.tick_count}
    assert status.ack_timeouts == {"a": 0, "b": 0}


def test_a_channel_that_leaves_mid_run_stops_being_waited_for():
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.005,
                         sync_timeout_s=3600.0)
    sub_b = pub.subscribe("w-b", "b")

    def leave_after_first_frame():
        assert sub_b.get(60.0).frame_number == 0
        pub.unsubscribe(sub_b)  # the worker died without acknowledging frame 0

    leaver = threading.Thread(target=leave_after_first_frame)
    leaver.start()
    received, _ = run_with_channels(pub, ["a"])
    leaver.join()
    assert received["a"] == list(range(pub.tick_count))
    assert pub.snapshot().channel_absent["b"] == pub.tick_count


def test_a_slow_frame_does_not_make_the_host_burst_to_catch_up():
    # Frame 0 takes 10 periods to acknowledge. Anchored to the start, frames 1..10 would then be
    # published back to back; the host restarts its schedule from frame 1 instead, so frame k
    # goes no earlier than k - 1 periods after frame 1 (a lower bound the host guarantees by
    # waiting; a slow machine only makes the gaps longer).
    period = 0.02
    times = []
    pub = FramePublisher(source=source, channels=["a"], rate_hz=1 / period, duration_s=5 * period,
                         clock=lambda: (times.append(time.monotonic()), time.time())[1])
    sub = pub.subscribe("w-a", "a")

    def channel():
        while (f := sub.get(0.05)) is not None or not sub.closed:
            if f is None:
                continue
            if f.frame_number == 0:
                time.sleep(10 * period)
            pub.ack("a", f.frame_number)

    t = threading.Thread(target=channel)
    t.start()
    pub.run(threading.Event())
    t.join()
    # the clock is called twice per tick (control sample, publish); take the control samples
    samples = times[::2]
    assert len(samples) == pub.tick_count
    slack = 1e-3  # between reading the schedule's clock and the control-sample clock
    for k in range(2, len(samples)):
        assert samples[k] - samples[1] >= (k - 1) * period - slack


def test_a_worker_still_starting_is_waited_for_past_the_start_timeout():
    # "b"'s worker is compiling its kernels: its health says NOT_SERVING (starting) and it does
    # not subscribe until long after the start timeout. The host waits for it; only then is
    # frame 0 published.
    answered = []
    late_frames = []

    def starting(channel):
        answered.append(channel)
        return True

    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.002,
                         sync_timeout_s=3600.0, start_timeout_s=0.2, starting=starting)

    def late_worker():
        time.sleep(1.0)  # five start timeouts
        sub = pub.subscribe("w-b", "b")
        late_frames.extend(f.frame_number for f in drain(sub, ack=(pub, "b")))

    late = threading.Thread(target=late_worker)
    late.start()
    received, _ = run_with_channels(pub, ["a"])
    late.join()
    status = pub.snapshot()
    assert "b" in answered and "a" not in answered  # only the missing channel is asked
    assert status.channel_absent["b"] == 0  # b was waited for, not given up on
    assert received["a"] == late_frames == list(range(pub.tick_count))


def test_a_silent_or_serving_but_unsubscribed_worker_is_given_up_after_the_start_timeout():
    # starting() is False both for a worker that does not answer and for one that answers
    # SERVING yet never subscribes (pointed at another host): neither holds the rig.
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.002,
                         sync_timeout_s=3600.0, start_timeout_s=0.3, starting=lambda channel: False)
    received, _ = run_with_channels(pub, ["a"])
    assert received["a"] == list(range(pub.tick_count))
    assert pub.snapshot().channel_absent["b"] == pub.tick_count


def test_an_external_hosts_frames_carry_its_frame_number_environment_and_views_and_a_restart_starts_a_new_run():
    from host_sim.publisher import FrameInput
    from ig.v1 import frame_pb2
    from services.rig.environment import Environment

    env = Environment(visibility_m=5000.0)
    view = frame_pb2.ChannelView(channel="a", yaw_deg=10.0)

    def external(t):
        k = round(t * 100)
        if k < 2:
            return FrameInput(None)  # no host yet: nothing published
        return FrameInput(source(t), host_frame_number=1000 + k, environment=env, views=(view,), new_run=k == 6)

    pub = FramePublisher(source=external, channels=["a"], rate_hz=100.0, duration_s=0.09, sync_timeout_s=1.0)
    first_run = pub.status.run_id
    _received, seen = run_with_channels(pub, ["a"])
    assert pub.status.idle_ticks == 2 and pub.status.runs == 2
    assert [f.frame_number for f in seen] == [0, 1, 2, 3, 0, 1, 2, 3]
    assert [f.run_id == first_run for f in seen] == [True] * 4 + [False] * 4
    assert [f.host_frame_number for f in seen] == list(range(1002, 1010))
    assert seen[0].environment.visibility_m == 5000.0 and seen[0].views[0].yaw_deg == 10.0
    # A late acknowledgement of the ended run is late, not refused.
    pub.ack("a", 3, run_id=first_run)
    assert pub.status.late_acks["a"] >= 1 and not pub.status.requests_refused
