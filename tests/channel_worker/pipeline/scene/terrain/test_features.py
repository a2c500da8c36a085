"""Flattened pads and the forest mask."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain.database import TerrainError
from channel_worker.pipeline.scene.terrain.features import (
    BUILDING_PATTERN,
    TREE_PATTERN,
    flatten,
    pad_distance,
    tree_mask,
    voxel_slope_deg,
)


def grid(n=81, spacing=10.0):
    x = (np.arange(n) - n // 2) * spacing
    return x, x.copy()


def test_a_pad_is_flat_inside_and_blends_linearly_outside():
    x, y = grid()
    heights = np.add.outer(y * 0.0, x * 0.0) + 50.0
    out = flatten(heights, x, y, [(-100.0, -50.0, 100.0, 50.0, 10.0, 100.0)])
    inside = (np.abs(x) <= 100)[None, :] & (np.abs(y) <= 50)[:, None]
    assert (out[inside] == 10.0).all()
    j0 = int(np.flatnonzero(y == 0)[0])
    col = {int(v): k for k, v in enumerate(x)}
    assert out[j0, col[150]] == pytest.approx(0.5 * 10.0 + 0.5 * 50.0)  # 50 m into the 100 m blend
    assert out[j0, col[200]] == 50.0 and out[j0, col[300]] == 50.0
    corner = out[int(np.flatnonzero(y == 110)[0]), col[180]]  # 100 m from the corner (60, 80)
    assert corner == pytest.approx(50.0)
    assert heights[0, 0] == 50.0  # input untouched


def test_a_pad_without_blend_is_a_step_and_pads_apply_in_order():
    x, y = grid()
    heights = np.full((81, 81), 5.0)
    out = flatten(heights, x, y, [(-50, -50, 50, 50, 0.0, 0.0), (0, 0, 50, 50, 1.0, 0.0)])
    j0, i0 = int(np.flatnonzero(y == 0)[0]), int(np.flatnonzero(x == 0)[0])
    assert out[j0 - 1, i0 - 1] == 0.0 and out[j0 + 1, i0 + 1] == 1.0 and out[j0, i0 + 6] == 5.0
    with pytest.raises(TerrainError, match="flatten"):
        flatten(heights, x, y, [(50, 0, -50, 10, 0, 0)])
    with pytest.raises(TerrainError, match="flatten"):
        flatten(heights, x, y, [(0, 0, 1, 1, 0)])


def test_trees_are_deterministic_gentle_outside_pads_and_at_the_requested_density():
    x, y = grid(121)
    rng = np.random.default_rng(0)
    heights = np.cumsum(np.cumsum(rng.normal(size=(121, 121)), axis=0), axis=1) * 0.5
    heights[:, :20] += np.arange(20)[None, ::-1] * 20.0  # a cliff strip in the west: 63 degrees
    pads = [(-200.0, -200.0, 100.0, 100.0, 0.0, 50.0)]
    kwargs = {"spacing_m": 10.0, "density": 0.3, "seed": 4, "max_slope_deg": 30.0, "pads": pads}
    mask = tree_mask(heights, x, y, **kwargs)
    assert mask.shape == (120, 120) and mask.dtype == np.uint8 and set(np.unique(mask)) == {0, 1}
    np.testing.assert_array_equal(mask, tree_mask(heights, x, y, **kwargs))
    assert not np.array_equal(mask, tree_mask(heights, x, y, **{**kwargs, "seed": 5}))
    slope = voxel_slope_deg(heights, 10.0)
    assert (slope[mask == 1] < 30.0).all()
    cx, cy = 0.5 * (x[:-1] + x[1:]), 0.5 * (y[:-1] + y[1:])
    near_pad = pad_distance(pads[0], cx[None, :], cy[:, None]) <= 50.0  # the pad and its blend
    assert near_pad.sum() > 30 * 30
    assert not mask[near_pad].any()
    eligible = (slope < 30.0) & ~near_pad
    assert mask.sum() == pytest.approx(0.3 * eligible.sum(), abs=1)
    assert tree_mask(heights, x, y, **{**kwargs, "density": 0.0}).sum() == 0
    with pytest.raises(TerrainError, match=r"density 1.5"):
        tree_mask(heights, x, y, **{**kwargs, "density": 1.5})


def test_trees_prefer_the_ridges():
    x, y = grid(101)
    heights = np.repeat(np.abs(x)[None, :] * 0.2, 101, axis=0)  # a valley along x = 0
    mask = tree_mask(heights, x, y, spacing_m=10.0, density=0.3, seed=1)
    cx = 0.5 * (x[:-1] + x[1:])
    assert mask[:, np.abs(cx) > 300].mean() > 3 * mask[:, np.abs(cx) < 200].mean()


def test_the_default_patterns():
    for pattern in (TREE_PATTERN, BUILDING_PATTERN):
        assert pattern.top_m.dtype == np.float32 and pattern.rgb.dtype == np.uint8
        assert pattern.rgb.shape == (pattern.top_m.size, 3) and np.all(np.diff(pattern.top_m) > 0)
    np.testing.assert_array_equal(TREE_PATTERN.top_m, [3.0, 14.0])
