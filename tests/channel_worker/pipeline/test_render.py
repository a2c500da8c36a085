"""The whole pipeline on hard cases: no NaN, correct ranges, far from the origin."""

import math

import numpy as np
import pytest

from channel_worker.pipeline.render import render_frame
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions
from services.rig.report import FrameReport

CH = ChannelSpec.symmetric("c", 64, 48, 60.0)


def scene(make_scene, box_model_factory, origin=(0.0, 0.0)):
    ox, oy = origin
    return make_scene({"b": box_model_factory(10, 10, 10, "#ff0000")},
                      [{"model": "b", "position": [ox, oy + 100.0, 0.0]}])


def test_box_in_front_has_the_right_range(make_scene, box_model_factory):
    db = scene(make_scene, box_model_factory)
    img = render_frame(db, CH, Eyepoint.of(0, 0, 5, 0, 0, 0), RenderOptions(samples=1))
    # the pixel at the centre of the raster looks straight at the box's south face (y = 95)
    assert img.range_m[24, 32] == pytest.approx(math.hypot(95.0, 0.5 * math.tan(math.radians(30)) * 95 / 32),
                                                rel=0.01)
    assert np.isinf(img.range_m[0, 0])  # sky
    # earth below: range = height / sin(depression) for the bottom-centre pixel
    fy = math.tan(math.radians(30)) * 48 / 64
    ty = fy * (24 - 47.5) / 24
    expected = 5.0 * math.sqrt(1 + ty * ty + (0.5 / 32 * math.tan(math.radians(30))) ** 2) / -ty
    assert img.range_m[47, 32] == pytest.approx(expected, rel=1e-3)


@pytest.mark.parametrize("hpr", [(0, 90, 0), (0, -90, 0), (359.5, 0, 180), (123, 89.999, 77), (0, -90, 180)])
def test_extreme_attitudes_have_no_nan(make_scene, box_model_factory, hpr):
    db = scene(make_scene, box_model_factory)
    img = render_frame(db, CH, Eyepoint.of(0, 90, 5, *hpr), RenderOptions(samples=4))
    assert np.isfinite(img.rgb).all()
    assert not np.isnan(img.range_m).any()


def test_looking_straight_down_sees_only_earth_at_the_height(make_scene, box_model_factory):
    db = scene(make_scene, box_model_factory)
    img = render_frame(db, CH, Eyepoint.of(0, -500, 50, 0, -90, 0), RenderOptions(samples=1))
    np.testing.assert_allclose(img.rgb, np.broadcast_to(db.earth_colour, img.rgb.shape), rtol=1e-6)
    assert img.range_m.min() >= 50.0 - 1e-3


def test_1000_km_from_origin_matches_the_origin(make_scene, box_model_factory):
    near = render_frame(scene(make_scene, box_model_factory), CH, Eyepoint.of(0, 0, 5, 10, 2, 3),
                        RenderOptions(samples=4))
    far_db = scene(make_scene, box_model_factory, origin=(1.0e6, -1.0e6))
    far = render_frame(far_db, CH, Eyepoint.of(1.0e6, -1.0e6, 5, 10, 2, 3), RenderOptions(samples=4))
    np.testing.assert_allclose(far.rgb, near.rgb, atol=1e-6)
    np.testing.assert_allclose(far.range_m, near.range_m, rtol=1e-6)


def test_eye_below_earth_is_clamped_not_nan(make_scene, box_model_factory):
    img = render_frame(scene(make_scene, box_model_factory), CH, Eyepoint.of(0, 0, -3, 0, 0, 0),
                       RenderOptions(samples=1))
    assert np.isfinite(img.rgb).all()
    assert not np.isnan(img.range_m).any()


def test_translucent_face_blends_over_what_is_behind(make_scene, box_model_factory):
    glass = {"vertices": [[-20, 0, 0], [20, 0, 0], [20, 0, 30], [-20, 0, 30]],
             "faces": [{"indices": [0, 1, 2, 3], "colour": "#ffffff", "opacity": 0.5}]}
    db = make_scene({"b": box_model_factory(10, 10, 10, "#ff0000"), "g": glass},
                    [{"model": "b", "position": [0, 100, 0]}, {"model": "g", "position": [0, 50, 0]}])
    img = render_frame(db, CH, Eyepoint.of(0, 0, 5, 0, 0, 0), RenderOptions(samples=1))
    px = img.rgb[24, 32]
    np.testing.assert_allclose(px, 0.5 * np.array([1, 1, 1]) + 0.5 * np.array([1, 0, 0]), atol=1e-6)
    assert img.range_m[24, 32] > 90  # range stays the opaque feature's


def test_stage_times_are_reported_in_order(make_scene, box_model_factory):
    db = scene(make_scene, box_model_factory)
    eye = Eyepoint.of(0, 0, 5, 0, 0, 0)
    common = ["view", "cull", "transform", "backface", "clip", "project", "edges", "binning", "visibility"]
    # Box filter: pixels come straight out of each sub-area (no separate resolve pass).
    report = FrameReport()
    render_frame(db, CH, eye, report=report)
    assert list(report.stage_seconds) == common
    report = FrameReport()
    render_frame(db, CH, eye, RenderOptions(filter="tent"), report=report)
    assert list(report.stage_seconds) == common + ["resolve"]


@pytest.mark.parametrize("samples", ["centre", "rgss4", "d3d16"])
@pytest.mark.parametrize("with_range", [True, False])
def test_fused_box_path_equals_sample_store_and_resolve(samples, with_range):
    """The default fast path (box filter inside each sub-area) and the sample store + resolve
    stage give the same image, on the bundled airfield with its translucent tower glass."""
    from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
    db = load_scene(bundled_scene_path())
    ch = ChannelSpec.symmetric("c", 160, 96, 60.0)
    # The control tower (its glass cab at 17.6-20.6 m) 60 m ahead, hangars and sky behind.
    eye = Eyepoint.of(-140.0, -660.0, 19.0, 0.0, 2.0, 5.0)
    options = RenderOptions(samples=samples, with_range=with_range, max_translucent=1)
    fused_report = FrameReport()
    fused = render_frame(db, ch, eye, options, report=fused_report)
    trace: dict = {}
    stored_report = FrameReport()
    stored = render_frame(db, ch, eye, options, trace=trace, report=stored_report)
    assert (trace["buffer"].translucent_count > 0).any()
    assert fused_report.counters == stored_report.counters
    np.testing.assert_allclose(fused.rgb, stored.rgb, rtol=0, atol=2e-6)
    if with_range:
        np.testing.assert_allclose(fused.range_m, stored.range_m, rtol=1e-6)
    else:
        assert fused.range_m is None and stored.range_m is None


def test_unknown_sample_pattern_is_named(make_scene, box_model_factory):
    with pytest.raises(ValueError, match="samples: unknown pattern 'foo'"):
        render_frame(scene(make_scene, box_model_factory), CH, Eyepoint.of(0, 0, 5, 0, 0, 0),
                     RenderOptions(samples="foo"))
    with pytest.raises(ValueError, match="samples: 3 has no pattern"):
        render_frame(scene(make_scene, box_model_factory), CH, Eyepoint.of(0, 0, 5, 0, 0, 0), RenderOptions(samples=3))


def test_nan_eyepoint_is_refused_naming_the_field(make_scene, box_model_factory):
    with pytest.raises(ValueError, match=r"eyepoint.position\[1\]: nan is not finite"):
        render_frame(scene(make_scene, box_model_factory), CH, Eyepoint.of(0, float("nan"), 5, 0, 0, 0))


def test_colours_can_be_written_into_the_callers_array(make_scene, box_model_factory):
    db = scene(make_scene, box_model_factory)
    eye = Eyepoint.of(0, 0, 5, 0, 0, 0)
    expect = render_frame(db, CH, eye)
    out = np.full((CH.height, CH.width, 3), np.nan, np.float32)
    for filter in ("box", "tent"):
        got = render_frame(db, CH, eye, RenderOptions(filter=filter), out=out)
        assert got.rgb is out and np.isfinite(out).all()
    np.testing.assert_array_equal(render_frame(db, CH, eye, out=out).rgb, expect.rgb)
    with pytest.raises(ValueError, match=r"out: expected a C-contiguous float32 array of shape \(48, 64, 3\)"):
        render_frame(db, CH, eye, out=np.zeros((48, 64, 3), np.float64))


def test_a_full_translucent_store_drops_the_farthest_and_says_so(make_scene, box_model_factory):
    """Two panes in front of a wall, a store of one: the near pane is kept, the far one counted."""
    def pane(y: float, colour: str) -> dict:
        v = [[-50, y, -50], [50, y, -50], [50, y, 50], [-50, y, 50]]
        return {"vertices": v, "faces": [{"indices": [0, 1, 2, 3], "colour": colour, "opacity": 0.5}]}
    db = make_scene({"wall": box_model_factory(200, 1, 200, "#ffffff"), "near": pane(20, "#ff0000"),
                     "far": pane(30, "#0000ff")},
                    [{"model": "wall", "position": [0, 100, -100]}, {"model": "near", "position": [0, 0, 5]},
                     {"model": "far", "position": [0, 0, 5]}])
    eye = Eyepoint.of(0, 0, 5, 0, 0, 0)
    for filter in ("box", "tent"):
        report = FrameReport()
        img = render_frame(db, CH, eye, RenderOptions(samples=1, max_translucent=1, filter=filter),
                           report=report)
        assert report.counters["translucent_dropped"] == CH.width * CH.height
        np.testing.assert_allclose(img.rgb[24, 32], [0.5 + 0.5, 0.5, 0.5], atol=1e-6)
        report = FrameReport()
        img = render_frame(db, CH, eye, RenderOptions(samples=1, max_translucent=2, filter=filter),
                           report=report)
        assert report.counters["translucent_dropped"] == 0
        np.testing.assert_allclose(img.rgb[24, 32], [0.5 + 0.25, 0.25, 0.25 + 0.25], atol=1e-6)


@pytest.mark.parametrize("renderer", ["subarea", "scanline"])
def test_two_threads_draw_what_one_draws(renderer):
    """Threads take runs of sub-areas, rows of cloud blocks, bands and blocks of terrain lines
    (two threads: blocks of other sizes) from work queues (jit.claim); every pixel is still
    computed by one thread with the same arithmetic, so the demo scene (terrain, clouds, fog,
    haze, the airfield; the scan-line renderer draws the airfield alone) comes out bit for bit
    the same."""
    from channel_worker.pipeline.jit import thread_pool_size
    from channel_worker.pipeline.scene.load import bundled_scene_path, demo_scene_path, load_scene
    if thread_pool_size() < 2:
        pytest.skip(f"numba was started with {thread_pool_size()} thread (NUMBA_NUM_THREADS)")
    db = load_scene(bundled_scene_path() if renderer == "scanline" else demo_scene_path())
    ch = ChannelSpec.symmetric("c", 200, 150, 60.0)
    # Banked over the runway threshold: sky, cloud, terrain and polygons in every row band.
    eye = Eyepoint.of(0.0, -1500.0, 120.0, 20.0, -3.0, 25.0)
    samples = "centre" if renderer == "scanline" else "rgss4"
    images = []
    for threads in (1, 2):
        options = RenderOptions(samples=samples, with_range=True, threads=threads, renderer=renderer)
        report = FrameReport()
        images.append((render_frame(db, ch, eye, options, report=report), report.counters))
    (one, one_counters), (two, two_counters) = images
    assert one_counters == two_counters
    np.testing.assert_array_equal(one.rgb, two.rgb)
    np.testing.assert_array_equal(one.range_m, two.range_m)
