"""The composite and its recording: stitched in memory at completion, written every Nth frame on
the recorder's thread, and left out (counted) rather than waited for when the writer is behind."""

import threading

import numpy as np
import pytest

from services.compositor import stitch as stitch_module
from services.compositor.gather import ChannelImage, CompleteFrame
from services.compositor.stitch import FrameRecorder, compose, stitch
from services.rig.image_io import read_image


def complete(n, heights=(2, 2)):
    images = tuple(ChannelImage(name, np.full((h, 3, 3), i, "<f2"), (1.0, 2.0, 3.0, 90.0, 1.0, -1.0), 0.01, 100.0, 0)
                   for i, (name, h) in enumerate(zip(("a", "b"), heights, strict=True)))
    return CompleteFrame(n, n / 10, (1.0, 2.0, 3.0, 90.0, 1.0, -1.0), 100.0, images)


def test_the_composite_is_stitched_at_once_and_its_images_are_views_of_it():
    composite = compose(complete(3), clock=lambda: 100.25)
    assert composite.time == 100.25
    assert composite.rgb.shape == (2, 6, 3) and composite.rgb.dtype == np.float16
    np.testing.assert_array_equal(composite.rgb[0, :, 0], [0, 0, 0, 1, 1, 1])
    for img in composite.frame.images:  # the received buffers are not kept alive by the composite
        assert np.shares_memory(img.rgb, composite.rgb)
    assert [img.channel for img in composite.frame.images] == ["a", "b"]
    np.testing.assert_array_equal(composite.frame.images[1].rgb, np.ones((2, 3, 3)))


def test_png_every_nth_frame_exr_every_mth(tmp_path):
    recorder = FrameRecorder(tmp_path / "frames", record_every=2, exr_every=3)
    for n in range(7):
        assert recorder.offer(compose(complete(n)))
    recorder.close()
    counts = recorder.snapshot()
    assert (counts.written, counts.errors, counts.not_recorded) == (5, 0, 0)  # frames 0, 2, 3, 4, 6
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [
        "frame_000000.exr", "frame_000000.png", "frame_000002.png", "frame_000003.exr", "frame_000004.png",
        "frame_000006.exr", "frame_000006.png"]
    pixels, attrs = read_image(tmp_path / "frames" / "frame_000006.exr")
    assert pixels.shape == (2, 6, 3)
    np.testing.assert_array_equal(pixels[0, :, 0], [0, 0, 0, 1, 1, 1])
    assert attrs["channels"] == "a,b" and int(attrs["frame_number"]) == 6
    assert float(attrs["heading_deg"]) == 90.0 and float(attrs["sim_time_s"]) == pytest.approx(0.6)
    assert attrs["eyepoint"] == "1.0 2.0 3.0 90.0 1.0 -1.0"  # exact float64 text


def test_pngs_by_simulated_time_take_the_first_frame_of_each_interval(tmp_path):
    # A rig paced by its own frame lock has no rate known in advance (ig demo --rate auto):
    # one PNG a simulated second, whatever the frames' spacing; EXRs stay by frame number.
    recorder = FrameRecorder(tmp_path, record_every=1, exr_every=0, record_per_s=1.0)
    times = [0.0, 0.3, 0.9, 1.2, 1.25, 2.7, 2.99, float("nan"), 3.0]
    due = [recorder.due(n, t)[0] for n, t in enumerate(times)]
    assert due == [True, False, False, True, False, True, False, False, True]
    recorder.close()
    twice = FrameRecorder(tmp_path / "frames", record_every=0, exr_every=4, record_per_s=2.0)
    for n in range(12):  # complete(n) is at n / 10 s
        assert twice.offer(compose(complete(n)))
    twice.close()
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [
        "frame_000000.exr", "frame_000000.png", "frame_000004.exr", "frame_000005.png", "frame_000008.exr",
        "frame_000010.png"]
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="record_per_s"):
            FrameRecorder(tmp_path, record_per_s=bad)


def test_a_writer_that_is_behind_never_blocks_the_offer(tmp_path, monkeypatch):
    """The disk stalls: offers return at once, the frames due beyond the queue are counted as
    not recorded, and everything queued is written once the disk comes back."""
    release = threading.Event()
    real_write = stitch_module.write_image

    def stalled_write(*args, **kwargs):
        release.wait(30)
        real_write(*args, **kwargs)

    monkeypatch.setattr(stitch_module, "write_image", stalled_write)
    size = compose(complete(0)).rgb.nbytes
    recorder = FrameRecorder(tmp_path, record_every=1, exr_every=0, max_bytes=2 * size)
    # The writer takes the first composite and stalls on it; a second fills the budget.
    results = [recorder.offer(compose(complete(n))) for n in range(6)]
    release.set()
    recorder.close()
    counts = recorder.snapshot()
    assert results == [True, True, False, False, False, False]
    assert counts.not_recorded == 4
    assert counts.written == 6 - counts.not_recorded and counts.errors == 0
    assert len(list(tmp_path.glob("frame_*.png"))) == counts.written


def test_frames_not_due_are_not_queued_and_zero_means_never(tmp_path):
    recorder = FrameRecorder(tmp_path, record_every=0, exr_every=0, max_bytes=1)
    assert all(recorder.offer(compose(complete(n))) for n in range(5))
    recorder.close()
    assert recorder.snapshot().written == 0 and not list(tmp_path.iterdir())
    with pytest.raises(ValueError, match="record_every: -1 must be >= 0"):
        FrameRecorder(tmp_path, record_every=-1)


def test_unequal_heights_cannot_be_stitched():
    with pytest.raises(ValueError, match=r"channel heights \[2, 3\] differ"):
        stitch(complete(0, heights=(2, 3)))


def test_an_unwritable_directory_is_a_counted_write_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    recorder = FrameRecorder(blocker / "frames", record_every=1, exr_every=0)
    recorder.offer(compose(complete(0)))
    recorder.close()
    counts = recorder.snapshot()
    assert (counts.written, counts.errors) == (0, 1)
    assert recorder.last_error.startswith("frame 0:")
