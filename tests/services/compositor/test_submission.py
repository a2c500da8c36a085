"""The worker's side of SubmitChannelImage, as the compositor receives it: the pixels rounded to
half floats bit for bit as numpy rounds them, and serialised once, after the other fields,
into a message protobuf parses as the plain request."""

import warnings

import numpy as np
import pytest

from channel_worker.submit import ImageSubmission, encode_rgb_f16, serialize_submission, to_half
from ig.v1 import compositor_pb2, frame_pb2


def numpy_half_bits(x):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # overflow to inf is what is tested
        return x.astype("<f2").view("<u2")


@pytest.mark.parametrize("lo,hi", [
    (0x00000000, 0x00100000),  # zero and the smallest float32s: round to +0
    (0x32FF0000, 0x39000000),  # around half's subnormals (2^-25 .. 2^-14) and its smallest normals
    (0x3F7F0000, 0x3F810000),  # around 1.0
    (0x477F0000, 0x47810000),  # around 65504 (half's largest) .. 65536: rounding up to inf
    (0x7F7F0000, 0x7F800001),  # the largest float32s and inf
])
def test_half_floats_are_numpys_bit_for_bit(lo, hi):
    # Every pattern of the range's upper 24 bits, with the low 8 bits 0x00, 0x01, 0x80 or
    # 0xFF: rounding to half drops 13 bits or more, so these hold every case of the dropped
    # bits (exact, a tie, just above a tie, below and above the half, sticky bits from the
    # lowest bit alone) with every bit above them. A 64th of the patterns: the range around
    # half's subnormals alone was 2 x 100 million values and 26 s of the suite.
    upper = np.arange(lo >> 8, (hi >> 8) + 1, dtype=np.uint64) << np.uint64(8)
    bits = (upper[:, None] | np.array([0x00, 0x01, 0x80, 0xFF], np.uint64)).ravel()
    bits = bits[(bits >= lo) & (bits < hi)].astype(np.uint32)
    for sign in (0, 0x80000000):
        x = (bits | np.uint32(sign)).view(np.float32)
        out = np.empty(x.shape, "<f2")
        to_half(x, out)
        np.testing.assert_array_equal(out.view("<u2"), numpy_half_bits(x))


def test_random_and_special_values_including_nan():
    rng = np.random.default_rng(7)
    x = rng.integers(0, 2**32, size=1_000_000, dtype=np.uint64).astype(np.uint32).view(np.float32)
    x = np.concatenate([x, np.array([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0], np.float32)])
    out = np.empty(x.shape, "<f2")
    to_half(x, out)
    expected = numpy_half_bits(x)
    nan = np.isnan(x)
    np.testing.assert_array_equal(out.view("<u2")[~nan], expected[~nan])
    assert np.isnan(out[nan]).all()


def test_other_layouts_fall_back_to_numpy_and_a_wrong_out_is_refused():
    rgb = np.linspace(0, 2, 2 * 3 * 3).reshape(2, 3, 3)  # float64
    out = np.empty(rgb.shape, "<f2")
    to_half(rgb, out)
    np.testing.assert_array_equal(out, rgb.astype("<f2"))
    assert encode_rgb_f16(rgb[:, ::-1].astype(np.float32)) == rgb[:, ::-1].astype("<f2").tobytes()
    with pytest.raises(ValueError, match=r"out: float32 \(2, 3, 3\) is not a contiguous <f2 array"):
        to_half(rgb, np.empty(rgb.shape, np.float32))


def test_the_serialised_submission_is_the_plain_request():
    pixels = np.arange(4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3).astype("<f2")
    head = compositor_pb2.SubmitChannelImageRequest(
        frame_number=7, channel_name="centre", width=5, height=4, pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16,
        eyepoint=frame_pb2.Eyepoint(x=1.0, z=3.0), render_time_s=0.01, run_id="r", frame_received_unix_s=10.0,
        render_start_unix_s=10.5, render_end_unix_s=11.0, submit_unix_s=11.25)
    submission = ImageSubmission(head, pixels.data.cast("B"))
    assert submission.frame_number == 7 and submission.channel_name == "centre"  # reads as the request
    parsed = compositor_pb2.SubmitChannelImageRequest.FromString(serialize_submission(submission))
    plain = compositor_pb2.SubmitChannelImageRequest()
    plain.CopyFrom(head)
    plain.pixels = pixels.tobytes()
    assert parsed == plain


def test_a_large_image_has_a_multi_byte_length():
    pixels = np.zeros((300, 400, 3), "<f2")  # 720,000 bytes: a three-byte length
    wire = serialize_submission(ImageSubmission(compositor_pb2.SubmitChannelImageRequest(frame_number=1),
                                                pixels.data.cast("B")))
    parsed = compositor_pb2.SubmitChannelImageRequest.FromString(wire)
    assert parsed.frame_number == 1 and len(parsed.pixels) == pixels.nbytes
