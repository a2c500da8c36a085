"""What the host takes from an acknowledgement: only frames this run has published, only this
run, clipped error text; and which channels each published frame lists."""

import threading

import pytest

from host_sim.publisher import FrameOutOfRange, FramePublisher, OtherRun, UnknownChannel
from services.rig.frame import Eyepoint
from services.rig.grpc_util import MAX_TEXT_CHARS

#: Longest status text kept from a clipped error: MAX_TEXT_CHARS and the note of what was cut.
CLIPPED_MAX = MAX_TEXT_CHARS + 80


def source(t):
    return Eyepoint.of(t, 2 * t, 10.0, 0.0, 0.0, 0.0)


def start(pub):
    stop = threading.Event()
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    return stop, runner


def test_an_ack_before_anything_was_published_is_out_of_range():
    pub = FramePublisher(source=source, channels=["a"], duration_s=0.0)
    with pytest.raises(FrameOutOfRange, match=r"frame_number: 0 has not been published \(the last is none yet\)"):
        pub.ack("a", 0)
    status = pub.snapshot()
    assert status.requests_refused == {"out_of_range": 1}
    assert status.last_error == "a: frame_number: 0 has not been published (the last is none yet)"


@pytest.mark.parametrize("ahead", ["next", "max"])
def test_an_ack_of_an_unpublished_frame_is_refused_and_the_host_still_waits(ahead):
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.001,
                         sync_timeout_s=3600.0)
    subs = {c: pub.subscribe(f"w-{c}", c) for c in ("a", "b")}
    stop, runner = start(pub)
    try:
        assert subs["a"].get(60.0).frame_number == 0
        assert subs["b"].get(60.0).frame_number == 0
        pub.ack("a", 0)
        bad = 1 if ahead == "next" else 2**64 - 1
        with pytest.raises(FrameOutOfRange, match=rf"frame_number: {bad} has not been published \(the last is 0\)"):
            pub.ack("b", bad)
        status = pub.snapshot()
        assert status.requests_refused == {"out_of_range": 1}
        assert status.last_error.startswith("b: frame_number:")
        # Had the refused ack counted, frame 1 would go now: the host still waits for b's frame 0.
        assert subs["a"].get(0.3) is None
        assert pub.snapshot().frames_published == 1
        pub.ack("b", 0)  # the real acknowledgement releases the barrier
        assert subs["a"].get(60.0).frame_number == 1
        pub.ack("a", 1)
        pub.ack("b", 1)
        runner.join(60.0)
    finally:
        stop.set()
        runner.join(60.0)
    status = pub.snapshot()
    assert status.finished and status.frames_published == 2
    assert status.ack_timeouts == {"a": 0, "b": 0} and status.late_acks == {"a": 0, "b": 0}
    assert status.requests_refused == {"out_of_range": 1}


def test_an_ack_of_another_run_is_refused_and_counted():
    pub = FramePublisher(source=source, channels=["a"], rate_hz=1000.0, duration_s=0.0, run_id="run-1",
                         sync_timeout_s=3600.0)
    sub = pub.subscribe("w-a", "a")
    stop, runner = start(pub)
    try:
        assert sub.get(60.0).frame_number == 0
        with pytest.raises(OtherRun, match=r"run_id: 'run-0' is not the host's run 'run-1'"):
            pub.ack("a", 0, run_id="run-0")
        with pytest.raises(OtherRun, match=r"run_id: 'xxxx"):
            pub.ack("a", 0, run_id="x" * 10_000_000)
        status = pub.snapshot()
        assert status.requests_refused == {"other_run": 2}
        assert len(status.last_error) < 200  # the foreign run id is cut
        assert pub.snapshot().frames_published == 1
        pub.ack("a", 0, run_id="run-1")  # this run's
        runner.join(60.0)
        assert not runner.is_alive()
    finally:
        stop.set()
        runner.join(60.0)
    status = pub.snapshot()
    assert status.ack_timeouts == {"a": 0} and status.requests_refused == {"other_run": 2}


def test_an_ack_without_a_run_id_is_taken_from_an_older_worker():
    pub = FramePublisher(source=source, channels=["a"], rate_hz=1000.0, duration_s=0.0, run_id="run-1",
                         sync_timeout_s=3600.0)
    sub = pub.subscribe("w-a", "a")
    stop, runner = start(pub)
    assert sub.get(60.0).frame_number == 0
    pub.ack("a", 0)
    runner.join(60.0)
    stop.set()
    assert not runner.is_alive() and pub.snapshot().requests_refused == {}


def test_an_unknown_channel_is_refused_with_its_name_clipped():
    pub = FramePublisher(source=source, channels=["a"], duration_s=0.0)
    with pytest.raises(UnknownChannel):
        pub.ack("z" * 10_000_000, 0)
    status = pub.snapshot()
    assert status.requests_refused == {"unknown_channel": 1} and len(status.last_error) < 300


def test_an_ack_of_an_older_frame_after_the_barrier_moved_on_is_late():
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.001,
                         sync_timeout_s=0.1)
    subs = {c: pub.subscribe(f"w-{c}", c) for c in ("a", "b")}
    stop, runner = start(pub)
    try:
        assert subs["a"].get(60.0).frame_number == 0
        assert subs["b"].get(60.0).frame_number == 0
        pub.ack("a", 0)  # b does not: the sync timeout passes and frame 1 goes without it
        assert subs["a"].get(60.0).frame_number == 1
        assert subs["b"].get(60.0).frame_number == 1
        pub.ack("b", 0)  # late: the barrier is at frame 1
        assert pub.snapshot().late_acks == {"a": 0, "b": 1}
        pub.ack("a", 1)
        pub.ack("b", 1)  # the frame waited for: not late
        runner.join(60.0)
    finally:
        stop.set()
        runner.join(60.0)
    status = pub.snapshot()
    assert status.late_acks == {"a": 0, "b": 1}
    assert status.ack_timeouts == {"a": 0, "b": 1}
    assert status.requests_refused == {}


def test_a_huge_error_text_is_clipped_in_last_error():
    pub = FramePublisher(source=source, channels=["a"], rate_hz=1000.0, duration_s=0.0, sync_timeout_s=3600.0)
    sub = pub.subscribe("w-a", "a")
    stop, runner = start(pub)
    try:
        assert sub.get(60.0).frame_number == 0
        pub.ack("a", 0, ok=False, error="E" * 10_000_000)
        runner.join(60.0)
    finally:
        stop.set()
        runner.join(60.0)
    status = pub.snapshot()
    assert status.ack_failures == {"a": 1}
    assert status.last_error.startswith("a: frame 0: EEEE")
    assert len(status.last_error) <= CLIPPED_MAX
    assert "more characters)" in status.last_error


def test_refusals_keep_a_clipped_message():
    pub = FramePublisher(source=source, channels=["a"], duration_s=0.0)
    pub.refuse("malformed", "m" * 10_000_000)
    status = pub.snapshot()
    assert status.requests_refused == {"malformed": 1} and len(status.last_error) <= CLIPPED_MAX


def test_published_frames_list_the_subscribed_channels_in_rig_order():
    pub = FramePublisher(source=source, channels=["left", "centre", "right"], rate_hz=1000.0, duration_s=0.002,
                         sync_timeout_s=3600.0, start_timeout_s=0.0, observers=1)
    subs = {c: pub.subscribe(f"w-{c}", c) for c in ("right", "left")}  # centre's worker is down
    observer = pub.subscribe("compositor", "")
    seen = []

    def channel(c):
        while (f := subs[c].get(0.05)) is not None or not subs[c].closed:
            if f is not None:
                pub.ack(c, f.frame_number)

    def observe():
        while (f := observer.get(0.05)) is not None or not observer.closed:
            if f is not None:
                seen.append(f)

    threads = [threading.Thread(target=channel, args=(c,)) for c in subs] + [threading.Thread(target=observe)]
    for t in threads:
        t.start()
    pub.run(threading.Event())
    for t in threads:
        t.join(60.0)
    assert [f.frame_number for f in seen] == list(range(pub.tick_count))
    assert all(list(f.channels) == ["left", "right"] for f in seen)
    assert pub.snapshot().channel_absent == {"left": 0, "centre": pub.tick_count, "right": 0}


def test_a_channel_that_subscribes_after_a_frame_went_out_is_not_waited_for_on_it():
    # The swap barrier of frame n covers the channels that received n: a worker that comes back
    # while the host waits for n never got it, and must not hold n up to the timeout.
    pub = FramePublisher(source=source, channels=["a", "b"], rate_hz=1000.0, duration_s=0.001,
                         sync_timeout_s=3600.0, start_timeout_s=0.0)
    a = pub.subscribe("w-a", "a")
    stop, runner = start(pub)
    try:
        first = a.get(60.0)
        assert first.frame_number == 0 and list(first.channels) == ["a"]
        b = pub.subscribe("w-b", "b")  # b returns while the host waits for frame 0
        pub.ack("a", 0)
        second = a.get(60.0)  # released by a's acknowledgement alone
        assert second.frame_number == 1 and list(second.channels) == ["a", "b"]
        assert b.get(60.0).frame_number == 1
        pub.ack("a", 1)
        pub.ack("b", 1)
        runner.join(60.0)
        status = pub.snapshot()
        assert status.ack_timeouts == {"a": 0, "b": 0}
        assert status.channel_absent == {"a": 0, "b": 1}
    finally:
        stop.set()
        runner.join(60.0)
