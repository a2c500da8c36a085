"""Image I/O through OpenImageIO."""

import numpy as np

from services.rig.colour import _srgb_encode, linear_to_srgb8, srgb8_to_linear
from services.rig.image_io import read_image, write_image


def test_srgb8_table_matches_the_transfer_function():
    x = np.linspace(0.0, 1.0, 200_001, dtype=np.float32)
    exact = np.round(_srgb_encode(x.astype(np.float64)) * 255.0)
    assert np.abs(linear_to_srgb8(x).astype(int) - exact).max() <= 1
    assert (linear_to_srgb8(x).astype(int) == exact).mean() > 0.999
    assert linear_to_srgb8(np.array([np.nan, -1.0, 2.0, np.inf])).tolist() == [0, 0, 255, 255]
    levels = np.arange(256, dtype=np.uint8)
    assert (linear_to_srgb8(srgb8_to_linear(levels)) == levels).all()


def test_exr_roundtrip_with_z_and_attributes(tmp_path):
    rgb = np.random.default_rng(0).random((5, 7, 3), dtype=np.float32)
    z = np.full((5, 7), np.inf, np.float32)
    z[2, 3] = 1234.5
    write_image(tmp_path / "a.exr", rgb, range_m=z, attributes={"frame_number": 7, "eye_x": 1.5e6})
    pixels, attrs = read_image(tmp_path / "a.exr")
    assert attrs["channelnames"] == "R,G,B,Z"
    np.testing.assert_allclose(pixels[..., :3], rgb, atol=1e-3)  # half floats
    assert pixels[2, 3, 3] == 1234.5 and np.isinf(pixels[0, 0, 3])
    assert attrs["frame_number"] == 7 and attrs["eye_x"] == 1.5e6


def test_png_is_srgb_8bit_with_text_attributes(tmp_path):
    rgb = np.full((2, 3, 3), srgb8_to_linear(np.uint8(128)), np.float32)
    write_image(tmp_path / "a.png", rgb, attributes={"frame_number": 3})
    pixels, attrs = read_image(tmp_path / "a.png")
    assert pixels.shape == (2, 3, 3)
    assert round(float(pixels[0, 0, 0]) * 255) == 128
    assert attrs["frame_number"] == "3"
