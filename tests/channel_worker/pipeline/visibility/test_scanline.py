"""Scan-line renderer (ARL Systems Note 77): exact coverage, priority list, horizon, translucent store."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.contract import EARTH_ID, SKY_ID, SUBPIXEL, ScreenPolygons
from channel_worker.pipeline.geometry.backface import eliminate_backfaces
from channel_worker.pipeline.geometry.clip import clip
from channel_worker.pipeline.geometry.cull import cull
from channel_worker.pipeline.geometry.project import project
from channel_worker.pipeline.geometry.transform import to_eye
from channel_worker.pipeline.geometry.view import (
    earth_dz_screen,
    frame_constants,
    make_view,
    screen_mapping,
)
from channel_worker.pipeline.scene.load import parse_scene
from channel_worker.pipeline.visibility.scanline import scanline_visibility
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

from ..conftest import screen_polygons


class _Scan:
    """The stage's sample store, its counters read as .stats."""

    def __init__(self, buffer, stats):
        self.buffer, self.stats = buffer, stats

    def __getattr__(self, name):
        return getattr(self.buffer, name)


def scanline(screen: ScreenPolygons, view, *, max_translucent: int = 4) -> _Scan:
    counters: dict[str, int] = {}
    options = RenderOptions(samples="centre", renderer="scanline", max_translucent=max_translucent)
    frame = frame_constants(view, DB, options.sample_offsets())
    return _Scan(scanline_visibility(screen, frame, options, counters), counters)

W, H = 40, 24
S = SUBPIXEL
HALF = S // 2
# Looking straight up: every pixel no face covers sees the sky.
UP = make_view(ChannelSpec.symmetric("t", W, H, 60.0), Eyepoint.of(0.0, 0.0, 10.0, 0.0, 90.0, 0.0))
# The scan line reads only the view for sky and earth; any database will do.
DB = parse_scene({"format": "ig-scene/1", "sky": {"colour": "#0000ff"},
                  "earth": {"colour": "#00ff00"}, "models": {}, "instances": []}, source="<test>")
FEW = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def edge_test(v: np.ndarray) -> np.ndarray:
    """(H, W) bool: the exact integer edge test with the top-left rule at every pixel centre."""
    ys, xs = np.mgrid[0:H, 0:W]
    px, py = xs * S + HALF, ys * S + HALF
    ok = np.ones((H, W), bool)
    for i in range(len(v)):
        x0, y0 = v[i]
        dx, dy = v[(i + 1) % len(v)] - v[i]
        e = (px - x0) * dy - (py - y0) * dx
        ok &= e >= (0 if (dy > 0 or (dy == 0 and dx < 0)) else 1)
    return ok


def covered(screen: ScreenPolygons) -> np.ndarray:
    return scanline(screen, UP).opaque[..., 0] >= 0


def polygon(screen: ScreenPolygons, p: int) -> np.ndarray:
    return screen.fixed[screen.start[p]:screen.start[p + 1]]


def priority_key(screen: ScreenPolygons, p: int) -> tuple:
    """Sort key, smallest first: the documented PRIORITY LIST order, computed independently."""
    def centroid_inv_z(q):
        c = polygon(screen, q).mean(axis=0) / S
        a, b, k = screen.inv_z[q]
        return a * c[0] + b * c[1] + k
    same_plane = [q for q in range(screen.polygon_count) if (screen.inv_z[q] == screen.inv_z[p]).all()]
    return (-max(centroid_inv_z(q) for q in same_plane), -int(screen.layer[p]), p)


def reference(screen: ScreenPolygons, k: int):
    """Per pixel: the first opaque face in priority order (-1: none) and the translucent faces
    ahead of it (at most k), by brute force over every face."""
    order = sorted(range(screen.polygon_count), key=lambda p: priority_key(screen, p))
    cover = [edge_test(polygon(screen, p)) for p in range(screen.polygon_count)]
    opaque = np.full((H, W), -1)
    trans = {}
    for m in np.ndindex(H, W):
        front = []
        for p in order:
            if cover[p][m]:
                if screen.opacity[p] >= 1.0:
                    opaque[m] = p
                    break
                front.append(p)
        trans[m] = front[:k]
    return opaque, trans


coord_x = st.integers(-300, W * S + 300)
coord_y = st.integers(-300, H * S + 300)
# Vertices anywhere, or exactly on pixel centres and corners, where the ties are.
on_grid = st.tuples(st.integers(-1, W + 1), st.integers(-1, H + 1), st.sampled_from([0, HALF])) \
    .map(lambda t: (t[0] * S + t[2], t[1] * S + t[2]))
vertex = st.one_of(st.tuples(coord_x, coord_y), on_grid)


def area2(v) -> int:
    v = np.asarray(v, np.int64)
    return int(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


def convex_hull(points) -> list:
    """Andrew's monotone chain, collinear points dropped."""
    pts = sorted(set(points))

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out
    return half(pts)[:-1] + half(pts[::-1])[:-1]


@FEW
@given(st.lists(vertex, min_size=3, max_size=3))
def test_triangle_coverage_is_the_exact_edge_test(tri):
    assume(area2(tri) != 0)
    screen = screen_polygons([tri])
    np.testing.assert_array_equal(covered(screen), edge_test(polygon(screen, 0)))


@FEW
@given(st.lists(vertex, min_size=4, max_size=8))
def test_convex_polygon_coverage_is_the_exact_edge_test(points):
    hull = convex_hull(points)
    assume(len(hull) >= 3)
    screen = screen_polygons([hull])
    np.testing.assert_array_equal(covered(screen), edge_test(polygon(screen, 0)))


@FEW
@given(st.lists(vertex, min_size=4, max_size=6))
def test_any_polygon_covers_the_intersection_of_its_half_planes(points):
    # Snapping can leave a polygon slightly non-convex; the edge test then keeps the
    # intersection of the half-planes, and so must the scan line.
    assume(area2(points) != 0)
    screen = screen_polygons([points])
    np.testing.assert_array_equal(covered(screen), edge_test(polygon(screen, 0)))


def test_slightly_reflex_quad_is_extended_and_exact():
    # The vertex (20 S, 10 S - 1) dents the top edge by 1/256 pixel.
    quad = [(2 * S, 10 * S), (20 * S, 10 * S + 1), (38 * S, 10 * S), (20 * S, 20 * S)]
    screen = screen_polygons([quad])
    buf = scanline(screen, UP)
    assert buf.stats["nonconvex_faces"] == 1
    np.testing.assert_array_equal(buf.opaque[..., 0] >= 0, edge_test(polygon(screen, 0)))


@FEW
@given(st.lists(vertex, min_size=4, max_size=4))
def test_two_triangles_sharing_an_edge_cover_each_centre_once(quad):
    hull = convex_hull(quad)
    assume(len(hull) == 4)
    a, b = [hull[0], hull[1], hull[2]], [hull[0], hull[2], hull[3]]
    alone_a = covered(screen_polygons([a]))
    alone_b = covered(screen_polygons([b]))
    assert not (alone_a & alone_b).any()  # no double cover
    whole = screen_polygons([hull])
    np.testing.assert_array_equal(alone_a | alone_b, edge_test(polygon(whole, 0)))  # no crack
    together = scanline(screen_polygons([a, b]), UP).opaque[..., 0]
    np.testing.assert_array_equal(together == 0, alone_a)
    np.testing.assert_array_equal(together == 1, alone_b)


def test_fan_around_a_vertex_on_a_pixel_centre_covers_it_once():
    centre = (20 * S + HALF, 12 * S + HALF)
    angles = np.radians(np.arange(0, 360, 45) + 10.0)
    ring = [(centre[0] + round(3000 * np.cos(t)), centre[1] + round(2000 * np.sin(t)))
            for t in angles]
    fan = [[centre, ring[i], ring[(i + 1) % len(ring)]] for i in range(len(ring))]
    counts = sum(covered(screen_polygons([t])).astype(int) for t in fan)
    assert counts[12, 20] == 1
    assert counts.max() == 1
    np.testing.assert_array_equal(counts == 1, edge_test(polygon(screen_polygons([ring]), 0)))
    together = scanline(screen_polygons(fan), UP)
    assert together.stats["multiple_edges"] > 0  # the vertex row meets several edges at once
    np.testing.assert_array_equal(together.opaque[..., 0] >= 0, counts == 1)


def test_edges_through_pixel_centres_follow_the_top_left_rule():
    # Left/top edges through centres keep them, right/bottom edges through centres do not.
    x0, x1, y0, y1 = 2 * S + HALF, 10 * S + HALF, 3 * S + HALF, 8 * S + HALF
    left = screen_polygons([[(x0, y0), (x1, y0), (x1, y1), (x0, y1)]])
    expect = np.zeros((H, W), bool)
    expect[3:8, 2:10] = True
    np.testing.assert_array_equal(covered(left), expect)
    # Its right neighbour shares the vertical edge x1: every column exactly once.
    x2 = 17 * S + HALF
    both = scanline(
        screen_polygons([[(x0, y0), (x1, y0), (x1, y1), (x0, y1)],
                      [(x1, y0), (x2, y0), (x2, y1), (x1, y1)]]), UP).opaque[..., 0]
    assert (both[3:8, 2:10] == 0).all() and (both[3:8, 10:17] == 1).all()
    assert (both[:3] < 0).all() and (both[8:] < 0).all() and (both[:, 17:] < 0).all()


def test_near_quad_hides_far_quad_in_either_order():
    far = [(2 * S, 2 * S), (30 * S, 2 * S), (30 * S, 20 * S), (2 * S, 20 * S)]
    near = [(10 * S, 6 * S), (36 * S, 6 * S), (36 * S, 22 * S), (10 * S, 22 * S)]
    for order in ((far, near), (near, far)):
        planes = [(0.0, 0.0, 0.2), (0.0, 0.0, 0.5)] if order[0] is far else \
            [(0.0, 0.0, 0.5), (0.0, 0.0, 0.2)]
        buf = scanline(screen_polygons(list(order), planes), UP)
        near_index = 1 if order[0] is far else 0
        ids = buf.opaque[..., 0]
        assert (ids[6:20, 10:30] == near_index).all()  # overlap: the near quad
        assert (ids[2:6, 2:30] == 1 - near_index).all()  # far quad where alone
        # range at the pixel centre: |(tx, ty, 1)| z with z = 2 m for the near quad
        sx_scale, sx_off, sy_scale, sy_off = screen_mapping(UP)
        tx, ty = (15.5 - sx_off) / sx_scale, (10.5 - sy_off) / sy_scale
        assert buf.polygon_range[10, 15] == pytest.approx(2.0 * np.sqrt(tx * tx + ty * ty + 1), rel=1e-6)


def test_marking_on_its_runway_is_seen_wherever_it_lies():
    # A runway plane tilted in depth; a marking far up it shares the plane bit for bit (scene
    # "on", layer 1). Its own centroid is farther than the runway's, but the shared plane makes
    # them one surface in the priority list and the layer decides.
    plane = (0.0, 0.01, 0.2)
    runway = [(4 * S, 1 * S), (36 * S, 1 * S), (36 * S, 23 * S), (4 * S, 23 * S)]
    marking = [(18 * S, 2 * S), (22 * S, 2 * S), (22 * S, 5 * S), (18 * S, 5 * S)]
    building = [(30 * S, 10 * S), (38 * S, 10 * S), (38 * S, 20 * S), (30 * S, 20 * S)]
    buf = scanline(screen_polygons([runway, marking, building],
                                           [plane, plane, (0.0, 0.0, 1.0)], layer=[0, 1, 0]),
                              UP)
    ids = buf.opaque[..., 0]
    assert (ids[2:5, 18:22] == 1).all()
    assert (ids[10:20, 30:36] == 2).all()
    assert (ids[10:20, 5:29] == 0).all()


def test_translucent_faces_ahead_of_the_opaque_one_nearest_first():
    quad = [(0, 0), (W * S, 0), (W * S, H * S), (0, H * S)]
    # Opaque at z = 2; translucent at z = 1.9 .. 1.0 (nearer) and one at z = 3 (behind it).
    planes = [(0.0, 0.0, 0.5)] + [(0.0, 0.0, 1.0 / z) for z in (1.9, 1.5, 1.2, 1.1, 1.0, 3.0)]
    screen = screen_polygons([quad] * 7, planes, [1.0] + [0.5] * 6)
    buf = scanline(screen, UP, max_translucent=3)
    assert buf.translucent.shape == (H, W, 1, 3)
    assert (buf.opaque == 0).all()
    assert (buf.translucent_count == 3).all()
    np.testing.assert_array_equal(buf.translucent[5, 7, 0], [5, 4, 3])
    assert (buf.translucent[..., 0] == 5).all() and (buf.translucent[..., 2] == 3).all()
    assert buf.stats["translucent_overflow"] == W * H  # every pixel had 5 > 3
    assert buf.stats["translucent_dropped"] == 2 * W * H
    roomy = scanline(screen, UP, max_translucent=8)
    assert (roomy.translucent_count == 5).all()
    assert roomy.stats["translucent_overflow"] == 0


def random_scene(seed: int, n: int, translucent_share: float) -> ScreenPolygons:
    rng = np.random.default_rng(seed)
    polys, planes, opacity = [], [], []
    while len(polys) < n:
        t = rng.integers([-300, -300], [W * S + 300, H * S + 300], size=(3, 2))
        if rng.random() < 0.3:
            t = (t // (4 * S)) * (4 * S) + rng.choice([0, HALF], size=(3, 2))
        if area2(t) == 0:
            continue
        polys.append(t)
        planes.append((rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(0.5, 1.0)))
        opacity.append(0.5 if rng.random() < translucent_share else 1.0)
    return screen_polygons(polys, planes, opacity, layer=list(rng.integers(0, 2, n)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_scene_matches_the_priority_list_by_brute_force(seed):
    screen = random_scene(seed, 12, 0.4)
    buf = scanline(screen, UP, max_translucent=2)
    opaque, trans = reference(screen, 2)
    np.testing.assert_array_equal(np.where(buf.opaque[..., 0] >= 0, buf.opaque[..., 0], -1), opaque)
    assert set(np.unique(buf.opaque[..., 0][opaque < 0])) <= {SKY_ID}
    for m, expect in trans.items():
        got = list(buf.translucent[m][0][:buf.translucent_count[m][0]])
        assert got == expect, (m, got, expect)
    assert np.isinf(buf.polygon_range[opaque < 0]).all()
    assert np.isfinite(buf.polygon_range[opaque >= 0]).all()


def test_result_does_not_depend_on_the_thread_count():
    screen = random_scene(7, 20, 0.3)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = scanline(screen, UP)
    finally:
        numba.set_num_threads(before)
    many = scanline(screen, UP)
    for field in ("opaque", "translucent", "translucent_count", "polygon_range"):
        np.testing.assert_array_equal(getattr(one, field), getattr(many, field))
    assert one.stats == many.stats


def horizon_reference(view) -> np.ndarray:
    kx, ky, k0 = earth_dz_screen(view)
    sy, sx = np.mgrid[0:view.height, 0:view.width] + 0.5
    return np.where(kx * sx + ky * sy + k0 < 0.0, EARTH_ID, SKY_ID)


def empty() -> ScreenPolygons:
    return screen_polygons([])


@pytest.mark.parametrize("roll", [0.0, 30.0, -70.0, 180.0])
def test_horizon_matches_the_per_pixel_test(roll):
    view = make_view(ChannelSpec.symmetric("t", W, H, 60.0), Eyepoint.of(0, 0, 10, 0, 0, roll))
    buf = scanline(empty(), view)
    ids = buf.opaque[..., 0]
    np.testing.assert_array_equal(ids, horizon_reference(view))
    if roll == 0.0:
        assert (ids[:H // 2] == SKY_ID).all() and (ids[H // 2:] == EARTH_ID).all()
    elif roll == 180.0:
        assert (ids[:H // 2] == EARTH_ID).all() and (ids[H // 2:] == SKY_ID).all()
    else:
        mixed = [(row == SKY_ID).any() and (row == EARTH_ID).any() for row in ids]
        assert any(mixed)  # the horizon line is tilted: some scan lines see both


def test_empty_scene_is_only_sky_and_earth():
    view = make_view(ChannelSpec.symmetric("t", W, H, 60.0), Eyepoint.of(0, 0, 10, 20, 5, 10))
    buf = scanline(empty(), view)
    assert set(np.unique(buf.opaque)) <= {SKY_ID, EARTH_ID}
    assert np.isinf(buf.polygon_range).all()
    assert (buf.translucent_count == 0).all()
    np.testing.assert_array_equal(buf.offsets, [[0.5, 0.5]])
    assert buf.stats["edges"] == 0 and buf.stats["field_entries"] == 0


def test_pipeline_box_touching_the_raster_edges_has_no_nan(make_scene, box_model_factory):
    db = make_scene({"b": box_model_factory(40, 10, 30, "#ff0000")},
                    [{"model": "b", "position": [3.0, 12.0, 0.0]}])
    view = make_view(ChannelSpec.symmetric("t", W, H, 60.0), Eyepoint.of(0, 0, 5, 10, 5, 15))
    screen = project(clip(eliminate_backfaces(to_eye(db, cull(db, view), view)), view), view)
    assert screen.polygon_count > 0
    touches = (screen.fixed == 0) | (screen.fixed == [W * S, H * S])
    assert touches.any()  # clipped at the raster edges
    buf = scanline(screen, view)
    ids = buf.opaque[..., 0]
    seen = ids >= 0
    assert seen[0].any() and seen[:, -1].any()
    assert not np.isnan(buf.polygon_range).any()
    assert np.isfinite(buf.polygon_range[seen]).all() and (buf.polygon_range[seen] > 0).all()
    assert np.isinf(buf.polygon_range[~seen]).all()
    for p in np.unique(ids[seen]):
        # every pixel a face is seen at is one its exact edge test covers
        assert edge_test(polygon(screen, p))[ids == p].all()


@pytest.mark.parametrize("k", [0, 16, -1, True, 2.5, "4"])
def test_max_translucent_is_validated(k):
    with pytest.raises(ValueError, match=r"max_translucent.*" + repr(k).replace(".", r"\.")):
        scanline(empty(), UP, max_translucent=k)
