"""line_of_sight: the hard cases on synthetic scenes and the bundled scene against the
independent ray march (channel_worker/testing/sight_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.query._query_kernels import MATERIAL_GROUND, MATERIAL_NONE, MATERIAL_POLYGON
from channel_worker.query.sight import line_of_sight
from channel_worker.testing.sight_reference import reference_ground, reference_sight

from .conftest import nodes, quad, scene, wall


def sight(db, p0, p1, min_opacity=0.0):
    p0, p1 = np.atleast_2d(np.asarray(p0, float)), np.atleast_2d(np.asarray(p1, float))
    return line_of_sight(db, p0, p1, np.full(p0.shape[0], min_opacity))


def ramp(x, y):
    return 0.25 * x - 0.5 * y + 20.0


def test_straight_down():
    db = scene(heights=nodes(ramp), origin=(5.0, 5.0, 0.0))
    s = sight(db, [[45.0, 35.0, 100.0]], [[45.0, 35.0, -100.0]])
    h = ramp(40.0, 30.0)
    assert s.hit[0] and s.range_m[0] == pytest.approx(100.0 - h, abs=1e-9)
    np.testing.assert_allclose(s.point[0], [45.0, 35.0, h], atol=1e-9)
    np.testing.assert_allclose(s.normal[0], np.array([-0.25, 0.5, 1.0]) / np.sqrt(1.3125), atol=1e-12)
    assert s.material[0] == MATERIAL_GROUND and s.rgba[0] & 0xFF == 255


def test_straight_down_on_a_grid_line_and_a_node():
    db = scene(heights=nodes(ramp))
    s = sight(db, [[40.0, 35.0, 100.0], [40.0, 30.0, 100.0]], [[40.0, 35.0, 0.0], [40.0, 30.0, 0.0]])
    np.testing.assert_allclose(s.range_m, [100.0 - ramp(40, 35), 100.0 - ramp(40, 30)], atol=1e-9)


def test_zero_length_segments():
    db = scene(heights=nodes(ramp))
    s = sight(db, [[40.0, 30.0, 0.0], [40.0, 30.0, 50.0]], [[40.0, 30.0, 0.0], [40.0, 30.0, 50.0]])
    assert s.hit.tolist() == [True, False] and s.range_m[0] == 0.0


@pytest.mark.parametrize("axis", [0, 1])
def test_parallel_to_grid_lines(axis):
    """Along a grid line and along the middle of a row of voxels, both directions."""
    db = scene(heights=nodes(lambda x, y: (x - 40) * (y - 40) / 64))
    starts, ends = [], []
    for line in (30.0, 35.0):
        for sign in (1, -1):
            a = np.array([0.5, 0.5, 12.0])
            a[1 - axis] = line
            b = a.copy()
            a[axis], b[axis] = (0.5, 119.0) if sign > 0 else (89.0, 0.5)
            b[2] = -30.0
            starts.append(a)
            ends.append(b)
    s = sight(db, starts, ends)
    ref_hit, ref_range, _ = reference_sight(db, np.array(starts), np.array(ends), np.zeros(len(starts)),
                                            step_m=0.01)
    assert (s.hit == ref_hit).all() and s.hit.sum() >= 4
    np.testing.assert_allclose(s.range_m, ref_range, atol=1e-6)


def test_horizontal_grazing_a_peak():
    heights = nodes(lambda x, y: 0 * x)
    heights[4, 5] = 10.0  # one raised node: a peak at (50, 40)
    db = scene(heights=heights)
    below = sight(db, [[0.5, 40.0, 10.0 - 1e-6]], [[119.0, 40.0, 10.0 - 1e-6]])
    above = sight(db, [[0.5, 40.0, 10.0 + 1e-6]], [[119.0, 40.0, 10.0 + 1e-6]])
    assert below.hit[0] and below.range_m[0] == pytest.approx(49.5, abs=1e-3)
    assert not above.hit[0] and above.material[0] == MATERIAL_NONE and np.isnan(above.range_m[0])
    level = sight(db, [[0.5, 20.0, 0.0 + 1e-9]], [[119.0, 20.0, 1e-9]])  # over the flat part
    assert not level.hit[0]


def test_through_a_tree():
    mask = np.zeros((9, 12), np.uint8)
    mask[2, 3] = 1  # voxel x 30..40, y 20..30, ground 0, crown 3..14 m
    db = scene(heights=nodes(lambda x, y: 0 * x), pattern_mask=mask)
    s = sight(db, [[0.5, 25.0, 5.0], [35.0, 25.0, 50.0], [0.5, 25.0, 1.0], [0.5, 25.0, 20.0]],
              [[119.0, 25.0, 5.0], [35.0, 25.0, 0.0], [119.0, 25.0, 1.0], [119.0, 25.0, 20.0]])
    assert s.hit.tolist() == [True, True, True, False]
    np.testing.assert_allclose(s.range_m[:3], [29.5, 36.0, 29.5], atol=1e-9)
    assert s.material[:3].tolist() == [MATERIAL_GROUND + 1] * 3
    np.testing.assert_allclose(s.normal[0], [-1, 0, 0])
    np.testing.assert_allclose(s.normal[1], [0, 0, 1])
    assert s.rgba[0] == (20 << 24 | 90 << 16 | 30 << 8 | 255)  # crown band
    assert s.rgba[2] == (100 << 24 | 70 << 16 | 40 << 8 | 255)  # trunk band


def test_against_polygons():
    db = scene({"wall": wall(60, 0, 90, 0, 30, "#ff0000"), "glass": wall(50, 0, 90, 0, 30, "#0000ff", 0.4)},
               nodes(lambda x, y: 0 * x))
    s = sight(db, [[10.0, 45.0, 5.0]] * 2, [[110.0, 45.0, 5.0]] * 2, 0.0)
    assert s.hit.all() and s.range_m[0] == pytest.approx(40.0)
    assert s.material[0] == MATERIAL_POLYGON + 1 and s.rgba[0] == (0x0000FF00 | 102)
    np.testing.assert_allclose(s.normal[0], [-1, 0, 0], atol=1e-12)
    opaque = line_of_sight(db, np.array([[10.0, 45.0, 5.0]]), np.array([[110.0, 45.0, 5.0]]), np.array([0.5]))
    assert opaque.range_m[0] == pytest.approx(50.0) and opaque.material[0] == MATERIAL_POLYGON
    assert opaque.rgba[0] == 0xFF0000FF
    back = sight(db, [[110.0, 45.0, 5.0]], [[10.0, 45.0, 5.0]], 0.5)  # from behind: normal faces the start
    np.testing.assert_allclose(back.normal[0], [1, 0, 0], atol=1e-12)


def test_polygon_on_its_pad_wins_within_the_margin():
    db = scene({"runway": quad(20, 20, 60, 70, -0.3)}, nodes(lambda x, y: 0 * x), margin=1.0)
    s = sight(db, [[30.0, 30.0, 50.0], [0.5, 45.0, 10.0]], [[30.0, 30.0, -50.0], [80.0, 45.0, -10.0]])
    assert s.material.tolist() == [MATERIAL_POLYGON, MATERIAL_POLYGON]
    assert s.range_m[0] == pytest.approx(50.3)


def test_starting_underground():
    db = scene(heights=nodes(ramp))
    s = sight(db, [[40.0, 30.0, ramp(40, 30) - 3.0]], [[40.0, 30.0, 100.0]])
    assert s.hit[0] and s.range_m[0] == 0.0
    np.testing.assert_allclose(s.point[0], [40.0, 30.0, ramp(40, 30) - 3.0])


def test_outside_and_entering_the_database():
    db = scene(heights=nodes(lambda x, y: 10.0 + 0 * x))
    s = sight(db, [[-100.0, 45.0, 50.0], [-50.0, 45.0, 5.0]], [[-100.0, 45.0, -50.0], [50.0, 45.0, 5.0]])
    assert s.hit.tolist() == [False, True]
    assert s.range_m[1] == pytest.approx(50.0)  # the database's edge is a wall
    np.testing.assert_allclose(s.normal[1], [-1, 0, 0])


def test_far_from_the_origin_is_the_same():
    models = {"wall": wall(60, 0, 90, 0, 30)}
    f = lambda x, y: (x - 40) * (y - 40) / 64  # noqa: E731
    near, far = scene(models, nodes(f)), scene(models, nodes(f), offset=(1.0e6, 1.0e6, 0.0))
    rng = np.random.default_rng(8)
    p0 = np.c_[rng.uniform(0, 120, 100), rng.uniform(0, 90, 100), rng.uniform(30, 60, 100)]
    p1 = np.c_[rng.uniform(0, 120, 100), rng.uniform(0, 90, 100), rng.uniform(-20, 10, 100)]
    a = line_of_sight(near, p0, p1, np.zeros(100))
    b = line_of_sight(far, p0 + [1.0e6, 1.0e6, 0.0], p1 + [1.0e6, 1.0e6, 0.0], np.zeros(100))
    assert (a.hit == b.hit).all() and a.hit.sum() > 50
    np.testing.assert_allclose(a.range_m, b.range_m, atol=1e-6)
    assert (a.material == b.material).all()


def test_bundled_scene_against_the_reference_march(bundled):
    """Random segments up to 10 km, near the airfield (polygons) and over the hills."""
    rng = np.random.default_rng(17)
    n = 120
    x, y = rng.uniform(-4000, 4000, n), rng.uniform(-4000, 4000, n)
    ground, _ = reference_ground(bundled.terrain, x, y)
    p0 = np.c_[x, y, ground + rng.uniform(0.5, 300, n)]
    heading, length, climb = rng.uniform(0, 2 * np.pi, n), rng.uniform(10, 10000, n), rng.uniform(-0.4, 0.1, n)
    p1 = p0 + length[:, None] * np.c_[np.cos(heading) * np.cos(climb), np.sin(heading) * np.cos(climb), np.sin(climb)]
    s = line_of_sight(bundled, p0, p1, np.zeros(n))
    hit, range_m, from_face = reference_sight(bundled, p0, p1, np.zeros(n))
    assert hit.sum() > n // 2 and from_face.any()
    # The march misses only solid thinner than its step along the segment; none here.
    assert (s.hit == hit).all()
    np.testing.assert_allclose(s.range_m[hit], range_m[hit], rtol=0, atol=1e-6)
    assert ((s.material >= MATERIAL_POLYGON) == from_face).all()


def test_bad_arguments_are_named():
    db = scene()
    with pytest.raises(ValueError, match="shapes"):
        line_of_sight(db, np.zeros((2, 3)), np.zeros((1, 3)), np.zeros(2))
    with pytest.raises(ValueError, match=r"p1\[0\]: \[0.0, inf, 0.0\] is not finite"):
        line_of_sight(db, np.zeros((1, 3)), np.array([[0.0, np.inf, 0.0]]), np.zeros(1))


