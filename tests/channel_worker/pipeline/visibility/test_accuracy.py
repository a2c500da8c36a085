"""Anti-aliasing accuracy: box-filtered pixels against exact area coverage (shapely).

Scenes are flat plates facing the eye at distinct depths, so the visibility order is known
and the exact box-filtered image can be computed by polygon clipping
(channel_worker/testing/coverage_reference.py) from the frame's own snapped screen polygons.
The difference is then pure sampling error, which is bounded per pixel:

- a pixel that one region of constant colour covers (one visible plate, a translucent overlap,
  or sky) must come out exact: every sample sees the same colour (float32 rounding only);
- a pixel crossed by one straight boundary between two regions of colours A and B: the
  renderer returns k/S of one and the exact answer is a, the area on that side, so the error
  is |k/S - a| * |A - B| <= D_S * |A - B|, where D_S is the pattern's half-plane discrepancy
  (coverage_reference.half_plane_discrepancy, computed from the offsets, not assumed). For
  these patterns D_S is 0.5, 0.5, 0.309, 0.227, 0.172 for S = 1, 2, 4, 8, 16: at most
  0.7 / sqrt(S), the usual ~1/sqrt(S) shape, but the measured constant is what is asserted;
- any other pixel (corners, crossings, slivers thinner than the sample spacing) can be off
  by up to the largest colour difference inside it; a broken renderer (a missing plate, wrong
  compositing, a shifted edge) is caught by the first two rules.

RMSE over the image is bounded by the root mean square of those per-pixel bounds, and on a
fixed scene more samples must give a lower RMSE, strictly, pattern after pattern.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from channel_worker.pipeline.contract import SUBPIXEL, ScreenPolygons
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.render import render_frame
from channel_worker.testing.coverage_reference import (
    ReferencePixels,
    depth_order,
    half_plane_discrepancy,
    horizon_backdrop,
    reference_pixels,
    sky_backdrop,
)
from channel_worker.testing.plates import PLATES, plates_model
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

PATTERNS = ["centre", "d3d2", "rgss4", "d3d8", "d3d16"]
W, H = 64, 48
CH = ChannelSpec.symmetric("acc", W, H, 60.0)
#: float32 colours averaged over at most 16 samples.
FLOAT_TOL = 1e-5
NONE = {"one_region": 0, "single_edge": 0, "any": 0, "rmse": 0}

@pytest.fixture
def overhead(make_scene):
    """Plates overhead, the eye looking straight up: only plates and sky in view."""
    model = plates_model(lambda u, v, d: (u * d, v * d, d))
    db = make_scene({"plates": model}, [{"model": "plates", "position": [0.0, 0.0, 1.5]}],
                    sky="#3060c0", earth="#406020")
    return db, Eyepoint.of(0.0, 0.0, 1.5, 0.0, 90.0, 0.0)


def render_and_reference(db, eye, pattern,
                         backdrop) -> tuple[np.ndarray, ReferencePixels, np.ndarray]:
    """The default (fused box filter) image, the exact reference from the frame's own screen
    polygons, and the sample offsets."""
    trace: dict = {}
    render_frame(db, CH, eye, RenderOptions(samples=pattern, filter="box"), trace=trace)
    image = render_frame(db, CH, eye, RenderOptions(samples=pattern, filter="box")).rgb.astype(np.float64)
    screen = trace["screen"]
    assert screen.polygon_count == len(PLATES)
    ref = reference_pixels(screen, W, H, depth_order(screen), backdrop)
    return image, ref, trace["buffer"].offsets


def pixel_bounds(ref: ReferencePixels, offsets: np.ndarray) -> np.ndarray:
    """(H, W) largest sampling error each pixel may show (see the module docstring)."""
    d_s = half_plane_discrepancy(offsets) + 1e-3  # the sup over directions to 1e-4
    bound = np.where(ref.single_edge, d_s * ref.contrast, ref.contrast)
    return bound + FLOAT_TOL


def violations(image: np.ndarray, ref: ReferencePixels, offsets: np.ndarray) -> dict[str, int]:
    """How many pixels break each rule, and whether the RMSE breaks its bound."""
    err = np.abs(image - ref.rgb).max(axis=2)
    bound = pixel_bounds(ref, offsets)
    one = ref.pieces == 1
    return {
        "one_region": int((err[one] > FLOAT_TOL).sum()),
        "single_edge": int((err[ref.single_edge] > bound[ref.single_edge]).sum()),
        "any": int((err > bound).sum()),
        "rmse": int(rmse(image, ref) > np.sqrt(np.mean(bound ** 2))),
    }


def rmse(image: np.ndarray, ref: ReferencePixels) -> float:
    return float(np.sqrt(np.mean((image - ref.rgb) ** 2)))


def report(name: str, image: np.ndarray, ref: ReferencePixels, offsets: np.ndarray) -> str:
    err = np.abs(image - ref.rgb).max(axis=2)
    bound = pixel_bounds(ref, offsets)
    return (f"{name:7s} S={offsets.shape[0]:2d} rmse={rmse(image, ref):.4f} "
            f"(bound {np.sqrt(np.mean(bound ** 2)):.4f}) max_abs={err.max():.4f} "
            f"max_abs_single_edge={err[ref.single_edge].max():.4f} "
            f"(D_S={half_plane_discrepancy(offsets):.3f}) "
            f"one_region_max={err[ref.pieces == 1].max():.1e}")


@pytest.mark.parametrize("pattern", PATTERNS)
def test_each_pattern_is_within_its_sampling_bound(overhead, pattern):
    db, eye = overhead
    image, ref, offsets = render_and_reference(db, eye, pattern, sky_backdrop(db))
    print(report(pattern, image, ref, offsets))
    # The scene exercises every rule: uniform pixels, single edges and complex pixels.
    assert (ref.pieces == 1).sum() > 1000 and ref.single_edge.sum() > 300
    assert ((ref.pieces > 2) | ((ref.pieces == 2) & ~ref.convex)).sum() > 50
    assert violations(image, ref, offsets) == NONE


def test_more_samples_give_a_lower_rmse(overhead):
    db, eye = overhead
    errors = []
    for pattern in PATTERNS:
        image, ref, offsets = render_and_reference(db, eye, pattern, sky_backdrop(db))
        errors.append(rmse(image, ref))
        print(report(pattern, image, ref, offsets))
    assert all(a > b for a, b in itertools.pairwise(errors)), errors
    # D_S falls from 0.5 to 0.17 from 1 to 16 samples; the RMSE must fall at least as much.
    assert errors[-1] < 0.35 * errors[0], errors


@pytest.mark.parametrize("pattern", ["rgss4", "d3d16"])
def test_horizon_edge_is_within_its_sampling_bound(make_scene, pattern):
    """Upright plates ahead of a rolled eye: plate edges against sky and earth, and the
    horizon line itself, anti-aliased like any other edge."""
    model = plates_model(lambda u, v, d: (u * d, d, v * d))
    db = make_scene({"plates": model}, [{"model": "plates", "position": [0.0, 0.0, 2.0]}],
                    sky="#3060c0", earth="#406020")
    eye = Eyepoint.of(0.0, 0.0, 2.0, 0.0, 2.0, 20.0)
    image, ref, offsets = render_and_reference(db, eye, pattern,
                                               horizon_backdrop(db, make_view(CH, eye)))
    print(report(pattern, image, ref, offsets))
    assert violations(image, ref, offsets) == NONE


def test_the_bounds_reject_wrong_images(overhead):
    """The rules are tight enough to catch an under-sampled, a shifted and an incomplete
    image: each must fail where the correct one passes."""
    db, eye = overhead
    good, ref, offsets = render_and_reference(db, eye, "d3d16", sky_backdrop(db))
    point_sampled, _, _ = render_and_reference(db, eye, "centre", sky_backdrop(db))
    assert violations(point_sampled, ref, offsets)["single_edge"] > 20
    shifted = np.roll(good, 1, axis=1)
    assert violations(shifted, ref, offsets)["one_region"] > 20
    # Without the nearest (translucent) plate the pixels it covers are wrong.
    without = reference_pixels(_screen(db, eye), W, H, depth_order(_screen(db, eye))[1:],
                               sky_backdrop(db))
    assert violations(without.rgb, ref, offsets)["one_region"] > 20


def _screen(db, eye):
    trace: dict = {}
    render_frame(db, CH, eye, RenderOptions(samples="centre"), trace=trace)
    return trace["screen"]


# The reference itself, against areas worked out by hand, before it judges the renderer.


def _polys(quads: list[list[tuple[float, float]]], inv_z: list[float], colours, opacity):
    fixed = np.concatenate([np.round(np.array(q) * SUBPIXEL).astype(np.int64)[::-1]
                            for q in quads])  # listed clockwise in y-up: reversed is y-down CW
    n = len(quads)
    return ScreenPolygons(fixed=fixed, start=np.arange(n + 1, dtype=np.int64) * 4,
                          inv_z=np.array([[0.0, 0.0, z] for z in inv_z]),
                          colour=np.array(colours, np.float32), opacity=np.array(opacity, np.float32),
                          feature_id=np.arange(n, dtype=np.int32), layer=np.zeros(n, np.int16))


def test_reference_areas_and_compositing_by_hand():
    # White from (0.25, 0.5) to past the raster's corner; half-transparent red over column 0.
    white = [(0.25, 0.5), (2.5, 0.5), (2.5, 2.5), (0.25, 2.5)]
    red = [(0.0, 0.0), (1.0, 0.0), (1.0, 2.0), (0.0, 2.0)]
    screen = _polys([white, red], [0.5, 1.0], [[1, 1, 1], [1, 0, 0]], [1.0, 0.5])
    order = depth_order(screen)
    assert list(order) == [1, 0]
    ref = reference_pixels(screen, 2, 2, order, np.zeros(3))
    # Pixel (0, 0): red (alpha 0.5) over white on 0.75 x 0.5 of it, black elsewhere.
    np.testing.assert_allclose(ref.rgb[0, 0], [0.5 + 0.5 * 0.375, 0.5 * 0.375, 0.5 * 0.375])
    assert ref.pieces[0, 0] == 2 and not ref.single_edge[0, 0]  # an L-shaped boundary
    # Pixel (1, 0): white below y = 0.5; pixel (0, 1): red over white right of x = 0.25.
    np.testing.assert_allclose(ref.rgb[0, 1], [0.5] * 3)
    np.testing.assert_allclose(ref.rgb[1, 0], [0.875, 0.375, 0.375])
    assert ref.single_edge[0, 1] and ref.single_edge[1, 0]
    np.testing.assert_allclose(ref.contrast[[0, 1], [1, 0]], [1.0, 0.5])
    # Pixel (1, 1): all white.
    np.testing.assert_allclose(ref.rgb[1, 1], [1.0] * 3)
    assert ref.pieces[1, 1] == 1 and ref.contrast[1, 1] == 0.0


def test_reference_refuses_interpenetrating_polygons():
    a = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    screen = _polys([a, a], [0.5, 1.0], [[1, 1, 1], [0, 0, 0]], [1.0, 1.0])
    tilted = np.array([[0.0, 0.0, 0.5], [0.5, 0.0, 0.0]])  # 1/z crosses 0.5 at x = 1
    screen = screen._replace(inv_z=tilted)
    with pytest.raises(ValueError, match="no single depth order"):
        depth_order(screen)


def test_half_plane_discrepancy_by_hand():
    assert half_plane_discrepancy(np.array([[0.5, 0.5]])) == pytest.approx(0.5)
    grid = (np.stack(np.meshgrid(np.arange(4), np.arange(4)), -1).reshape(-1, 2) + 0.5) / 4
    assert half_plane_discrepancy(grid) == pytest.approx(1 / 8, abs=1e-3)
