"""Fixtures of the terrain tests: level reassembly from pages, small grids, the bundled build."""

from __future__ import annotations

import time

import numpy as np
import pytest


def assemble_level(db, level):
    """(heights (sy+1, sx+1), rgb (sy+1, sx+1, 3) uint8, pattern (sy, sx)) of one level, from its
    pages' corners; None for a level that lacks a page."""
    sx, sy = db.level_size(level)
    p = db.page_size
    z = np.full((sy + 1, sx + 1), np.nan, np.float64)
    rgb = np.zeros((sy + 1, sx + 1, 3), np.uint8)
    pattern = np.zeros((sy, sx), np.uint8)
    for py in range(int(db.pages_y[level])):
        for px in range(int(db.pages_x[level])):
            k = db.page_index(level, px, py)
            if k < 0:
                return None
            vy, vx = min(p, sy - py * p), min(p, sx - px * p)
            for c, (dx, dy) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
                rows = slice(py * p + dy, py * p + dy + vy)
                cols = slice(px * p + dx, px * p + dx + vx)
                z[rows, cols] = db.z[k, :vy, :vx, c]
                rgb[rows, cols] = db.rgb[k, :vy, :vx, c]
            pattern[py * p: py * p + vy, px * p: px * p + vx] = db.pattern[k, :vy, :vx]
    return z, rgb, pattern


@pytest.fixture(scope="session")
def assemble():
    return assemble_level


@pytest.fixture(scope="session")
def bundled_build(tmp_path_factory):
    """The bundled terrain built once per session into a temporary IG_CACHE_DIR:
    (cache dir, path, seconds the build took)."""
    from channel_worker.pipeline.scene.terrain.bundled import bundled_terrain_path

    cache = tmp_path_factory.mktemp("ig-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("IG_CACHE_DIR", str(cache))
        t0 = time.perf_counter()
        path = bundled_terrain_path()
        seconds = time.perf_counter() - t0
    return cache, path, seconds
