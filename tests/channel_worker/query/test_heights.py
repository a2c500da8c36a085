"""height_of_terrain: exact on synthetic terrain, the bundled terrain against its stored source,
polygons, z_max, patterns, outside the database."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from channel_worker.query._query_kernels import MATERIAL_GROUND, MATERIAL_NONE, MATERIAL_POLYGON
from channel_worker.query.heights import height_of_terrain
from channel_worker.testing.sight_reference import reference_ground

from .conftest import SPACING, nodes, quad, scene, wall

INF = np.inf
SURFACES = {
    "plane": (lambda x, y: 5.0 + 0 * x, lambda x, y: 5.0 + 0 * x, lambda x, y: (0 * x, 0 * x)),
    "ramp": (lambda x, y: 0.25 * x - 0.5 * y, lambda x, y: 0.25 * x - 0.5 * y,
             lambda x, y: (0.25 + 0 * x, -0.5 + 0 * x)),
    "saddle": (lambda x, y: (x - 40) * (y - 40) / 64, lambda x, y: (x - 40) * (y - 40) / 64,
               lambda x, y: ((y - 40) / 64, (x - 40) / 64)),
}


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_synthetic_surfaces_exact(name):
    f_nodes, f, grad = SURFACES[name]
    origin = (100.0, -50.0, 3.0)
    db = scene(heights=nodes(f_nodes), origin=origin)
    rng = np.random.default_rng(5)
    lx, ly = rng.uniform(0, 12 * SPACING, 400), rng.uniform(0, 9 * SPACING, 400)
    lx[:3], ly[:3] = [0.0, 120.0, 30.0], [0.0, 90.0, 40.0]  # corners and a node
    h = height_of_terrain(db, lx + origin[0], ly + origin[1], np.full(400, INF))
    assert h.valid.all()
    np.testing.assert_allclose(h.height_m, f(lx, ly) + origin[2], rtol=0, atol=1e-6)
    gx, gy = grad(lx, ly)
    expect = np.stack([-gx, -gy, np.ones_like(gx)], 1) / np.sqrt(gx ** 2 + gy ** 2 + 1)[:, None]
    np.testing.assert_allclose(h.normal, expect, atol=1e-9)
    assert (h.material == MATERIAL_GROUND).all()


def test_bundled_terrain_matches_the_stored_surface(bundled):
    terrain_only = dataclasses.replace(bundled, instance_model=bundled.instance_model[:0],
                                       instance_position=bundled.instance_position[:0],
                                       instance_rotation=bundled.instance_rotation[:0])
    t = bundled.terrain
    rng = np.random.default_rng(11)
    x = t.origin[0] + rng.uniform(0, t.nx * t.spacing_m, 2000)
    y = t.origin[1] + rng.uniform(0, t.ny * t.spacing_m, 2000)
    h = height_of_terrain(terrain_only, x, y, np.full(2000, INF))
    ground, top = reference_ground(t, x, y)
    assert h.valid.all()
    # float32 corner heights: both read the same floats, so only float64 rounding differs.
    np.testing.assert_allclose(h.height_m, top, rtol=0, atol=1e-6)
    trees = h.material == MATERIAL_GROUND + 1
    assert trees.any() and (h.material[~trees] == MATERIAL_GROUND).all()
    assert (top[trees] > ground[trees]).all()


def test_runway_polygon_over_terrain():
    db = scene({"runway": quad(20, 20, 60, 70, 2.0, "#404040")}, nodes(lambda x, y: 0 * x))
    h = height_of_terrain(db, np.array([30.0, 10.0]), np.array([30.0, 10.0]), np.full(2, INF))
    np.testing.assert_allclose(h.height_m, [2.0, 0.0], atol=1e-12)
    assert h.material.tolist() == [MATERIAL_POLYGON + 0, MATERIAL_GROUND]
    np.testing.assert_allclose(h.normal[0], [0, 0, 1])


def test_polygon_within_the_margin_below_the_terrain_wins():
    """A runway drawn over its pad though rounding puts it a little under the terrain."""
    db = scene({"runway": quad(20, 20, 60, 70, -0.4)}, nodes(lambda x, y: 0 * x), margin=1.0)
    h = height_of_terrain(db, np.array([30.0]), np.array([30.0]), np.array([INF]))
    assert h.material[0] == MATERIAL_POLYGON and h.height_m[0] == pytest.approx(-0.4)
    deep = scene({"runway": quad(20, 20, 60, 70, -1.5)}, nodes(lambda x, y: 0 * x), margin=1.0)
    h = height_of_terrain(deep, np.array([30.0]), np.array([30.0]), np.array([INF]))
    assert h.material[0] == MATERIAL_GROUND and h.height_m[0] == 0.0


def test_height_above_terrain_under_a_bridge():
    db = scene({"bridge": quad(0, 40, 120, 50, 10.0)}, nodes(lambda x, y: 0.1 * x))
    x, y = np.array([50.0, 50.0, 50.0]), np.array([45.0, 45.0, 45.0])
    h = height_of_terrain(db, x, y, np.array([INF, 10.0, 9.99]))
    np.testing.assert_allclose(h.height_m, [10.0, 10.0, 5.0], atol=1e-9)
    assert h.material.tolist() == [MATERIAL_POLYGON, MATERIAL_POLYGON, MATERIAL_GROUND]
    below = height_of_terrain(db, np.array([50.0]), np.array([45.0]), np.array([4.0]))
    assert not below.valid[0] and below.material[0] == MATERIAL_NONE


def test_translucent_and_vertical_faces():
    db = scene({"glass": quad(0, 0, 50, 50, 8.0, opacity=0.4), "canopy": quad(60, 0, 100, 50, 6.0, opacity=0.5),
                "wall": wall(30, 0, 50, 0, 20)}, nodes(lambda x, y: 0 * x))
    h = height_of_terrain(db, np.array([30.0, 70.0]), np.array([10.0, 10.0]), np.full(2, INF))
    np.testing.assert_allclose(h.height_m, [0.0, 6.0])  # glass below one half: not a surface


def test_pattern_top_and_inside():
    mask = np.zeros((9, 12), np.uint8)
    mask[2, 3] = 1
    db = scene(heights=nodes(lambda x, y: 0.1 * x), pattern_mask=mask)
    x, y = np.full(3, 35.0), np.full(3, 25.0)
    h = height_of_terrain(db, x, y, np.array([INF, 10.0, 1.0]))
    top = 0.1 * 40 + 14.0  # highest corner + the tree's last band
    np.testing.assert_allclose(h.height_m, [top, 3.5, np.nan], atol=1e-6)
    assert h.material.tolist() == [MATERIAL_GROUND + 1, MATERIAL_GROUND, MATERIAL_NONE]
    np.testing.assert_allclose(h.normal[0], [0, 0, 1])


def test_outside_every_database():
    db = scene({"pad": quad(0, 0, 10, 10, 0.0)}, nodes(lambda x, y: 0 * x))
    h = height_of_terrain(db, np.array([-1.0, 500.0, 5.0, 120.0]), np.array([5.0, 5.0, -0.5, 90.0]),
                          np.full(4, INF))
    assert h.valid.tolist() == [False, False, False, True]  # the far corner belongs to the terrain
    assert np.isnan(h.height_m[:3]).all() and (h.material[:3] == MATERIAL_NONE).all()
    empty = scene()
    assert not height_of_terrain(empty, np.zeros(1), np.zeros(1), np.full(1, INF)).valid[0]


def test_far_from_the_origin_is_the_same():
    near = scene({"roof": quad(20, 20, 40, 40, 7.25)}, nodes(lambda x, y: (x - 40) * (y - 40) / 64))
    far = scene({"roof": quad(20, 20, 40, 40, 7.25)}, nodes(lambda x, y: (x - 40) * (y - 40) / 64),
                offset=(1.0e6, -1.0e6, 0.0))
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0, 120, 100), rng.uniform(0, 90, 100)
    a = height_of_terrain(near, x, y, np.full(100, INF))
    b = height_of_terrain(far, x + 1.0e6, y - 1.0e6, np.full(100, INF))
    np.testing.assert_allclose(a.height_m, b.height_m, atol=1e-6)
    assert (a.material == b.material).all()


def test_bad_arguments_are_named():
    db = scene()
    with pytest.raises(ValueError, match="lengths 2, 1, 1"):
        height_of_terrain(db, np.zeros(2), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match=r"y\[1\]: nan"):
        height_of_terrain(db, np.zeros(2), np.array([0.0, np.nan]), np.zeros(2))
