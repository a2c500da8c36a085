"""Sub-area binning and multi-sample visibility against a brute-force per-sample reference."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.binning.binning import bin_features
from channel_worker.pipeline.binning.edges import setup_edges
from channel_worker.pipeline.contract import EARTH_ID, SKY_ID, SUBPIXEL, ScreenPolygons
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.visibility.visibility import coverage_counts
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

from ..conftest import screen_polygons, store

W, H = 40, 24
# Looking straight up: every uncovered sample sees the sky.
UP = Eyepoint.of(0.0, 0.0, 10.0, 0.0, 90.0, 0.0)
VIEW = make_view(ChannelSpec.symmetric("t", W, H, 60.0), UP)


def brute_force(screen: ScreenPolygons, offsets: np.ndarray, k: int):
    """Per sample: nearest opaque index (or -1) and the nearer translucent ones, nearest first."""
    off = np.round(offsets * SUBPIXEL).astype(np.int64)
    ys, xs = np.mgrid[0:H, 0:W]
    px = xs[..., None] * SUBPIXEL + off[None, None, :, 0]
    py = ys[..., None] * SUBPIXEL + off[None, None, :, 1]
    inside, depth = [], []
    for p in range(screen.polygon_count):
        v = screen.fixed[screen.start[p]:screen.start[p + 1]]
        ok = np.ones(px.shape, bool)
        for i in range(len(v)):
            x0, y0 = v[i]
            dx, dy = v[(i + 1) % len(v)] - v[i]
            e = (px - x0) * dy - (py - y0) * dx
            ok &= e >= (0 if (dy > 0 or (dy == 0 and dx < 0)) else 1)
        a, b, c = screen.inv_z[p]
        inside.append(ok)
        depth.append(a * (px * (1.0 / SUBPIXEL)) + b * (py * (1.0 / SUBPIXEL)) + c)
    def key(p, m):
        return depth[p][m], int(screen.layer[p]), -p

    opaque = np.full(px.shape, -1)
    trans = {}
    for m in np.ndindex(px.shape):
        cover = [p for p in range(screen.polygon_count) if inside[p][m]]
        opq = [p for p in cover if screen.opacity[p] >= 1.0]
        best = max(opq, key=lambda p: key(p, m)) if opq else -1
        opaque[m] = best
        tr = [p for p in cover if screen.opacity[p] < 1.0 and (best < 0 or key(p, m) > key(best, m))]
        trans[m] = sorted(tr, key=lambda p: key(p, m), reverse=True)[:k]
    return opaque, trans


def random_scene(seed: int, n: int, translucent_share: float = 0.0) -> ScreenPolygons:
    rng = np.random.default_rng(seed)
    tris, planes, opacity = [], [], []
    while len(tris) < n:
        t = rng.integers([-300, -300], [W * SUBPIXEL + 300, H * SUBPIXEL + 300], size=(3, 2))
        if rng.random() < 0.3:  # vertices exactly on sub-area corners and sample points
            t = (t // (4 * SUBPIXEL)) * (4 * SUBPIXEL) + rng.choice([0, 128, 96], size=(3, 2))
        u, v = t[1] - t[0], t[2] - t[0]
        area2 = u[0] * v[1] - u[1] * v[0]
        if area2 == 0:
            continue
        tris.append(t)
        # 1/z planes positive over the raster, some tilted steeply.
        planes.append((rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(0.5, 1.0)))
        opacity.append(0.5 if rng.random() < translucent_share else 1.0)
    return screen_polygons(tris, planes, opacity)


@pytest.mark.parametrize("subarea", [1, 4, 8, 16, 32])
@pytest.mark.parametrize("pattern", ["centre", "rgss4", "d3d8"])
def test_visibility_matches_brute_force(subarea, pattern):
    offsets = RenderOptions(samples=pattern).sample_offsets()
    screen = random_scene(subarea * 7 + len(offsets), 14, translucent_share=0.4)
    buf = store(screen, VIEW, pattern, max_translucent=2, subarea=subarea)
    opaque, trans = brute_force(screen, offsets, 2)
    np.testing.assert_array_equal(np.where(buf.opaque >= 0, buf.opaque, -1), opaque)
    assert set(np.unique(buf.opaque[opaque < 0])) <= {SKY_ID}
    for m, expect in trans.items():
        got = list(buf.translucent[m][:buf.translucent_count[m]])
        assert got == expect, (m, got, expect)


@pytest.mark.parametrize("subarea", [5, 16, 64])
@pytest.mark.parametrize("pattern", ["rgss4", "d3d16"])
def test_opaque_masks_match_brute_force(subarea, pattern):
    # Opaque only: every sub-area takes the word-at-a-time merge. Odd sub-areas pack 12
    # sample rows into a word with 4 bits spare; 64 puts one sample row in each word.
    offsets = RenderOptions(samples=pattern).sample_offsets()
    screen = random_scene(subarea * 11 + len(offsets), 24)
    buf = store(screen, VIEW, pattern, subarea=subarea)
    opaque, _ = brute_force(screen, offsets, 1)
    np.testing.assert_array_equal(np.where(buf.opaque >= 0, buf.opaque, -1), opaque)


def test_features_behind_covered_samples_are_rejected_whole():
    # The nearest quad covers the left half; nine quads behind it lie inside the part of the
    # sub-areas at x 16..23 (subarea 8) that it covers. Those sub-areas are not wholly covered
    # (no early stop), so each of the nine is read and rejected by its box alone.
    def rect(x0, x1):
        return np.array([[x0 * SUBPIXEL, 0], [x1 * SUBPIXEL, 0], [x1 * SUBPIXEL, H * SUBPIXEL],
                         [x0 * SUBPIXEL, H * SUBPIXEL]])

    polys = [rect(0, 20)] + [rect(17, 19)] * 9 + [rect(0, W)]
    planes = ([(0.0, 0.0, 1.0)] + [(0.0, 0.0, 1.0 / (2.0 + k)) for k in range(9)]
              + [(0.0, 0.0, 0.01)])
    buf = store(screen_polygons(polys, planes), VIEW, "rgss4", subarea=8)
    assert (buf.opaque[:, :19] == 0).all()
    assert (buf.opaque[:, 21:] == 10).all()
    assert buf.stats["entries_hidden"] == 9 * (H // 8)


def test_fully_covered_subareas_are_covered_at_every_sample():
    offsets = RenderOptions(samples="d3d16").sample_offsets()
    screen = random_scene(5, 30)
    for size in (2, 4, 8):
        edges = setup_edges(screen, W, H)
        bins = bin_features(edges, screen.start, W, H, size)
        counts = coverage_counts(screen, W, H, offsets, subarea=size)
        reference = coverage_counts(screen, W, H, offsets, subarea=1)
        np.testing.assert_array_equal(counts, reference)
        assert bins.full.any() and not bins.full.all()


def test_translucent_store_keeps_the_nearest_k_and_counts_the_rest():
    quad = np.array([[0, 0], [W * SUBPIXEL, 0], [W * SUBPIXEL, H * SUBPIXEL], [0, H * SUBPIXEL]])
    # Opaque at 1/z 0.5 (z = 2); translucent at z = 1.9 .. 1.0 (nearer) and one at z = 3 (behind).
    planes = [(0.0, 0.0, 0.5)] + [(0.0, 0.0, 1.0 / z) for z in (1.9, 1.5, 1.2, 1.1, 1.0, 3.0)]
    screen = screen_polygons([quad] * 7, planes, [1.0] + [0.5] * 6)
    buf = store(screen, VIEW, "rgss4", max_translucent=3, subarea=8)
    assert (buf.opaque == 0).all()
    assert (buf.translucent_count == 3).all()
    assert (buf.translucent[..., 0] == 5).all() and (buf.translucent[..., 2] == 3).all()
    # Two of the five nearer translucent features are dropped at every sample.
    assert buf.stats["translucent_dropped"] == 2 * W * H * 4


def test_earth_and_sky_fill_uncovered_samples():
    view = make_view(ChannelSpec.symmetric("t", W, H, 60.0), Eyepoint.of(0, 0, 10, 0, 0, 0))
    screen = screen_polygons([np.array([[0, 0], [256, 0], [0, 256]])], [(0.0, 0.0, 0.5)])
    buf = store(screen, view, 1, subarea=8)
    assert (buf.opaque[: H // 2 - 1, 2:] == SKY_ID).all()
    assert (buf.opaque[H // 2 + 1:] == EARTH_ID).all()


def test_bad_store_and_subarea_sizes_are_named():
    screen = random_scene(1, 2)
    with pytest.raises(ValueError, match=r"subarea: .*0"):
        store(screen, VIEW, 1, subarea=0)
    with pytest.raises(ValueError, match=r"max_translucent: .*16"):
        store(screen, VIEW, 1, max_translucent=16)


def _decal_scene(make_scene):
    """A 400 x 400 m ground square with a 40 x 100 m stripe painted on it (layer 1) and a
    20 x 20 m patch on the stripe (layer 2), all in the plane z = 0.02."""
    z = 0.02
    v = [[-200, -200, z], [200, -200, z], [200, 200, z], [-200, 200, z],
         [-20, -50, z], [20, -50, z], [20, 50, z], [-20, 50, z],
         [-10, -10, z], [10, -10, z], [10, 10, z], [-10, 10, z]]
    faces = [{"indices": [0, 1, 2, 3], "colour": "#000000"},
             {"indices": [4, 5, 6, 7], "colour": "#ffffff", "on": 0, "layer": 1},
             {"indices": [8, 9, 10, 11], "colour": "#ff0000", "on": 1, "layer": 2}]
    return make_scene({"pad": {"vertices": v, "faces": faces}}, [{"model": "pad", "position": [0, 0, 0]}])


@pytest.mark.parametrize("distance", [150.0, 2000.0, 30000.0])
def test_coplanar_markings_resolve_by_layer_at_any_range(make_scene, distance):
    db = _decal_scene(make_scene)
    # A shallow view of the pad from the south, the layers a few pixels tall far away.
    height = distance * np.tan(np.radians(10.0))
    fov = np.degrees(2.0 * np.arctan(60.0 / distance))
    ch = ChannelSpec.symmetric("c", 64, 48, fov)
    trace: dict = {}
    render_frame(db, ch, Eyepoint.of(0.0, -distance, height, 0.0, -10.0, 0.0), RenderOptions(samples=4), trace=trace)
    ids = trace["screen"].feature_id[np.maximum(trace["buffer"].opaque, 0)]
    seen = np.where(trace["buffer"].opaque >= 0, ids, -1)
    # The patch (feature 2) and stripe (1) are seen, and every sample inside them sees them:
    # the base (0) never shows through, at any range.
    assert (seen == 2).sum() > 0 and (seen == 1).sum() > 0
    assert _z_fighting_free(trace, db)


def _z_fighting_free(trace, db) -> bool:
    """Every sample sees the highest layer covering it (coverage, not depth, decides)."""
    screen, buf = trace["screen"], trace["buffer"]
    h, w, _ = buf.opaque.shape
    best = np.full(buf.opaque.shape, -1)
    for p in range(screen.polygon_count):
        a, b = screen.start[p], screen.start[p + 1]
        one = ScreenPolygons(screen.fixed[a:b], np.array([0, b - a]), screen.inv_z[p:p + 1],
                             screen.colour[p:p + 1], screen.opacity[p:p + 1],
                             screen.feature_id[p:p + 1], screen.layer[p:p + 1])
        hit = coverage_counts(one, w, h, buf.offsets) > 0
        best = np.where(hit, np.maximum(best, screen.layer[p]), best)
    seen_layer = np.where(buf.opaque >= 0, screen.layer[np.maximum(buf.opaque, 0)], -1)
    return bool((seen_layer == best).all())
