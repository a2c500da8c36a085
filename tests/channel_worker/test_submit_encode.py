"""The worker's parallel sRGB encoder (channel_worker/submit.py) against the shared one."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.submit import encode_srgb8
from services.rig.colour import linear_to_srgb8


def test_the_rows_encoder_is_the_shared_encoder_bit_for_bit():
    rng = np.random.default_rng(7)
    rgb = (rng.random((37, 53, 3), dtype=np.float32) * 1.4 - 0.2)
    rgb[0, 0] = [np.nan, np.inf, -np.inf]
    rgb[1, 1] = [0.0, 1.0, np.float32(0.0031308)]
    out = np.empty(rgb.shape, np.uint8)
    encode_srgb8(rgb, out)
    np.testing.assert_array_equal(out, linear_to_srgb8(rgb))
    # A strided or float64 image takes the shared encoder's path, with the same result.
    wide = rgb.astype(np.float64)
    encode_srgb8(wide, out)
    np.testing.assert_array_equal(out, linear_to_srgb8(rgb))


def test_a_wrong_output_array_is_refused_naming_it():
    with pytest.raises(ValueError, match=r"^out: uint16 \(2, 2, 3\) is not a contiguous uint8 array"):
        encode_srgb8(np.zeros((2, 2, 3), np.float32), np.zeros((2, 2, 3), np.uint16))
