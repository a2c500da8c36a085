"""The frame writer: PNG every frame, EXR every Nth with attributes, latency at composite time."""

import numpy as np
import pytest

from services.compositor.gather import ChannelImage, CompleteFrame
from services.compositor.stitch import FrameWriter, stitch
from services.rig.image_io import read_image


def complete(n, heights=(2, 2)):
    images = tuple(ChannelImage(name, np.full((h, 3, 3), i, "<f2"), (1.0, 2.0, 3.0, 90.0, 1.0, -1.0), 0.01, 100.0, 0)
                   for i, (name, h) in enumerate(zip(("a", "b"), heights, strict=True)))
    return CompleteFrame(n, n / 10, (1.0, 2.0, 3.0, 90.0, 1.0, -1.0), 100.0, images)


def test_png_every_frame_exr_every_nth_and_latency(tmp_path):
    writer = FrameWriter(tmp_path / "frames", exr_every=2, clock=lambda: 100.25)
    for n in range(3):
        writer.put(complete(n))
    writer.close()
    written, errors, latencies = writer.snapshot()
    assert (written, errors) == (3, 0)
    assert latencies == [pytest.approx(0.25)] * 3
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [
        "frame_000000.exr", "frame_000000.png", "frame_000001.png", "frame_000002.exr", "frame_000002.png"]
    pixels, attrs = read_image(tmp_path / "frames" / "frame_000002.exr")
    assert pixels.shape == (2, 6, 3)
    np.testing.assert_array_equal(pixels[0, :, 0], [0, 0, 0, 1, 1, 1])
    assert attrs["channels"] == "a,b" and int(attrs["frame_number"]) == 2
    assert float(attrs["heading_deg"]) == 90.0 and float(attrs["sim_time_s"]) == pytest.approx(0.2)
    assert attrs["eyepoint"] == "1.0 2.0 3.0 90.0 1.0 -1.0"  # exact float64 text


def test_unequal_heights_are_a_counted_write_error(tmp_path):
    with pytest.raises(ValueError, match=r"channel heights \[2, 3\] differ"):
        stitch(complete(0, heights=(2, 3)))
    writer = FrameWriter(tmp_path, exr_every=0)
    writer.put(complete(0, heights=(2, 3)))
    writer.close()
    assert writer.snapshot()[:2] == (0, 1)
    assert "differ" in writer.last_error
