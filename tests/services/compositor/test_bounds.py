"""The gatherer's bounds: rig-file sizes, frames the host published without a channel, the open
frames' count and bytes, and the decided frames it remembers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ig.v1 import compositor_pb2, frame_pb2
from services.compositor import gather as gather_module
from services.compositor.gather import (
    DECIDED_MEMORY,
    UNPUBLISHED,
    WRONG_SIZE,
    FrameGatherer,
    InvalidSubmission,
)

CHANNELS = ("left", "centre", "right")
W, H = 4, 3
IMAGE_BYTES = W * H * 3 * 2


def eye(n):
    return frame_pb2.Eyepoint(x=1000.0 + n, y=2.0, z=3.0, heading_deg=359.5, pitch_deg=1.0, roll_deg=-2.0)


def published(n, channels=CHANNELS, run_id="r"):
    return frame_pb2.Frame(frame_number=n, sim_time_s=n / 60, eyepoint=eye(n), run_id=run_id,
                           control_sample_time_unix_s=100.0 + n, channels=list(channels))


def image(n, channel, *, w=W, h=H, run_id="r"):
    rgb = np.full((h, w, 3), 0.5, dtype="<f2")
    return compositor_pb2.SubmitChannelImageRequest(
        frame_number=n, channel_name=channel, width=w, height=h,
        pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16, pixels=rgb.tobytes(),
        eyepoint=eye(n), render_time_s=0.01, run_id=run_id)


class FakeClock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def gatherer(channels=CHANNELS, **kw):
    done = []
    g = FrameGatherer(channels, done.append, monotonic=FakeClock(), **kw)
    return g, done


# --- sizes -------------------------------------------------------------------------------------
def test_an_image_of_another_size_than_the_rig_files_is_refused():
    g, _ = gatherer(sizes=dict.fromkeys(CHANNELS, (W, H)))
    g.on_published(published(0))
    with pytest.raises(InvalidSubmission) as err:
        g.submit(image(0, "centre", w=W + 1, h=H))
    assert err.value.cause == WRONG_SIZE
    assert str(err.value) == f"width x height: {W + 1} x {H} is not channel 'centre''s {W} x {H} (rig file)"
    with pytest.raises(InvalidSubmission, match=f"{W} x {H + 2} is not channel 'left''s {W} x {H}"):
        g.submit(image(0, "left", h=H + 2))
    r = g.report()
    assert r["rejected_submissions"] == {WRONG_SIZE: 2} and r["pending_bytes"] == 0
    # The frame was not touched: the right size still completes it.
    for c in CHANNELS:
        g.submit(image(0, c))
    assert g.report()["frames_complete"] == 1


def test_without_sizes_any_consistent_size_is_taken():
    g, done = gatherer(channels=("a",))
    g.on_published(published(0, ("a",)))
    g.submit(image(0, "a", w=7, h=5))
    assert done[0].images[0].rgb.shape == (5, 7, 3)


# --- channels the host published without ------------------------------------------------------
def test_a_frame_published_without_a_channel_is_decided_when_the_listed_ones_delivered():
    g, done = gatherer()
    g.on_published(published(0, ("left", "right")))  # centre's worker is down
    g.submit(image(0, "left"))
    assert g.pending == 1  # right has not delivered yet
    g.submit(image(0, "right"))
    assert g.pending == 0 and done == []
    r = g.report()
    assert r["frames_incomplete"] == {"missing_channel": 1, "eyepoint_mismatch": 0}
    assert r["missing_by_channel"] == {"left": 0, "centre": 1, "right": 0}
    assert "frame 0: missing_channel: missing centre" in r["last_incomplete"]
    assert r["pending_bytes"] == 0
    g.submit(image(0, "centre"))  # the worker came back, too late for frame 0
    assert g.report()["late_by_channel"] == {"left": 0, "centre": 1, "right": 0}


def test_a_frame_without_a_channel_list_waits_for_every_channel():
    g, done = gatherer()
    g.on_published(published(0, ()))
    g.submit(image(0, "left"))
    g.submit(image(0, "right"))
    assert g.pending == 1
    g.submit(image(0, "centre"))
    assert [f.frame_number for f in done] == [0]


def test_the_listed_channels_decide_before_an_older_frame_is_given_up():
    g, done = gatherer()
    g.on_published(published(0))
    g.submit(image(0, "left"))
    g.on_published(published(1, ("left", "right")))
    g.submit(image(1, "left"))
    g.submit(image(1, "right"))
    r = g.report()
    # Frame 1 decided frame 0 too (frames are rendered in order): both incomplete, once each.
    assert r["frames_incomplete"]["missing_channel"] == 2 and r["frames_pending"] == 0 and done == []
    assert r["missing_by_channel"] == {"left": 0, "centre": 2, "right": 1}


# --- open frames: count and bytes --------------------------------------------------------------
def test_max_pending_frames_evicts_the_oldest_open_frame():
    g, _ = gatherer(max_pending_frames=2)
    for n in range(3):
        g.on_published(published(n))
        g.submit(image(n, "left"))
    r = g.report()
    assert r["frames_pending"] == 2 and r["frames_evicted"] == 1
    assert r["peak_pending_frames"] == 3  # counted before the eviction it caused
    assert r["pending_bytes"] == 2 * IMAGE_BYTES
    assert "frame 0: missing_channel: missing centre, right (evicted: 3 frames" in r["last_incomplete"]
    g.submit(image(0, "centre"))  # evicted: late
    assert g.report()["late_images"] == 1
    g.finalize_all()
    r = g.report()
    assert r["pending_bytes"] == 0 and r["frames_pending"] == 0
    assert r["frames_incomplete"]["missing_channel"] == 3


def test_max_pending_bytes_evicts_the_oldest_open_frames():
    g, done = gatherer(max_pending_bytes=2 * IMAGE_BYTES + 1)
    for n in range(3):
        g.on_published(published(n))
    g.submit(image(2, "left"))
    g.submit(image(1, "left"))
    assert g.report()["frames_evicted"] == 0
    g.submit(image(1, "centre"))  # three images: over the bound, the oldest open frame (0) goes first
    r = g.report()
    assert r["frames_evicted"] == 2  # frame 0 held nothing; frame 1 then went too
    assert r["pending_bytes"] == IMAGE_BYTES and r["peak_pending_bytes"] == 3 * IMAGE_BYTES
    assert r["frames_pending"] == 1  # frame 2 with its one image
    for c in ("centre", "right"):
        g.submit(image(2, c))
    assert [f.frame_number for f in done] == [2]
    r = g.report()
    assert r["pending_bytes"] == 0 and r["frames_pending"] == 0
    assert r["frames_complete"] + sum(r["frames_incomplete"].values()) == r["frames_published"] == 3


def test_an_image_larger_than_the_byte_bound_is_dropped_with_its_frame():
    g, _ = gatherer(max_pending_bytes=IMAGE_BYTES - 1)
    g.on_published(published(0))
    g.submit(image(0, "left"))
    r = g.report()
    assert r["frames_evicted"] == 1 and r["pending_bytes"] == 0 and r["frames_pending"] == 0


@pytest.mark.parametrize("kw", [dict(max_pending_frames=0), dict(max_pending_bytes=0)])
def test_bounds_below_one_are_refused(kw):
    with pytest.raises(ValueError, match="both must be >= 1"):
        FrameGatherer(CHANNELS, lambda f: None, **kw)


# --- any interleaving --------------------------------------------------------------------------
@st.composite
def interleavings(draw):
    """Frames 0..n-1, each published with some channels listed, some images delivered (only of
    listed channels, or of any), in a random order that keeps each frame's images within the
    gatherer's look-ahead of the frames published so far."""
    n = draw(st.integers(1, 12))
    events = []
    for k in range(n):
        listed = draw(st.lists(st.sampled_from(CHANNELS), unique=True, max_size=3))
        events.append(("pub", k, tuple(c for c in CHANNELS if c in listed)))
        for c in draw(st.lists(st.sampled_from(CHANNELS), unique=True, max_size=3)):
            events.append(("img", k, c))
    order = draw(st.permutations(events))
    return n, order


@settings(max_examples=300, deadline=None)
@given(case=interleavings(), max_frames=st.integers(1, 6), max_images=st.integers(1, 8))
def test_every_published_frame_is_decided_exactly_once(case, max_frames, max_images):
    n, order = case
    g, done = gatherer(max_pending_frames=max_frames, max_pending_bytes=max_images * IMAGE_BYTES)
    delivered = 0
    for kind, k, what in order:
        if kind == "pub":
            g.on_published(published(k, what))
        else:
            try:
                g.submit(image(k, what))
                delivered += 1
            except InvalidSubmission as exc:
                assert exc.cause == UNPUBLISHED  # an image far ahead of the published frames
        r = g.report()
        assert 0 <= r["frames_pending"] <= max_frames
        assert 0 <= r["pending_bytes"] <= max_images * IMAGE_BYTES
        assert r["pending_bytes"] % IMAGE_BYTES == 0
    g.finalize_all()
    r = g.report()
    assert r["frames_published"] == n
    assert r["frames_pending"] == 0 and r["pending_bytes"] == 0
    assert r["frames_complete"] + sum(r["frames_incomplete"].values()) == n
    assert r["frames_complete"] == len(done)
    numbers = [f.frame_number for f in done]
    assert numbers == sorted(set(numbers))  # in frame order, each once
    assert r["peak_pending_frames"] <= max_frames + 1
    assert r["late_images"] == sum(r["late_by_channel"].values()) <= delivered


# --- decided frames remembered -----------------------------------------------------------------
def test_decided_frames_are_bounded_and_a_late_image_of_a_forgotten_frame_is_still_late():
    g, done = gatherer(channels=("a",))
    frames = DECIDED_MEMORY + 10
    for n in range(frames):
        g.on_published(published(n, ("a",)))
        g.submit(image(n, "a"))
    assert len(done) == frames
    assert len(g._decided) <= DECIDED_MEMORY
    g.submit(image(0, "a"))  # decided long ago and forgotten: still late, never a new open frame
    g.submit(image(frames - 1, "a"))  # remembered: late
    r = g.report()
    assert r["late_images"] == 2 and r["late_by_channel"] == {"a": 2}
    assert r["frames_pending"] == 0 and r["pending_bytes"] == 0
    g.finalize_all()
    assert g.report()["frames_incomplete"]["missing_channel"] == 0


def test_an_incomplete_forgotten_frame_is_not_reopened(monkeypatch):
    monkeypatch.setattr(gather_module, "DECIDED_MEMORY", 4)
    g, _ = gatherer(channels=("a", "b"))
    for n in range(10):
        g.on_published(published(n, ("a", "b")))
        g.submit(image(n, "a"))
        g.submit(image(n, "b"))
    assert len(g._decided) == 4
    g.submit(image(1, "a"))
    r = g.report()
    assert r["late_by_channel"] == {"a": 1, "b": 0} and r["frames_pending"] == 0
    g.submit(image(1, "a"))  # a second image of a forgotten frame: late again, not a duplicate
    assert g.report()["late_by_channel"] == {"a": 2, "b": 0}
