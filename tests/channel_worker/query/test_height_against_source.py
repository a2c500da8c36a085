"""Height of terrain against the terrain source: a DEM-like node grid built into a database
with build_terrain (every level, pages, page tables), queried at random points, compared with
the bilinear interpolation of the source nodes themselves.

The terrain documentation states the tolerance: the stored corners are the source heights in
float32, and a pruned database reproduces its pages within the prune tolerance DZ
(docs/terrain-database.md, docs/cigi-queries.md)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain.build import build_terrain
from channel_worker.query.heights import height_of_terrain

from .conftest import scene

SPACING = 30.0
ORIGIN = (-4000.0, -3000.0, 0.0)


def source_nodes(seed: int) -> np.ndarray:
    """A 257 x 257 node grid (heights 0-700 m, like the bundled DEM): rolling hills with noise in
    the east, a gentle slope in the west (which a pruned build leaves to coarser pages)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:257, 0:257] * SPACING
    hills = (350 + 200 * np.sin(x / 900.0) * np.cos(y / 700.0) + 80 * np.sin(x / 230.0 + y / 310.0)
             + rng.normal(0, 3.0, x.shape))
    slope = 300 + 0.02 * x + 0.01 * y
    return np.where(x < 128 * SPACING, slope, hills)


def bilinear(h: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The source's own surface: bilinear between its nodes."""
    u, v = (x - ORIGIN[0]) / SPACING, (y - ORIGIN[1]) / SPACING
    i, j = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - i, v - j
    return ((1 - fu) * (1 - fv) * h[j, i] + fu * (1 - fv) * h[j, i + 1] + (1 - fu) * fv * h[j + 1, i]
            + fu * fv * h[j + 1, i + 1])


@pytest.mark.parametrize("prune_m", [None, 0.5])
def test_hot_is_the_source_surface_within_the_stated_tolerance(prune_m):
    h = source_nodes(5)
    colours = np.full(h.shape + (3,), 0.3)
    terrain = build_terrain(h, colours, spacing_m=SPACING, origin=ORIGIN, page_size=32,
                            prune_tolerance=None if prune_m is None else (prune_m, 1.0))
    db = dataclasses.replace(scene(), terrain=terrain)
    rng = np.random.default_rng(11)
    x = ORIGIN[0] + rng.uniform(0, 256 * SPACING, 2000)
    y = ORIGIN[1] + rng.uniform(0, 256 * SPACING, 2000)
    got = height_of_terrain(db, x, y, np.full(x.shape, np.inf))
    assert got.valid.all()
    error = np.abs(got.height_m - bilinear(h, x, y))
    # float32 keeps 24 bits: 700 m to within 2^-14 m (61 micrometres), and a bilinear mix of
    # four such corners no worse.
    float32_m = float(np.spacing(np.float32(h.max())))
    if prune_m is None:
        assert error.max() <= float32_m
    else:
        assert terrain.info["build"]["pruned_pages"] > 0  # the west is answered from coarser pages
        assert error.max() <= prune_m + float32_m
