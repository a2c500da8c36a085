"""The scene file's "terrain" and "haze" keys (channel_worker/pipeline/scene.py): what loads,
where relative database paths are taken from, and that every error names the field and value."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from channel_worker.pipeline.scene.load import (
    DEFAULT_HAZE_SCALE_HEIGHT_M,
    SceneError,
    load_scene,
    parse_scene,
)
from channel_worker.pipeline.scene.terrain.store import save_terrain
from channel_worker.testing.terrain_reference import single_level_database

from ..terrain_fixtures import linear

ORIGIN = (5.0, 6.0, 7.0)


def small_db():
    h = np.arange(81, dtype=np.float32).reshape(9, 9) * 0.5
    c = np.full((9, 9, 3), 100, np.uint8)
    return single_level_database(h, c, 10.0, np.array(ORIGIN), page_size=8)


def doc(**extra) -> dict:
    base = {"format": "ig-scene/1", "sky": {"colour": "#808080"}, "earth": {"colour": "#808080"},
            "models": {}, "instances": []}
    base.update(extra)
    return base


@pytest.fixture
def layout(tmp_path):
    """tmp/scenes/ holds the scene files, tmp/data/pad.igt a saved database."""
    save_terrain(small_db(), tmp_path / "data" / "pad.igt")
    (tmp_path / "scenes").mkdir()
    return tmp_path


def write(layout: Path, d: dict, name: str = "scene.json") -> Path:
    path = layout / "scenes" / name
    path.write_text(json.dumps(d))
    return path


def test_terrain_and_haze_load(layout):
    path = write(layout, doc(
        terrain={"database": "../data/pad.igt", "offset_m": [100.0, -200.0, 3.0],
                 "polygon_margin_m": 0.5},
        haze={"visibility_m": 8000.0, "colour": "#c0c8d0", "scale_height_m": 900.0,
              "base_height_m": 250.0}))
    db = load_scene(path)
    t = db.terrain
    # The path is taken from the scene file's directory; offset_m moves the database origin.
    assert Path(t.source).resolve() == (layout / "data" / "pad.igt").resolve()
    assert np.array_equal(t.origin, np.array(ORIGIN) + [100.0, -200.0, 3.0])
    assert t.nx == t.ny == 8 and t.spacing_m == 10.0
    assert np.array_equal(np.asarray(t.z), np.asarray(small_db().z))
    assert db.terrain_margin_m == 0.5
    hz = db.haze
    assert (hz.visibility_m, hz.scale_height_m, hz.base_height_m) == (8000.0, 900.0, 250.0)
    assert np.allclose(hz.colour, linear("#c0c8d0"), atol=1e-6)


def test_defaults(layout):
    db = load_scene(write(layout, doc(terrain={"database": "../data/pad.igt"},
                                      haze={"visibility_m": 8000.0, "colour": "#c0c8d0"})))
    assert np.array_equal(db.terrain.origin, np.array(ORIGIN))
    assert db.terrain_margin_m == 1.0
    assert db.haze.scale_height_m == DEFAULT_HAZE_SCALE_HEIGHT_M
    assert db.haze.base_height_m == 0.0
    homogeneous = load_scene(write(layout, doc(haze={"visibility_m": 8000.0, "colour": "#c0c8d0",
                                                     "scale_height_m": None})))
    assert math.isinf(homogeneous.haze.scale_height_m) and homogeneous.terrain is None
    plain = load_scene(write(layout, doc()))
    assert plain.terrain is None and plain.haze is None


def test_parse_scene_takes_paths_from_base_dir_or_the_current_directory(layout, monkeypatch):
    d = doc(terrain={"database": "data/pad.igt"})
    assert parse_scene(d, base_dir=layout).terrain.nx == 8
    monkeypatch.chdir(layout)
    assert parse_scene(d).terrain.nx == 8
    absolute = doc(terrain={"database": str(layout / "data" / "pad.igt")})
    assert load_scene(write(layout, absolute)).terrain.nx == 8


def test_bundled_terrain_by_name(layout, monkeypatch):
    # The bundled database is built on first use; here its loader hands back the small one.
    import channel_worker.pipeline.scene.terrain.bundled as bundled

    monkeypatch.setattr(bundled, "load_bundled_terrain", lambda **_: small_db())
    db = parse_scene(doc(terrain={"database": "bundled:jacksboro", "offset_m": [1.0, 2.0, 3.0]}))
    assert np.array_equal(db.terrain.origin, np.array(ORIGIN) + [1.0, 2.0, 3.0])


def _malformed(root: Path) -> dict[str, Path]:
    """Database directories broken in different ways."""
    out = {}
    empty = root / "empty.igt"
    empty.mkdir()
    out["no header"] = empty
    bad_json = root / "badjson.igt"
    save_terrain(small_db(), bad_json)
    (bad_json / "terrain.json").write_text("{ not json")
    out["bad json"] = bad_json
    wrong = root / "wrong.igt"
    save_terrain(small_db(), wrong)
    head = json.loads((wrong / "terrain.json").read_text())
    head["spacing_m"] = -1.0
    (wrong / "terrain.json").write_text(json.dumps(head))
    out["bad field"] = wrong
    short = root / "short.igt"
    save_terrain(small_db(), short)
    (short / "z.npy").unlink()
    out["missing array"] = short
    return out


@pytest.mark.parametrize("kind", ["no header", "bad json", "bad field", "missing array"])
def test_a_malformed_database_is_refused_naming_it(layout, kind):
    broken = _malformed(layout / "data")[kind]
    path = write(layout, doc(terrain={"database": f"../data/{broken.name}"}))
    with pytest.raises(SceneError) as err:
        load_scene(path)
    msg = str(err.value)
    assert str(path) in msg and "terrain.database" in msg and broken.name in msg, msg


ERRORS = {
    # name: (scene keys, field the message must name, value it must show)
    "missing database": ({"terrain": {}}, "terrain", "database"),
    "database not a string": ({"terrain": {"database": 3}}, "terrain.database", "3"),
    "empty database": ({"terrain": {"database": ""}}, "terrain.database", 'got ""'),
    "unknown bundled": ({"terrain": {"database": "bundled:atlantis"}}, "terrain.database",
                        "bundled:atlantis"),
    "no such path": ({"terrain": {"database": "../data/nowhere.igt"}}, "terrain.database",
                     "nowhere.igt"),
    "terrain not an object": ({"terrain": ["pad.igt"]}, "terrain", "pad.igt"),
    "unknown terrain key": ({"terrain": {"database": "../data/pad.igt", "offset": [0, 0, 0]}},
                            "terrain.offset", "unknown key"),
    "short offset": ({"terrain": {"database": "../data/pad.igt", "offset_m": [0, 0]}},
                     "terrain.offset_m", "[0, 0]"),
    "negative margin": ({"terrain": {"database": "../data/pad.igt", "polygon_margin_m": -1.0}},
                        "terrain.polygon_margin_m", "-1"),
    "missing visibility": ({"haze": {"colour": "#c0c8d0"}}, "haze", "visibility_m"),
    "zero visibility": ({"haze": {"visibility_m": 0, "colour": "#c0c8d0"}}, "haze.visibility_m",
                        "0"),
    "negative visibility": ({"haze": {"visibility_m": -5, "colour": "#c0c8d0"}},
                            "haze.visibility_m", "-5"),
    "nan visibility": ({"haze": {"visibility_m": "fog", "colour": "#c0c8d0"}},
                       "haze.visibility_m", "fog"),
    "colour without hash": ({"haze": {"visibility_m": 5000, "colour": "c0c8d0"}}, "haze.colour",
                            "c0c8d0"),
    "colour not hex": ({"haze": {"visibility_m": 5000, "colour": "#c0c8dz"}}, "haze.colour",
                       "#c0c8dz"),
    "colour not a string": ({"haze": {"visibility_m": 5000, "colour": [1, 1, 1]}}, "haze.colour",
                            "[1, 1, 1]"),
    "zero scale height": ({"haze": {"visibility_m": 5000, "colour": "#c0c8d0",
                                    "scale_height_m": 0}}, "haze.scale_height_m", "0"),
    "unknown haze key": ({"haze": {"visibility_m": 5000, "colour": "#c0c8d0", "density": 3}},
                         "haze.density", "unknown key"),
}


@pytest.mark.parametrize("name", list(ERRORS))
def test_every_error_names_the_field_and_value(layout, name):
    keys, field, value = ERRORS[name]
    path = write(layout, doc(**keys))
    with pytest.raises(SceneError) as err:
        load_scene(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: "), msg
    assert re.search(rf"(^|[\s:]){re.escape(field)}([\s:.]|$)", msg), (field, msg)
    assert value in msg, (value, msg)
