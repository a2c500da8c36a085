"""Frame gathering: complete, missing, mismatched, late, refused submissions."""

import numpy as np
import pytest

from ig.v1 import compositor_pb2, frame_pb2
from services.compositor.gather import FrameGatherer, InvalidSubmission
from services.compositor.stitch import stitch

CHANNELS = ("left", "centre", "right")


def eye(n):
    return frame_pb2.Eyepoint(x=1000.0 + n, y=2.0, z=3.0, heading_deg=359.5, pitch_deg=1.0, roll_deg=-2.0)


def published(n):
    return frame_pb2.Frame(frame_number=n, sim_time_s=n / 60, eyepoint=eye(n), run_id="r",
                           control_sample_time_unix_s=100.0 + n)


def image(n, channel, *, eyepoint=None, w=4, h=3, value=None):
    rgb = np.full((h, w, 3), CHANNELS.index(channel) if value is None else value, dtype="<f2") \
        if channel in CHANNELS else np.zeros((h, w, 3), "<f2")
    return compositor_pb2.SubmitChannelImageRequest(
        frame_number=n, channel_name=channel, width=w, height=h,
        pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16, pixels=rgb.tobytes(),
        eyepoint=eyepoint or eye(n), render_time_s=0.01, control_sample_time_unix_s=100.0 + n, run_id="r")


class FakeClock:
    """A monotonic clock the test moves by hand."""

    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def gatherer(clock=None, **kw):
    done = []
    g = FrameGatherer(CHANNELS, done.append, monotonic=clock or FakeClock(), **kw)
    return g, done


def test_complete_frame_is_stitched_in_channel_order():
    g, done = gatherer()
    g.on_published(published(0))
    for c in ("right", "left", "centre"):
        g.submit(image(0, c))
    assert [f.frame_number for f in done] == [0]
    rgb = stitch(done[0])
    assert rgb.shape == (3, 12, 3)
    np.testing.assert_array_equal(rgb[0, ::4, 0], [0, 1, 2])
    assert done[0].control_sample_time == 100.0 and done[0].sim_time_s == 0.0
    r = g.report()
    assert r["frames_complete"] == 1 and r["frames_published"] == 1 and r["frames_pending"] == 0


def test_images_before_the_host_frame_wait_for_it():
    g, done = gatherer()
    for c in CHANNELS:
        g.submit(image(0, c))
    assert done == []
    g.on_published(published(0))
    assert len(done) == 1


def test_missing_channel_is_counted_when_a_newer_frame_completes():
    g, done = gatherer()
    for n in (0, 1):
        g.on_published(published(n))
    g.submit(image(0, "left"))
    g.submit(image(0, "centre"))
    for c in CHANNELS:
        g.submit(image(1, c))
    assert [f.frame_number for f in done] == [1]
    assert g.report()["frames_incomplete"]["missing_channel"] == 1
    g.submit(image(0, "right"))  # too late now
    assert g.report()["late_images"] == 1
    assert len(done) == 1


def test_eyepoint_mismatch_is_never_stitched():
    g, done = gatherer()
    g.on_published(published(0))
    g.submit(image(0, "left"))
    g.submit(image(0, "centre"))
    off = eye(0)
    off.heading_deg = np.nextafter(off.heading_deg, 400.0)  # one ulp is a mismatch
    g.submit(image(0, "right", eyepoint=off))
    assert done == []
    r = g.report()
    assert r["frames_incomplete"]["eyepoint_mismatch"] == 1
    assert "channels right rendered another eyepoint" in r["last_incomplete"]


def test_negative_zero_is_not_bitwise_equal_to_zero():
    g, done = gatherer()
    frame = published(0)
    frame.eyepoint.roll_deg = 0.0
    g.on_published(frame)
    for c in CHANNELS:
        e = eye(0)
        e.roll_deg = -0.0 if c == "centre" else 0.0
        g.submit(image(0, c, eyepoint=e))
    assert done == [] and g.report()["frames_incomplete"]["eyepoint_mismatch"] == 1


def test_an_open_frame_times_out_as_missing_channel():
    clock = FakeClock()
    g, done = gatherer(clock, pending_timeout_s=30.0)
    g.on_published(published(0))
    g.submit(image(0, "left"))
    clock.now += 29.0
    assert g.expire() == 0
    clock.now += 1.0
    assert g.expire() == 1
    r = g.report()
    assert r["frames_incomplete"]["missing_channel"] == 1 and r["frames_pending"] == 0
    assert r["last_incomplete"] == "frame 0: missing_channel: missing centre, right"
    g.submit(image(0, "centre"))
    assert g.report()["late_images"] == 1 and done == []


def test_an_image_of_another_run_is_refused():
    g, _done = gatherer()
    g.on_published(published(0))
    stale = image(0, "left")
    stale.run_id = "old"
    with pytest.raises(InvalidSubmission, match="run_id: 'old' is not the current run 'r'"):
        g.submit(stale)
    assert g.report()["rejected_submissions"] == {"other_run": 1}


def test_a_gatherer_collects_one_run():
    # The compositor starts a gatherer per run (test_runs.py); another run's frame is a mistake.
    g, _done = gatherer()
    g.on_published(published(0))
    second = published(0)
    second.run_id = "r2"
    with pytest.raises(ValueError, match="run_id: 'r2' is not this gatherer's run 'r'"):
        g.on_published(second)


def test_end_of_run_finalises_open_frames():
    g, _done = gatherer()
    g.on_published(published(0))
    g.on_published(published(1))
    g.submit(image(1, "left"))
    g.finalize_all()
    r = g.report()
    assert r["frames_incomplete"]["missing_channel"] == 2 and r["frames_pending"] == 0


@pytest.mark.parametrize("request_,cause,pattern", [
    (image(0, "bogus"), "unknown_channel", r"channel_name: 'bogus' is not a channel of the rig"),
    (image(0, "left", eyepoint=frame_pb2.Eyepoint(x=float("nan"))), "non_finite_eyepoint",
     r"eyepoint.x: nan is not finite"),
])
def test_bad_submissions_are_refused_and_counted(request_, cause, pattern):
    g, done = gatherer()
    g.on_published(published(0))
    with pytest.raises(InvalidSubmission, match=pattern):
        g.submit(request_)
    assert g.report()["rejected_submissions"] == {cause: 1}
    for c in CHANNELS:  # the rig is unaffected
        g.submit(image(0, c))
    assert len(done) == 1


def test_wrong_pixel_count_is_refused():
    g, _ = gatherer()
    bad = image(0, "left")
    bad.width = 5
    with pytest.raises(InvalidSubmission, match=r"pixels: 72 bytes, expected 90 for 5 x 3"):
        g.submit(bad)


def test_duplicate_image_is_refused():
    g, _ = gatherer()
    g.submit(image(0, "left"))
    with pytest.raises(InvalidSubmission, match="channel_name: 'left' already delivered frame_number 0"):
        g.submit(image(0, "left"))
    assert g.report()["rejected_submissions"] == {"duplicate_image": 1}


def test_wrong_pixel_format_is_named():
    g, _ = gatherer()
    bad = image(0, "left")
    bad.pixel_format = compositor_pb2.PIXEL_FORMAT_UNSPECIFIED
    with pytest.raises(InvalidSubmission, match="pixel_format: PIXEL_FORMAT_UNSPECIFIED is not "
                                                "PIXEL_FORMAT_RGB_SRGB8 or PIXEL_FORMAT_RGB_F16"):
        g.submit(bad)


def test_missing_eyepoint_is_refused():
    g, _ = gatherer()
    bad = image(0, "left")
    bad.ClearField("eyepoint")
    with pytest.raises(InvalidSubmission, match="eyepoint: missing"):
        g.submit(bad)
