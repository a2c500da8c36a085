"""Levels by 2 x 2 averaging, pages and page tables, border copies, pruning, patterns."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.scene.terrain.build import build_terrain, level_nodes
from channel_worker.pipeline.scene.terrain.database import (
    CORNERS,
    Pattern,
    TerrainError,
    level_count,
)
from channel_worker.pipeline.scene.terrain.features import TREE_PATTERN
from services.rig.colour import linear_to_srgb8, srgb8_to_linear


def grey(shape, value=0.25):
    return np.full(shape + (3,), value)


@settings(max_examples=25, deadline=None)
@given(nx=st.integers(1, 70), ny=st.integers(1, 70), page=st.sampled_from([4, 8, 16]),
       z=st.floats(-500, 3000), rgb=st.floats(0, 1))
def test_a_constant_field_stays_constant_at_every_level(nx, ny, page, z, rgb, assemble):
    db = build_terrain(np.full((ny + 1, nx + 1), z), grey((ny + 1, nx + 1), rgb), spacing_m=10.0,
                       origin=(0.0, 0.0, 0.0), page_size=page)
    assert db.levels == level_count(nx, ny, page)
    assert max(db.level_size(db.levels - 1)) <= page
    assert (db.page_table >= 0).all()
    np.testing.assert_array_equal(db.z, np.float32(z))
    assert (db.rgb == linear_to_srgb8(np.array([rgb]))[0]).all()
    for level in range(db.levels):
        heights, _, _ = assemble(db, level)
        assert heights.shape == (db.level_size(level)[1] + 1, db.level_size(level)[0] + 1)


@settings(max_examples=25, deadline=None)
@given(kx=st.integers(1, 12), ky=st.integers(1, 12), a=st.floats(-5, 5), b=st.floats(-5, 5))
def test_a_linear_ramp_stays_the_same_ramp_at_every_level_edges_included(kx, ky, a, b):
    nx, ny = 8 * kx, 8 * ky  # whole coarse voxels at levels 0..3: no padding
    j, i = np.mgrid[0:ny + 1, 0:nx + 1]
    for level, (h, _) in enumerate(level_nodes(100.0 + a * i + b * j, grey((ny + 1, nx + 1)), 4)):
        jj, ii = np.mgrid[0:h.shape[0], 0:h.shape[1]]
        # coarse node (jj, ii) sits at level-0 node (jj, ii) * 2**level
        np.testing.assert_allclose(h, 100.0 + (a * ii + b * jj) * 2 ** level, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(nx=st.integers(1, 90), ny=st.integers(1, 90), seed=st.integers(0, 2 ** 32 - 1))
def test_odd_sizes_pad_by_repeating_the_edge_and_never_overshoot(nx, ny, seed):
    rng = np.random.default_rng(seed)
    h = rng.uniform(-10, 10, (ny + 1, nx + 1))
    levels = level_count(nx, ny, 4)
    nodes = level_nodes(h, grey((ny + 1, nx + 1)), levels)
    for level, (hl, _) in enumerate(nodes):
        size_x, size_y = -(-nx // 2 ** level), -(-ny // 2 ** level)
        assert hl.shape == (size_y + 1, size_x + 1)
        assert h.min() - 1e-9 <= hl.min() and hl.max() <= h.max() + 1e-9
    j, i = np.mgrid[0:ny + 1, 0:nx + 1]
    ramp = level_nodes(3.0 * i - 2.0 * j, grey((ny + 1, nx + 1)), 2)[1][0]
    jj, ii = np.mgrid[0:ramp.shape[0], 0:ramp.shape[1]]
    inside = (2 * jj <= ny) & (2 * ii <= nx)  # the nodes within the data: exact
    np.testing.assert_allclose(ramp[inside], (6.0 * ii - 4.0 * jj)[inside], atol=1e-9)


def test_level_nodes_are_the_average_of_the_four_voxels_meeting_there():
    rng = np.random.default_rng(1)
    h = rng.normal(size=(9, 9))
    c = rng.uniform(size=(9, 9, 3))
    (h1, c1) = level_nodes(h, c, 2)[1]
    voxel = 0.25 * (h[:-1, :-1] + h[:-1, 1:] + h[1:, :-1] + h[1:, 1:])
    cvox = 0.25 * (c[:-1, :-1] + c[:-1, 1:] + c[1:, :-1] + c[1:, 1:])
    # interior coarse node (2, 1) is fine node (4, 2): voxels (3..4, 1..2) meet there
    assert h1[2, 1] == pytest.approx(voxel[3:5, 1:3].mean())
    np.testing.assert_allclose(c1[2, 1], cvox[3:5, 1:3].mean(axis=(0, 1)))
    # a colour edge node averages the voxels that exist: fine node (0, 2) has voxels (0, 1..2)
    np.testing.assert_allclose(c1[0, 1], cvox[0, 1:3].mean(axis=0))


def test_colours_are_averaged_in_linear_space():
    n = 8
    c = np.zeros((n + 1, n + 1, 3))
    c[:, 1::2] = 1.0  # black and white node columns: every voxel averages to 0.5 linear
    db = build_terrain(np.zeros((n + 1, n + 1)), c, spacing_m=1.0, origin=(0, 0, 0), page_size=4)
    coarse = db.rgb[db.page_index(1, 0, 0)]
    # linear 0.5 is sRGB 188; averaging the encoded 0 and 255 would give 128
    assert (coarse == 188).all()


def test_page_table_and_page_content_round_trip(assemble):
    rng = np.random.default_rng(7)
    ny, nx, page = 37, 53, 8
    h = rng.uniform(-10, 10, (ny + 1, nx + 1))
    c = rng.uniform(0, 1, (ny + 1, nx + 1, 3))
    db = build_terrain(h, c, spacing_m=5.0, origin=(10.0, 20.0, 30.0), page_size=page)
    assert db.levels == 4 and list(db.pages_x) == [7, 4, 2, 1] and list(db.pages_y) == [5, 3, 2, 1]
    assert list(db.table_offset) == [0, 35, 47, 51] and db.page_table.size == 52
    assert sorted(db.page_table) == list(range(52))  # every page stored once
    assert db.z.shape == (52, page, page, 4) and db.rgb.shape == (52, page, page, 4, 3)
    heights, rgb, pattern = assemble(db, 0)
    np.testing.assert_array_equal(heights, h.astype(np.float32))
    np.testing.assert_array_equal(rgb, linear_to_srgb8(c))
    assert not pattern.any()
    # voxel (i, j) corner order: sw, se, nw, ne
    k = db.page_index(0, 2, 3)
    for corner, (dx, dy) in enumerate(CORNERS):
        assert db.z[k, 1, 4, corner] == np.float32(h[3 * page + 1 + dy, 2 * page + 4 + dx])
    for level, (hl, cl) in enumerate(level_nodes(h, c, db.levels)):
        got_h, got_rgb, _ = assemble(db, level)
        np.testing.assert_allclose(got_h, hl, atol=1e-4)
        np.testing.assert_array_equal(got_rgb, linear_to_srgb8(cl))
    assert db.z_min == pytest.approx(h.min(), abs=1e-4) and db.z_max == pytest.approx(h.max(), abs=1e-4)
    assert db.page_index(0, 7, 0) == -1 and db.page_index(0, -1, 0) == -1


def test_border_pages_hold_copies_of_the_edge_voxels_not_garbage():
    rng = np.random.default_rng(3)
    ny, nx, page = 10, 13, 8  # the second page column has 5 real voxels, the second row 2
    h = rng.uniform(0, 100, (ny + 1, nx + 1))
    db = build_terrain(h, grey((ny + 1, nx + 1)), spacing_m=1.0, origin=(0, 0, 0), page_size=page)
    k = db.page_index(0, 1, 1)
    edge_x, edge_y = nx - 1 - page, ny - 1 - page  # last real voxel inside the page
    for vy in range(page):
        for vx in range(page):
            sy, sx = min(vy, edge_y), min(vx, edge_x)
            np.testing.assert_array_equal(db.z[k, vy, vx], db.z[k, sy, sx])
            np.testing.assert_array_equal(db.rgb[k, vy, vx], db.rgb[k, sy, sx])
    assert np.isfinite(db.z).all()


def flat_with_a_hill(n=64):
    j, i = np.mgrid[0:n + 1, 0:n + 1]
    h = 50.0 * np.exp(-((i - 8.0) ** 2 + (j - 8.0) ** 2) / 8.0)
    return h, grey((n + 1, n + 1), 0.2)


def test_pruning_drops_the_pages_of_a_flat_region_and_keeps_the_coarsest_level(assemble):
    h, c = flat_with_a_hill()
    full = build_terrain(h, c, spacing_m=10.0, origin=(0, 0, 0), page_size=8)
    db = build_terrain(h, c, spacing_m=10.0, origin=(0, 0, 0), page_size=8, prune_tolerance=(0.05, 0.002))
    missing = int((db.page_table < 0).sum())
    assert missing > 0 and db.info["build"]["pruned_pages"] == missing
    assert sum(db.info["build"]["pruned_pages_per_level"]) == missing
    assert db.z.shape[0] == full.z.shape[0] - missing  # pruned data is not stored
    top = db.levels - 1
    assert all(db.page_index(top, px, py) >= 0 for px in range(db.pages_x[top]) for py in range(db.pages_y[top]))
    assert db.page_index(0, 1, 1) >= 0  # the hill (around voxel 8, 8) is kept
    assert db.page_index(0, 7, 7) == -1  # far flat corner is left out
    for level in range(db.levels - 1):  # a page is only missing where its coarser page exists
        for py in range(db.pages_y[level]):
            for px in range(db.pages_x[level]):
                if db.page_index(level, px, py) < 0:
                    assert db.page_index(level + 1, px // 2, py // 2) >= 0
    # kept pages hold exactly what the unpruned build holds
    for level in range(db.levels):
        for py in range(db.pages_y[level]):
            for px in range(db.pages_x[level]):
                k = db.page_index(level, px, py)
                if k >= 0:
                    np.testing.assert_array_equal(db.z[k], full.z[full.page_index(level, px, py)])


def test_without_tolerance_nothing_is_pruned_and_patterned_pages_are_never_pruned():
    n = 32
    mask = np.zeros((n, n), np.uint8)
    mask[28, 28] = 1  # one tree in the far corner of the flat field
    db = build_terrain(np.zeros((n + 1, n + 1)), grey((n + 1, n + 1)), spacing_m=10.0, origin=(0, 0, 0),
                       page_size=8, prune_tolerance=(1.0, 1.0), pattern_mask=mask, patterns=[TREE_PATTERN])
    assert db.page_index(0, 3, 3) >= 0
    assert db.page_index(0, 0, 0) == -1


def test_pattern_flags_at_level_0_only_and_canopy_colours_at_coarser_levels(assemble):
    n = 32
    ground = 0.05
    mask = np.zeros((n, n), np.uint8)
    mask[8:24, 8:24] = 2
    building = Pattern("shed", np.array([4.0], np.float32), np.array([[200, 0, 0]], np.uint8))
    db = build_terrain(np.full((n + 1, n + 1), 7.0), grey((n + 1, n + 1), ground), spacing_m=10.0,
                       origin=(0, 0, 0), page_size=8, pattern_mask=mask, patterns=[building, TREE_PATTERN])
    _, rgb0, pattern0 = assemble(db, 0)
    np.testing.assert_array_equal(pattern0, mask)
    assert (rgb0 == linear_to_srgb8(np.array([ground]))[0]).all()  # the ground under the trees
    canopy = TREE_PATTERN.rgb[-1]
    for level in range(1, db.levels):
        _, rgb, pattern = assemble(db, level)
        assert not pattern.any()
        centre = rgb.shape[0] // 2
        np.testing.assert_allclose(srgb8_to_linear(rgb[centre, centre]), srgb8_to_linear(canopy), atol=0.004)
        np.testing.assert_array_equal(rgb[0, 0], linear_to_srgb8(np.array([ground] * 3)))
    assert db.z_max == pytest.approx(7.0 + 14.0)
    assert db.z_min == pytest.approx(7.0)


@pytest.mark.parametrize("kwargs,field", [
    ({"heights": np.zeros((1, 5))}, "heights"),
    ({"colours": np.zeros((5, 5, 4))}, "colours"),
    ({"heights": np.full((5, 5), np.nan)}, "heights"),
    ({"colours": np.full((5, 5, 3), 2.0)}, "colours"),
    ({"spacing_m": 0.0}, "spacing_m"),
    ({"origin": (0, 0)}, "origin"),
    ({"page_size": 0}, "page_size"),
    ({"pattern_mask": np.ones((4, 4), np.uint8)}, "pattern_mask: value 1"),
    ({"pattern_mask": np.ones((3, 4), np.uint8)}, "pattern_mask"),
    ({"prune_tolerance": (-1.0, 0.0)}, "prune_tolerance"),
])
def test_bad_inputs_are_named(kwargs, field):
    args = {"heights": np.zeros((5, 5)), "colours": grey((5, 5)), "spacing_m": 1.0, "origin": (0, 0, 0),
            "page_size": 4, **kwargs}
    with pytest.raises(TerrainError, match=field):
        build_terrain(args.pop("heights"), args.pop("colours"), **args)
