"""Analytic edge coverage (RenderOptions.coverage = "area", shade/_coverage_kernels.py).

- the closed-form area of a line clipping the pixel square, against shapely, on random lines
  and on the awkward ones (parallel to an axis, through a corner, missing the square);
- on random eye-facing quads (channel_worker/testing/quads.py) against the exact area coverage
  (coverage_reference.py): the RMSE targets per sample count, never worse than the samples
  alone, and every pixel the area decided that the reference calls single-edge is exact;
- a mesh's shared edge stays watertight: one colour either side gives exactly that colour;
- the fused box path and the sample store + resolve agree, with terrain, haze, fog and clouds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import example, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import demo_scene_path, load_scene, parse_scene
from channel_worker.pipeline.shade._coverage_kernels import square_fraction
from channel_worker.testing.coverage_reference import (
    ReferencePixels,
    depth_order,
    reference_pixels,
    sky_backdrop,
)
from channel_worker.testing.quads import QUADS_EYEPOINT, QUADS_FOV_DEG, quads_scene_doc
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

#: float32 colours of a pixel mixed from two features.
FLOAT_TOL = 1e-5
#: The acceptance targets at 640 x 480 on 200 quads: RMSE per pattern with coverage "area"
#: (rgss4: 0.6 x llvmpipe 4x MSAA's 0.0083 on the same kind of scene).
TARGETS = {"rgss4": 0.005, "d3d8": 0.004, "d3d16": 0.003}


def _shapely_fraction(a: float, b: float, c: float) -> float:
    """Area of the unit square where a u + b v + c > 0, by clipping with a large half-plane."""
    n = math.hypot(a, b)
    if n == 0.0:
        return 1.0 if c > 0.0 else 0.0
    nx, ny, d = a / n, b / n, c / n
    px, py = -d * nx, -d * ny  # the foot of the line nearest the origin
    tx, ty, r = -ny, nx, 10.0 + abs(d)
    half = shapely.Polygon([(px - r * tx, py - r * ty), (px + r * tx, py + r * ty),
                            (px + r * tx + r * nx, py + r * ty + r * ny),
                            (px - r * tx + r * nx, py - r * ty + r * ny)])
    return float(shapely.intersection(shapely.box(0.0, 0.0, 1.0, 1.0), half).area)


_ANGLES = st.one_of(st.floats(0.0, 2.0 * math.pi),
                    st.sampled_from([0.0, math.pi / 2, math.pi, 1.5 * math.pi, math.pi / 4,
                                     0.75 * math.pi, 1e-9, math.pi / 2 + 1e-12]))
#: A point the line passes through: anywhere near the square, or one of its corners.
_POINTS = st.one_of(st.tuples(st.floats(-0.5, 1.5), st.floats(-0.5, 1.5)),
                    st.sampled_from([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]))


@settings(max_examples=400, deadline=None)
@given(theta=_ANGLES, through=_POINTS, scale=st.sampled_from([1.0, 256.0, 3.0e5]))
@example(theta=0.0, through=(0.25, 0.0), scale=1.0)         # vertical line x = 0.25
@example(theta=math.pi / 2, through=(0.0, 0.7), scale=1.0)  # horizontal
@example(theta=math.pi / 4, through=(1.0, 0.0), scale=1.0)  # a diagonal through two corners
@example(theta=math.pi / 4, through=(3.0, 3.0), scale=1.0)  # misses the square: nothing inside
@example(theta=math.pi / 4, through=(-3.0, -3.0), scale=1.0)  # misses: all inside
def test_square_fraction_is_the_clipped_area(theta, through, scale):
    a, b = math.cos(theta) * scale, math.sin(theta) * scale
    c = -(a * through[0] + b * through[1])
    got = square_fraction(a, b, c)
    assert 0.0 <= got <= 1.0
    assert got == pytest.approx(_shapely_fraction(a, b, c), abs=1e-9)
    # The other side of the line has the rest.
    assert got + square_fraction(-a, -b, -c) == pytest.approx(1.0, abs=1e-12)


def test_square_fraction_without_a_line_is_the_sign_of_c():
    assert square_fraction(0.0, 0.0, 1.0) == 1.0
    assert square_fraction(0.0, 0.0, -1.0) == 0.0


# --- Random eye-facing quads against the exact area coverage ---------------------------------

W, H = 640, 480


def _quads(seed: int) -> tuple:
    db = parse_scene(quads_scene_doc(seed=seed), source="quads")
    ch = ChannelSpec.symmetric("quads", W, H, QUADS_FOV_DEG)
    eye = Eyepoint.of(*QUADS_EYEPOINT)
    trace: dict = {}
    render_frame(db, ch, eye, RenderOptions(samples="centre"), trace=trace)
    screen = trace["screen"]
    return db, ch, eye, reference_pixels(screen, W, H, depth_order(screen), sky_backdrop(db))


@pytest.fixture(scope="module", params=[2027, 11])
def quads(request):
    return _quads(request.param)


def _rmse(image: np.ndarray, ref: ReferencePixels) -> float:
    return float(np.sqrt(np.mean((image - ref.rgb) ** 2)))


@pytest.mark.parametrize("pattern", ["centre", "d3d2", "rgss4", "d3d8", "d3d16"])
def test_area_meets_the_targets_and_is_never_worse_than_samples(quads, pattern):
    db, ch, eye, ref = quads
    images = {c: render_frame(db, ch, eye, RenderOptions(samples=pattern, coverage=c,
                                                         with_range=False)).rgb.astype(np.float64)
              for c in ("samples", "area")}
    err = {c: _rmse(im, ref) for c, im in images.items()}
    print(pattern, err)
    assert err["area"] <= err["samples"] + 1e-5
    if pattern in TARGETS:
        assert err["area"] <= TARGETS[pattern]
        # The area did the work: at least a third less than the samples' error.
        assert err["area"] < 0.67 * err["samples"]
    # Every pixel the area decided that is truly one straight edge between two regions is
    # exact (the rest it decided hide a third region no sample saw: samples miss it too).
    decided = np.abs(images["area"] - images["samples"]).max(axis=2) > 0
    off = np.abs(images["area"] - ref.rgb).max(axis=2)
    assert (off[decided & ref.single_edge] <= FLOAT_TOL).all()
    if pattern != "centre":  # one sample never sees two features
        assert (decided & ref.single_edge).sum() > 1000


def test_the_tent_filter_and_one_sample_ignore_the_setting(quads):
    db, ch, eye, _ = quads
    for options in (RenderOptions(samples="rgss4", filter="tent"), RenderOptions(samples="centre")):
        a = render_frame(db, ch, eye, options.replace(coverage="area")).rgb
        s = render_frame(db, ch, eye, options.replace(coverage="samples")).rgb
        np.testing.assert_array_equal(a, s)


# --- Watertight: a mesh's shared edge ---------------------------------------------------------

def _two_faces(colours: tuple[str, str], diagonal: float) -> dict:
    """A 6 x 8 m rectangle 2 m above an eye looking up (it fills the view), made of two
    rectangles either side of a line through its centre at `diagonal` radians: two faces of
    one model sharing that edge."""
    c, s = math.cos(diagonal), math.sin(diagonal)
    ends = [(3.0 * c, 3.0 * s), (-3.0 * c, -3.0 * s)]
    left = [ends[0], (-4.0 * s + 3 * c, 4.0 * c + 3 * s), (-4.0 * s - 3 * c, 4.0 * c - 3 * s), ends[1]]
    right = [ends[1], (4.0 * s - 3 * c, -4.0 * c - 3 * s), (4.0 * s + 3 * c, -4.0 * c + 3 * s), ends[0]]
    verts, faces = [], []
    for outline, colour in zip((left, right), colours, strict=True):
        pts = [[x, y, 2.0] for x, y in outline]
        if np.dot(np.cross(np.subtract(pts[1], pts[0]), np.subtract(pts[2], pts[0])), pts[0]) > 0:
            pts = pts[::-1]
        faces.append({"indices": list(range(len(verts), len(verts) + 4)), "colour": colour})
        verts += pts
    return {"format": "ig-scene/1", "sky": {"colour": "#3060c0"},
            "earth": {"colour": "#406020", "height_m": 0.0}, "lighting": {"ambient": 1.0},
            "models": {"m": {"vertices": verts, "faces": faces}},
            "instances": [{"model": "m", "position": [0.0, 0.0, 0.0]}]}


@pytest.mark.parametrize("pattern", ["rgss4", "d3d16"])
@pytest.mark.parametrize("diagonal", [0.3, 1.1, math.pi / 4, 0.0])
def test_a_shared_edge_between_one_colour_is_that_colour_everywhere(pattern, diagonal):
    db = parse_scene(_two_faces(("#b06030", "#b06030"), diagonal), source="mesh")
    ch = ChannelSpec.symmetric("m", 96, 64, 60.0)
    eye = Eyepoint.of(0.0, 0.0, 0.0, 0.0, 90.0, 0.0)
    for filter_ in ("box", "tent"):
        trace: dict = {}
        img = render_frame(db, ch, eye, RenderOptions(samples=pattern, filter=filter_), trace=trace).rgb
        assert trace["screen"].polygon_count == 2
        np.testing.assert_array_equal(img, np.broadcast_to(db.models[0].colour[0], img.shape))


@pytest.mark.parametrize("diagonal", [0.3, 1.1])
def test_a_shared_edge_between_two_colours_is_exact(diagonal):
    """Both faces cross the pixel by the same edge, reversed: the area decides every pixel
    whose samples see both (where they all fall on one side, their count stays: nothing
    tells what the other side is)."""
    db = parse_scene(_two_faces(("#b06030", "#2040ff"), diagonal), source="mesh")
    ch = ChannelSpec.symmetric("m", 96, 64, 60.0)
    eye = Eyepoint.of(0.0, 0.0, 0.0, 0.0, 90.0, 0.0)
    trace: dict = {}
    render_frame(db, ch, eye, RenderOptions(samples="centre"), trace=trace)
    screen = trace["screen"]
    ref = reference_pixels(screen, 96, 64, depth_order(screen), sky_backdrop(db))
    assert ref.single_edge.sum() > 60
    img = render_frame(db, ch, eye, RenderOptions(samples="rgss4")).rgb
    samples = render_frame(db, ch, eye, RenderOptions(samples="rgss4", coverage="samples")).rgb
    decided = np.abs(img - samples).max(axis=2) > 0
    assert decided.sum() > 40 and (decided <= ref.single_edge).all()
    np.testing.assert_allclose(img[decided], ref.rgb[decided], rtol=0, atol=FLOAT_TOL)
    # Everywhere else the samples' estimate, within the pattern's discrepancy (0.31).
    np.testing.assert_allclose(img, ref.rgb, rtol=0, atol=0.31 * 1.0 + FLOAT_TOL)


# --- The two box paths agree ------------------------------------------------------------------

def test_fused_equals_store_and_resolve_on_quads(quads):
    db, ch, eye, _ = quads
    for pattern in ("rgss4", "d3d16"):
        options = RenderOptions(samples=pattern)
        fused = render_frame(db, ch, eye, options).rgb
        stored = render_frame(db, ch, eye, options, trace={}).rgb
        np.testing.assert_array_equal(fused, stored)


def test_fused_equals_store_and_resolve_through_the_atmosphere():
    """The demo scene: terrain, haze, layered fog and clouds; the area applies there too.

    With ranges both paths shade every mixed pixel's samples alike. Without, the fused path
    shades a pixel whose samples all see one polygon through the air at the pixel's centre
    (box_subarea), the resolve stage at each sample: they differed there before the area
    coverage (up to 0.011 on this view), and the area adds no pixel to that difference.
    """
    db = load_scene(demo_scene_path())
    ch = ChannelSpec.symmetric("c", 160, 96, 60.0)
    eye = Eyepoint.of(-140.0, -660.0, 19.0, 0.0, 2.0, 5.0)
    options = RenderOptions(samples="rgss4", with_range=True)
    fused = render_frame(db, ch, eye, options)
    stored = render_frame(db, ch, eye, options, trace={})
    np.testing.assert_allclose(fused.rgb, stored.rgb, rtol=0, atol=2e-6)
    samples = render_frame(db, ch, eye, options.replace(coverage="samples"))
    assert (np.abs(fused.rgb - samples.rgb).max(axis=2) > 1e-4).sum() > 20
    np.testing.assert_array_equal(fused.range_m, samples.range_m)  # the samples' nearest
    differ = {}
    for coverage in ("area", "samples"):
        options = RenderOptions(samples="rgss4", with_range=False, coverage=coverage)
        fused_rgb = render_frame(db, ch, eye, options).rgb
        stored_rgb = render_frame(db, ch, eye, options, trace={}).rgb
        differ[coverage] = np.abs(fused_rgb - stored_rgb).max(axis=2) > 2e-6
    np.testing.assert_array_equal(differ["area"], differ["samples"])
