"""save_terrain / load_terrain: round trip (memory-mapped or not) and every validation error."""

from __future__ import annotations

import json

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain.build import build_terrain
from channel_worker.pipeline.scene.terrain.database import TerrainError
from channel_worker.pipeline.scene.terrain.features import BUILDING_PATTERN, TREE_PATTERN
from channel_worker.pipeline.scene.terrain.store import load_terrain, save_terrain


@pytest.fixture(scope="module")
def small_db():
    rng = np.random.default_rng(5)
    ny, nx = 21, 30
    h = rng.uniform(-3, 40, (ny + 1, nx + 1))
    c = rng.uniform(0, 1, (ny + 1, nx + 1, 3))
    mask = np.zeros((ny, nx), np.uint8)
    mask[2:5, 3:9] = 1
    mask[10, 10] = 2
    return build_terrain(h, c, spacing_m=2.5, origin=(-40.0, -30.0, 120.0), page_size=8,
                         pattern_mask=mask, patterns=[TREE_PATTERN, BUILDING_PATTERN],
                         info={"source": "test", "licence": "CC0", "nested": {"a": [1, 2]}})


@pytest.mark.parametrize("mmap", [True, False])
def test_save_load_round_trip(small_db, tmp_path, mmap):
    path = save_terrain(small_db, tmp_path / "t.igt")
    db = load_terrain(path, mmap=mmap)
    assert isinstance(db.z, np.memmap) == mmap and isinstance(db.rgb, np.memmap) == mmap
    for name in ("z", "rgb", "pattern", "page_table", "pages_x", "pages_y", "table_offset", "origin"):
        np.testing.assert_array_equal(getattr(db, name), getattr(small_db, name))
        assert getattr(db, name).dtype == getattr(small_db, name).dtype
    for name in ("spacing_m", "nx", "ny", "page_size", "levels", "z_min", "z_max", "info"):
        assert getattr(db, name) == getattr(small_db, name)
    assert [p.name for p in db.patterns] == ["tree", "building"]
    for got, want in zip(db.patterns, small_db.patterns, strict=True):
        np.testing.assert_array_equal(got.top_m, want.top_m)
        np.testing.assert_array_equal(got.rgb, want.rgb)
        assert got.top_m.dtype == np.float32 and got.rgb.dtype == np.uint8
    assert db.source == str(path)
    if mmap:
        with pytest.raises(ValueError):
            db.z[0, 0, 0, 0] = 1.0  # read-only mapping


def test_a_pruned_database_round_trips(tmp_path):
    h = np.zeros((65, 65))
    db = build_terrain(h, np.full((65, 65, 3), 0.3), spacing_m=1.0, origin=(0, 0, 0), page_size=8,
                       prune_tolerance=(0.1, 0.01))
    assert (db.page_table < 0).any()
    back = load_terrain(save_terrain(db, tmp_path / "p.igt"))
    np.testing.assert_array_equal(back.page_table, db.page_table)


def header(path):
    return json.loads((path / "terrain.json").read_text())


def write_header(path, doc):
    (path / "terrain.json").write_text(json.dumps(doc))


def edit_header(**changes):
    def apply(path):
        doc = header(path)
        for key, value in changes.items():
            if value is _DELETE:
                del doc[key]
            else:
                doc[key] = value
        write_header(path, doc)
    return apply


def edit_array(name, change):
    def apply(path):
        a = np.load(path / f"{name}.npy")
        np.save(path / f"{name}.npy", change(a))
    return apply


def set_item(index, value):
    def change(a):
        a = a.copy()
        a[index] = value
        return a
    return change


def edit_pattern(**changes):
    def apply(path):
        doc = header(path)
        doc["patterns"][0].update(changes)
        write_header(path, doc)
    return apply


_DELETE = object()

CASES = {
    "format": (edit_header(format="ig-terrain/2"), "terrain.json: format: 'ig-terrain/2' is not 'ig-terrain/1'"),
    "spacing": (edit_header(spacing_m=-1), "terrain.json: spacing_m: -1 is not a finite number > 0"),
    "spacing bool": (edit_header(spacing_m=True), "spacing_m: True"),
    "origin": (edit_header(origin=[0, 0]), "terrain.json: origin: [0, 0] is not 3 finite numbers"),
    "nx": (edit_header(nx=0), "terrain.json: nx: 0 is not a whole number"),
    "page_size": (edit_header(page_size=2.5), "terrain.json: page_size: 2.5"),
    "levels": (edit_header(levels=7), "terrain.json: levels: 7 is not a whole number in [3, 3]"),
    "pages_x": (edit_header(pages_x=[9, 2, 1]), "terrain.json: pages_x: [9, 2, 1] is not [4, 2, 1]"),
    "table_offset": (edit_header(table_offset=[0, 12, 13]), "terrain.json: table_offset: [0, 12, 13]"),
    "z range": (edit_header(z_max=-100.0), "terrain.json: z_max: -100.0 is below z_min"),
    "z_min nan": (edit_header(z_min="nan"), "terrain.json: z_min: 'nan' is not a finite number"),
    "missing": (edit_header(ny=_DELETE), "terrain.json: ny: missing"),
    "unknown": (edit_header(colour="#fff"), "terrain.json: colour: '#fff' is not a field"),
    "info": (edit_header(info=[]), "terrain.json: info: [] is not a JSON object"),
    "pattern rgb": (edit_pattern(rgb=["#5a432c", "green"]), "terrain.json: patterns[0].rgb: ['#5a432c', 'green']"),
    "pattern top": (edit_pattern(top_m=[3.0, 2.0]), "terrain.json: patterns[0].top_m: [3.0, 2.0]"),
    "patterns": (edit_header(patterns={}), "terrain.json: patterns: {}"),
    "table range": (edit_array("page_table", set_item(3, 999)),
                    "page_table.npy: page_table[3]: 999 is not -1 or a page index in [0, 17)"),
    "table below": (edit_array("page_table", set_item(0, -2)), "page_table.npy: page_table[0]: -2"),
    "coarsest": (edit_array("page_table", set_item(-1, -1)),
                 "page_table.npy: page_table[16]: -1, but the coarsest level 2 must have every page"),
    "table dtype": (edit_array("page_table", lambda a: a.astype(np.int64)), "page_table.npy: dtype: 'int64'"),
    "table shape": (edit_array("page_table", lambda a: a[:-1]), "page_table.npy: shape: (16,) is not (17,)"),
    "z nan": (edit_array("z", set_item((4, 1, 2, 3), np.nan)), "z.npy: z[4]: nan is not finite"),
    "z inf": (edit_array("z", set_item((0, 0, 0, 0), -np.inf)), "z.npy: z[0]: -inf is not finite"),
    "z outside range": (edit_array("z", set_item((1, 0, 0, 0), 1e4)), "z.npy: z: "),
    "z dtype": (edit_array("z", lambda a: a.astype(np.float64)), "z.npy: dtype: 'float64' is not '<f4'"),
    "z big endian": (edit_array("z", lambda a: a.astype(">f4")), "z.npy: dtype: '>f4' is not '<f4'"),
    "z fortran": (edit_array("z", np.asfortranarray), "z.npy: order: Fortran-ordered"),
    "rgb shape": (edit_array("rgb", lambda a: a[..., :2]), "rgb.npy: shape: (17, 8, 8, 4, 2) is not (17, 8, 8, 4, 3)"),
    "pattern shape": (edit_array("pattern", lambda a: a[:-1]), "pattern.npy: shape: (16, 8, 8) is not (17, 8, 8)"),
    "pattern index": (edit_array("pattern", set_item((0, 0, 0), 9)),
                      "pattern.npy: pattern: 9 is not 0 or one of the 2 patterns"),
    "pickled": (edit_array("z", lambda a: np.array([object()] * 2)), "z.npy: not a readable .npy array"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_load_error_names_the_file_field_and_value(small_db, tmp_path, case):
    change, message = CASES[case]
    path = save_terrain(small_db, tmp_path / "t.igt")
    if case == "pickled":  # np.save needs allow_pickle for an object array
        np.save(path / "z.npy", np.array([object()] * 2), allow_pickle=True)
    else:
        change(path)
    with pytest.raises(TerrainError) as exc:
        load_terrain(path)
    assert message in str(exc.value)
    assert str(path) in str(exc.value)


def test_missing_files_and_bad_json_are_named(small_db, tmp_path):
    with pytest.raises(TerrainError, match=r"nowhere.igt/terrain.json: no such file"):
        load_terrain(tmp_path / "nowhere.igt")
    path = save_terrain(small_db, tmp_path / "t.igt")
    (path / "rgb.npy").unlink()
    with pytest.raises(TerrainError, match=r"t.igt/rgb.npy: no such file"):
        load_terrain(path)
    (path / "terrain.json").write_text("{not json")
    with pytest.raises(TerrainError, match=r"terrain.json: not readable JSON"):
        load_terrain(path)
    (path / "terrain.json").write_text("[1, 2]")
    with pytest.raises(TerrainError, match=r"terrain.json: \(top level\): \[1, 2\] is not a JSON object"):
        load_terrain(path)


def test_info_that_json_cannot_hold_is_refused(small_db, tmp_path):
    from dataclasses import replace
    with pytest.raises(TerrainError, match="info"):
        save_terrain(replace(small_db, info={"bad": float("nan")}), tmp_path / "x.igt")
    with pytest.raises(TerrainError, match="info"):
        save_terrain(replace(small_db, info={"bad": object()}), tmp_path / "y.igt")
    assert not (tmp_path / "x.igt").exists()
