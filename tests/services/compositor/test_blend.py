"""Edge blending: the seam check's numbers, Bourke's ramps, the stitching plan and the masks."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.geometry.view import make_view
from services.compositor.blend import (
    BlendPlan,
    blend_plan,
    bourke_ramp,
    channel_masks,
    ramp_weights,
    seam_check,
    seams_report,
    write_masks,
)
from services.compositor.gather import ChannelImage, CompleteFrame
from services.compositor.stitch import compose, stitch
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.image_io import read_image
from services.rig.rigfile import BlendSpec, default_rig_path, load_rig

DEFAULT = tuple(ch.spec for ch in load_rig(default_rig_path()).channels)
NO_BLEND = BlendSpec()
EYE = (1.0, 2.0, 3.0, 90.0, 1.0, -1.0)


def rig_with(**centre) -> list[ChannelSpec]:
    """The default rig with its centre channel changed."""
    return [DEFAULT[0], replace(DEFAULT[1], **centre), DEFAULT[2]]


def widened(by_deg: float, width: int = 1024, *, outer: bool = False) -> list[ChannelSpec]:
    """The default rig with every inner frustum edge widened by by_deg (the overlap's half);
    outer: the outer edges too, so every channel has the same pixel pitch at its edges."""
    left, centre, right = DEFAULT
    out = 30.0 + by_deg if outer else 30.0
    return [replace(left, left_deg=-out, right_deg=30.0 + by_deg, width=width),
            replace(centre, left_deg=-30.0 - by_deg, right_deg=30.0 + by_deg, width=width),
            replace(right, left_deg=-30.0 - by_deg, right_deg=out, width=width)]


def frame_of(images: list[np.ndarray]) -> CompleteFrame:
    chans = tuple(ChannelImage(f"c{i}", rgb, EYE, 0.01, 100.0, 0) for i, rgb in enumerate(images))
    return CompleteFrame(7, 0.7, EYE, 100.0, chans)


# The seam check.

def test_the_default_rig_abuts_with_no_error():
    seams = seam_check(DEFAULT, NO_BLEND)
    assert [(s.left, s.right) for s in seams] == [("left", "centre"), ("centre", "right")]
    for s in seams:
        assert s.ok
        assert abs(s.overlap_min_deg) < 1e-9 and abs(s.overlap_max_deg) < 1e-9
        assert s.horizontal_error_deg < 1e-9 and s.vertical_error_deg < 1e-9
        assert s.horizontal_error_px < 1e-9 and s.vertical_error_px < 1e-9


def test_a_centre_channel_yawed_one_degree_opens_one_seam_and_overlaps_the_other():
    gap, overlap = seam_check(rig_with(yaw_deg=1.0), NO_BLEND)
    assert gap.overlap_min_deg == pytest.approx(-1.0) and gap.overlap_max_deg == pytest.approx(-1.0)
    assert overlap.overlap_min_deg == pytest.approx(1.0) and overlap.overlap_max_deg == pytest.approx(1.0)
    for s in (gap, overlap):
        assert s.horizontal_error_deg == pytest.approx(1.0)
        assert s.vertical_error_deg < 1e-9  # a yaw moves no row
        # 1024 px over tan 30 - tan(-30), at the edge sec^2(30) = 4/3: px per radian.
        px_per_rad = 1024 / (2 * math.tan(math.radians(30))) * 4 / 3
        assert s.horizontal_error_px == pytest.approx(math.radians(1.0) * px_per_rad, rel=1e-6)
        assert not s.ok


def test_a_configured_overlap_made_by_widening_the_frusta_is_ok():
    blend = BlendSpec(overlap_deg=10.0)
    seams = seam_check(widened(5.0), blend)
    for s in seams:
        assert s.ok
        assert s.overlap_min_deg == pytest.approx(10.0) and s.overlap_max_deg == pytest.approx(10.0)
        assert s.horizontal_error_deg < 1e-9 and s.vertical_error_deg < 1e-9
    # The same overlap against a configuration that expects abutting channels is 10 degrees off.
    assert all(s.horizontal_error_deg == pytest.approx(10.0) and not s.ok for s in seam_check(widened(5.0), NO_BLEND))


def test_a_rolled_channel_gives_a_vertical_error():
    """Rolling the centre 2 degrees tilts its rows: at its edges, 30 degrees off its axis, a ray
    of elevation 0 lands 2 sin 30 = 1 degree up or down (more towards the corners)."""
    for s in seam_check(rig_with(roll_deg=2.0), NO_BLEND):
        assert s.vertical_error_deg == pytest.approx(1.0, abs=0.02)
        assert s.vertical_error_px > 15  # 1 degree is about 21 rows of 768 over 45 degrees
        # The tilted edge crosses the other channel's: in at one end, out at the other.
        assert s.overlap_min_deg < -0.5 and s.overlap_max_deg > 0.5
        assert not s.ok


def test_a_pitched_channel_gives_a_vertical_error_of_pitch_times_cos_azimuth():
    for s in seam_check(rig_with(pitch_deg=2.0), NO_BLEND):
        assert s.vertical_error_deg == pytest.approx(2.0 * math.cos(math.radians(30.0)), abs=0.01)
        assert not s.ok
    small = seam_check(rig_with(pitch_deg=0.01), NO_BLEND)
    assert all(s.ok for s in small)  # within the default tolerance of 0.05 degrees


def test_asymmetric_frusta_that_meet_abut():
    """Left -20..40 at yaw -70 puts its right edge at -30 from the nose, the centre's left edge."""
    rig = [replace(DEFAULT[0], left_deg=-20.0, right_deg=40.0, yaw_deg=-70.0), DEFAULT[1],
           replace(DEFAULT[2], left_deg=-25.0, right_deg=35.0, yaw_deg=55.0)]
    for s in seam_check(rig, NO_BLEND):
        assert s.ok and abs(s.overlap_max_deg) < 1e-9 and s.vertical_error_deg < 1e-9
    # Asymmetric by a degree too much: 1 degree of gap.
    rig[2] = replace(rig[2], yaw_deg=56.0)
    assert seam_check(rig, NO_BLEND)[1].overlap_min_deg == pytest.approx(-1.0)


def test_one_channel_has_no_seams_and_five_have_four():
    assert seam_check(DEFAULT[:1], NO_BLEND) == []
    five = [ChannelSpec.symmetric(f"c{i}", 640, 480, 40.0, 30.0, yaw_deg=40.0 * (i - 2)) for i in range(5)]
    seams = seam_check(five, NO_BLEND)
    assert [(s.left, s.right) for s in seams] == [("c0", "c1"), ("c1", "c2"), ("c2", "c3"), ("c3", "c4")]
    assert all(s.ok for s in seams)
    five[3] = replace(five[3], yaw_deg=41.0)
    assert [s.ok for s in seam_check(five, NO_BLEND)] == [True, True, False, False]


def test_a_channel_facing_away_is_a_huge_error_not_a_division_by_zero():
    rig = [DEFAULT[0], replace(DEFAULT[1], yaw_deg=180.0)]
    (s,) = seam_check(rig, NO_BLEND)
    assert math.isfinite(s.horizontal_error_deg) and s.horizontal_error_deg > 90.0 and not s.ok


@settings(max_examples=40, deadline=None)
@given(st.floats(-20, 20), st.floats(-5, 5), st.floats(-5, 5), st.floats(-40, -10), st.floats(10, 40))
def test_the_seam_check_agrees_with_the_renderers_projection(yaw, pitch, roll, b_left, a_right):
    """Where the worker's own view (make_view: its world -> eye rotation and tangent-plane
    frustum) puts the left channel's right-edge rays in the right channel matches the check."""
    a = ChannelSpec("a", 800, 600, -30.0, a_right, -20.0, 25.0, yaw_deg=-30.0)
    b = ChannelSpec("b", 800, 600, b_left, 30.0, -20.0, 25.0, yaw_deg=a_right - b_left - 30.0 + yaw,
                    pitch_deg=pitch, roll_deg=roll)
    (s,) = seam_check([a, b], NO_BLEND)
    eye = Eyepoint.of(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    va, vb = make_view(a, eye), make_view(b, eye)
    overlaps = []
    for elev_tan in np.linspace(math.tan(math.radians(-20.0)), math.tan(math.radians(25.0)), 9):
        ray_eye = np.array([math.tan(math.radians(a_right)), elev_tan, 1.0])
        world = va.world_to_eye.T @ ray_eye
        xb, _, zb = vb.world_to_eye @ world
        assert zb > 0
        overlaps.append(math.degrees(math.atan(xb / zb) - math.atan(vb.tan_left)))
    assert s.overlap_min_deg == pytest.approx(min(overlaps), abs=1e-6)
    assert s.overlap_max_deg == pytest.approx(max(overlaps), abs=1e-6)


def test_the_report_is_json_ready():
    import json
    seams = seam_check(rig_with(yaw_deg=1.0), NO_BLEND)
    doc = json.loads(json.dumps(seams_report(seams)))
    assert doc["ok"] is False
    assert doc["seams"][0]["left"] == "left" and doc["seams"][0]["horizontal_error_deg"] == pytest.approx(1.0)
    plan = blend_plan(DEFAULT, NO_BLEND)
    doc = json.loads(json.dumps(plan.report()))
    assert doc["ok"] is True and doc["stitched_width"] == 3072
    assert [s["overlap_columns"] for s in doc["seams"]] == [0, 0]
    assert [s["overlap_columns_right"] for s in doc["seams"]] == [0, 0]


def test_the_report_shows_overlaps_of_unequal_pixel_pitch():
    """Widening only the inner edges of 1024 px channels gives the outer ones a finer pitch:
    the left channel has more columns in the 10 degrees than the centre, and the report says so."""
    plan = blend_plan(widened(5.0), BlendSpec(overlap_deg=10.0))
    (first, second) = plan.report()["seams"]
    assert first["ok"] and second["ok"]
    assert first["overlap_columns"] > first["overlap_columns_right"] + 10
    assert second["overlap_columns"] + 10 < second["overlap_columns_right"]
    even = blend_plan(widened(5.0, outer=True), BlendSpec(overlap_deg=10.0))
    assert even.overlaps == even.overlaps_right


# The ramps.

@given(st.integers(0, 4000), st.floats(0.5, 16.0))
def test_ramps_sum_to_exactly_one_and_rise_monotonically(n, power):
    fade_out, fade_in = ramp_weights(n, power)
    assert fade_out.dtype == fade_in.dtype == np.float32 and fade_in.shape == (n,)
    assert np.all(fade_out + fade_in == np.float32(1.0))
    assert np.all(fade_out.astype(np.float64) + fade_in.astype(np.float64) == 1.0)
    assert np.all(np.diff(fade_in) >= 0) and np.all((fade_in >= 0) & (fade_in <= 1))
    np.testing.assert_array_equal(fade_in, fade_out[::-1])  # symmetric about the middle


def test_bourke_curve_values():
    x = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    np.testing.assert_allclose(bourke_ramp(x, 2.0), [0.0, 0.125, 0.5, 0.875, 1.0])
    np.testing.assert_allclose(bourke_ramp(x, 1.0), x)
    with pytest.raises(ValueError, match=r"power: 0\.0 must be > 0"):
        bourke_ramp(x, 0.0)


# The plan and the stitch.

def test_the_plan_of_an_abutting_rig_is_a_plain_concatenation_bit_for_bit():
    plan = blend_plan(DEFAULT, NO_BLEND)
    assert plan.overlaps == (0, 0) and plan.offsets == (0, 1024, 2048) and plan.stitched_width == 3072
    assert not plan.blends
    rng = np.random.default_rng(1)
    images = [rng.random((768, 1024, 3)).astype(np.float16) for _ in range(3)]
    frame = frame_of(images)
    out = stitch(frame, plan)
    np.testing.assert_array_equal(out, np.concatenate(images, axis=1))
    assert out.dtype == np.float16
    assert np.array_equal(compose(frame, plan, clock=lambda: 1.0).rgb, stitch(frame))


def test_an_overlapping_plan_counts_columns_inside_the_other_channel():
    """10 degrees of overlap on 70-degree channels of 1120 px: the left channel's columns whose
    centres lie beyond 25 degrees in its own frame (the right channel's left edge)."""
    chans = widened(5.0, width=1120, outer=True)
    plan = blend_plan(chans, BlendSpec(overlap_deg=10.0))
    t = math.tan(math.radians(35.0))
    centres = np.degrees(np.arctan(-t + (np.arange(1120) + 0.5) / 1120 * 2 * t))
    expected = int(np.sum(centres > 25.0))
    assert plan.overlaps == (expected, expected) and expected > 100
    assert plan.offsets == (0, 1120 - expected, 2 * (1120 - expected))
    assert plan.stitched_width == 3 * 1120 - 2 * expected
    assert [w.size for w in plan.left_weights] == [0, expected, expected]
    assert [w.size for w in plan.right_weights] == [expected, expected, 0]


def test_a_uniform_image_stays_uniform_across_the_overlaps():
    chans = widened(5.0, width=300, outer=True)
    plan = blend_plan(chans, BlendSpec(overlap_deg=10.0, power=3.0))
    assert all(plan.overlaps)
    for value in (0.0, 0.2, 1.0, 37.5):
        frame = frame_of([np.full((20, 300, 3), value, np.float16) for _ in range(3)])
        out = stitch(frame, plan)
        assert out.shape == (20, plan.stitched_width, 3) and out.dtype == np.float16
        assert np.all(out == np.float16(value))


def test_the_overlap_is_a_cross_fade_with_the_linear_weights():
    chans = widened(5.0, width=300, outer=True)
    plan = blend_plan(chans, BlendSpec(overlap_deg=10.0))
    n = plan.overlaps[0]
    frame = frame_of([np.full((4, 300, 3), float(i + 1), np.float16) for i in range(3)])
    composite = compose(frame, plan)
    seam = composite.rgb[0, plan.offsets[1]:plan.offsets[1] + n, 0].astype(np.float32)
    expected = (1.0 * plan.right_weights[0] + 2.0 * plan.left_weights[1]).astype(np.float16)
    np.testing.assert_array_equal(seam, expected)
    assert np.all(composite.rgb[:, :plan.offsets[1], :] == 1.0)  # the left channel alone
    centre_alone = composite.rgb[:, plan.offsets[1] + n:plan.offsets[2], :]
    assert centre_alone.shape[1] == 300 - 2 * n and np.all(centre_alone == 2.0)
    # Each channel's view of the composite is its width, at its offset.
    for img, x in zip(composite.frame.images, plan.offsets, strict=True):
        assert img.rgb.shape == (4, 300, 3) and np.shares_memory(img.rgb, composite.rgb)
        np.testing.assert_array_equal(img.rgb, composite.rgb[:, x:x + 300])


def test_a_frame_that_does_not_fit_the_plan_is_refused():
    plan = blend_plan(widened(5.0, width=300, outer=True), BlendSpec(overlap_deg=10.0))
    frame = frame_of([np.zeros((4, 300, 3), np.float16), np.zeros((4, 301, 3), np.float16),
                      np.zeros((4, 300, 3), np.float16)])
    with pytest.raises(ValueError, match=r"channel widths \[300, 301, 300\] are not the blend plan's"):
        stitch(frame, plan)


def test_overlaps_wider_than_a_channel_are_refused():
    chans = [replace(DEFAULT[0], right_deg=80.0, width=100), replace(DEFAULT[1], left_deg=-80.0, width=10)]
    with pytest.raises(ValueError, match="channel 'centre'"):
        blend_plan(chans, NO_BLEND)
    with pytest.raises(ValueError, match="channels: empty"):
        blend_plan([], NO_BLEND)


# The masks.

def test_masks_are_one_outside_the_overlaps_and_the_ramp_to_one_over_gamma_inside(tmp_path):
    blend = BlendSpec(overlap_deg=10.0, power=2.0, gamma=2.2)
    plan = blend_plan(widened(5.0, width=300, outer=True), blend)
    n = plan.overlaps[0]
    fade_out, fade_in = ramp_weights(n, 2.0)
    masks = channel_masks(plan)
    assert list(masks) == ["left", "centre", "right"]
    left, centre, right = masks.values()
    assert left.shape == (300,) and left.dtype == np.float32
    assert np.all(left[:300 - n] == 1.0) and np.all(right[n:] == 1.0) and np.all(centre[n:300 - n] == 1.0)
    np.testing.assert_allclose(left[300 - n:], fade_out.astype(np.float64) ** (1 / 2.2), rtol=1e-6)
    np.testing.assert_allclose(centre[:n], fade_in.astype(np.float64) ** (1 / 2.2), rtol=1e-6)
    np.testing.assert_allclose(centre[300 - n:], fade_out.astype(np.float64) ** (1 / 2.2), rtol=1e-6)
    # In light the projectors' masks still sum to one across the seam.
    np.testing.assert_allclose(left[300 - n:].astype(np.float64) ** 2.2 + centre[:n].astype(np.float64) ** 2.2,
                               1.0, atol=1e-5)
    full = channel_masks(plan, full=True)["centre"]
    assert full.shape == (768, 300) and np.all(full == centre[None, :])
    assert all(np.all(m == 1.0) for m in channel_masks(blend_plan(DEFAULT, NO_BLEND)).values())

    paths = write_masks(plan, tmp_path)
    assert [p.name for p in paths] == ["mask_left.png", "mask_centre.png", "mask_right.png"]
    pixels, attrs = read_image(paths[1])
    assert pixels.shape == (768, 300, 3) and attrs["channel"] == "centre"
    # The PNG holds the signal-space mask itself, to an 8-bit level.
    np.testing.assert_allclose(pixels[5, :, 1], centre, atol=0.6 / 255)


def test_blend_plan_is_not_compared_by_value():
    """A plan holds numpy arrays; comparing two by value would be ambiguous, so it is by identity."""
    plan = blend_plan(DEFAULT, NO_BLEND)
    assert isinstance(plan, BlendPlan) and plan == plan and plan != blend_plan(DEFAULT, NO_BLEND)


def test_srgb_channels_blend_in_linear_light_and_stay_bytes():
    """sRGB-wire channels: the overlap decoded to linear light, cross-faded with the same weights
    as half floats, encoded again; the columns a channel shows alone are its bytes as sent."""
    from services.rig.colour import decode_srgb8, linear_to_srgb8

    chans = widened(5.0, width=300, outer=True)
    plan = blend_plan(chans, BlendSpec(overlap_deg=10.0))
    n = plan.overlaps[0]
    levels = [np.full((4, 300, 3), v, np.uint8) for v in (40, 200, 90)]
    composite = compose(frame_of(levels), plan)
    assert composite.rgb.dtype == np.uint8 and composite.rgb.shape == (4, plan.stitched_width, 3)
    assert np.all(composite.rgb[:, :plan.offsets[1]] == 40)
    assert np.all(composite.rgb[:, plan.offsets[1] + n:plan.offsets[2]] == 200)
    a, b = (decode_srgb8(np.array([v], np.uint8))[0] for v in (40, 200))
    expected = linear_to_srgb8(a * plan.right_weights[0] + b * plan.left_weights[1])
    np.testing.assert_array_equal(composite.rgb[0, plan.offsets[1]:plan.offsets[1] + n, 0], expected)
    # A uniform picture stays uniform across the seams (the weights sum to one in linear light).
    uniform = compose(frame_of([np.full((4, 300, 3), 123, np.uint8) for _ in range(3)]), plan)
    assert np.all(uniform.rgb == 123)
