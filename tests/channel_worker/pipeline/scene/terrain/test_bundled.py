"""The bundled terrain: built once per session into a temporary cache, flat pad at z = 0."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain import bundled
from channel_worker.pipeline.scene.terrain.store import load_terrain


@pytest.fixture(scope="module")
def db(bundled_build):
    return load_terrain(bundled_build[1])


def test_it_is_built_into_the_cache_under_the_recipe_key(bundled_build):
    cache, path, _ = bundled_build
    assert path.parent == cache and path.name == f"jacksboro-{bundled.recipe_key(bundled.BUNDLED_RECIPE)}.igt"
    assert [p.name for p in cache.iterdir()] == [path.name]  # the temporary build directory is gone


def test_the_airfield_pad_is_flat_at_world_z_0(db, assemble):
    heights, _, pattern = assemble(db, 0)
    x = db.origin[0] + np.arange(db.nx + 1) * db.spacing_m
    y = db.origin[1] + np.arange(db.ny + 1) * db.spacing_m
    assert 0.0 in x and 0.0 in y  # world (0, 0), the geodetic origin, is a node
    pad = ((x >= -450) & (x <= 550))[None, :] & ((y >= -1300) & (y <= 1300))[:, None]
    assert pad.sum() > 30 * 80
    np.testing.assert_allclose(db.origin[2] + heights[pad], 0.0, atol=0.01)
    runway = pattern[(np.abs(y[:-1] + 15) < 1300)][:, np.abs(x[:-1] + 15) < 500]
    assert not runway.any()  # no trees on the airfield
    # the blend reaches back to the terrain: 400 m out the pad's heights are the DEM's again
    ring = ((x >= -1000) & (x <= 1100))[None, :] & ((y >= -1850) & (y <= 1850))[:, None] & ~(
        ((x >= -850) & (x <= 950))[None, :] & ((y >= -1700) & (y <= 1700))[:, None])
    assert np.abs(heights[ring]).max() > 5.0


def test_extent_heights_levels_and_info_are_plausible(db):
    east, north = db.extent_m
    assert 28_000 < east < 31_000 and 30_000 < north < 33_000
    assert db.spacing_m == 30.0 and db.page_size == 128 and db.levels == 5
    assert (db.page_table >= 0).all()  # the recipe does not prune
    # the DEM spans 236..1076 m; the pad (349 m) is world 0, the far corners dip ~40 m (curvature)
    assert -200.0 < db.z_min < -50.0 and 650.0 < db.z_max < 800.0
    assert db.patterns[0].name == "tree" and db.info["build"]["pattern_voxels"] > 0.05 * db.nx * db.ny
    assert db.info["recipe"]["origin"] == list(bundled.AIRFIELD_ORIGIN)
    assert "public domain" in db.info["licence"] and db.info["source"].startswith("mpl:jacksboro")


def test_the_cache_is_reused_and_a_changed_recipe_has_another_key(bundled_build, monkeypatch):
    cache, path, _ = bundled_build
    monkeypatch.setenv("IG_CACHE_DIR", str(cache))
    stamp = (path / "z.npy").stat().st_mtime_ns
    assert bundled.bundled_terrain_path() == path
    assert (path / "z.npy").stat().st_mtime_ns == stamp
    changed = {**bundled.BUNDLED_RECIPE, "spacing_m": 60.0}
    assert bundled.recipe_key(changed) != bundled.recipe_key(bundled.BUNDLED_RECIPE)


def test_the_cache_dir_defaults_to_the_user_cache(monkeypatch, tmp_path):
    monkeypatch.delenv("IG_CACHE_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert bundled.cache_dir() == tmp_path / ".cache" / "ig-rig"
