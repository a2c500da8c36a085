"""Scene limits (docs/scene-format.md, Limits): each accepted at its value, refused one past it
with the JSON path and the count, before anything is built from the document."""

import json
import math

import pytest

from channel_worker.pipeline.scene import load
from channel_worker.pipeline.scene.load import SceneError, load_scene, parse_scene

from ..conftest import box_model, scene_doc


def polygon_model(n: int, radius: float = 50.0) -> dict:
    """A regular n-gon lying on the ground, counter-clockwise seen from above: one face."""
    vertices = [[radius * math.cos(2 * math.pi * i / n), radius * math.sin(2 * math.pi * i / n), 0.0]
                for i in range(n)]
    return {"vertices": vertices, "faces": [{"indices": list(range(n)), "colour": "#ff0000"}]}


def one(model: dict, instances: int = 1) -> dict:
    return scene_doc({"m": model}, [{"model": "m", "position": [0, 0, 0]}] * instances)


def test_face_vertices_at_the_limit_load_and_one_more_is_refused():
    db = parse_scene(one(polygon_model(load.MAX_FACE_VERTICES)))
    assert int(db.faces.face_size[0]) == load.MAX_FACE_VERTICES == 64
    with pytest.raises(SceneError, match=r"^<scene>: models.m.faces\[0\].indices: 65 vertices, more than "
                                         r"the 64 a face may have"):
        parse_scene(one(polygon_model(65)))


def test_a_100k_vertex_face_is_refused_before_any_vertex_is_checked(monkeypatch):
    doc = one(polygon_model(100_000))

    def vec3(*args):
        raise AssertionError("a vertex was validated before the face's size was checked")
    # Refused from the list's length, before 100000 vertices are validated one by one (seconds).
    monkeypatch.setattr(load._Parser, "vec3", vec3)
    with pytest.raises(SceneError, match=r"models.m.faces\[0\].indices: 100000 vertices, more than the 64"):
        parse_scene(doc)


def test_model_vertices_at_the_limit_load_and_one_more_is_refused():
    model = box_model(2, 2, 2)
    model["vertices"] += [[0.0, 0.0, 1.0]] * (load.MAX_MODEL_VERTICES - 8)
    assert parse_scene(one(model)).models[0].vertices.shape == (65_536, 3)
    model["vertices"].append([0.0, 0.0, 1.0])
    with pytest.raises(SceneError, match=r"models.m.vertices: 65537 vertices, more than the 65536 a model"):
        parse_scene(one(model))


def test_model_faces_past_the_limit_are_refused():
    model = box_model(2, 2, 2)
    model["faces"] = (model["faces"] * 10_923)[:load.MAX_MODEL_FACES + 1]
    with pytest.raises(SceneError, match=r"models.m.faces: 65537 faces, more than the 65536 a model may have"):
        parse_scene(one(model))


def test_model_faces_at_the_limit_load(monkeypatch):
    # At the real limit the load validates 65536 faces in Python (seconds): the same check
    # at a small limit.
    monkeypatch.setattr(load, "MAX_MODEL_FACES", 6)
    parse_scene(one(box_model(2, 2, 2)))
    monkeypatch.setattr(load, "MAX_MODEL_FACES", 5)
    with pytest.raises(SceneError, match=r"models.m.faces: 6 faces, more than the 5 a model may have"):
        parse_scene(one(box_model(2, 2, 2)))


def test_scene_faces_past_the_limit_name_the_instance():
    instances = -(-load.MAX_SCENE_FACES // 6)  # 166667 boxes: 1000002 faces
    with pytest.raises(SceneError, match=r"instances\[166666\]: 1000002 faces drawn over the instances so "
                                         r"far, more than the 1000000 a scene may have"):
        parse_scene(one(box_model(2, 2, 2), instances))


def test_scene_faces_and_face_vertices_at_the_limit_load(monkeypatch):
    monkeypatch.setattr(load, "MAX_SCENE_FACES", 12)
    monkeypatch.setattr(load, "MAX_SCENE_FACE_VERTICES", 48)
    assert parse_scene(one(box_model(2, 2, 2), 2)).feature_count == 12
    with pytest.raises(SceneError, match=r"instances\[2\]: 18 faces drawn over the instances so far, more "
                                         r"than the 12 a scene may have"):
        parse_scene(one(box_model(2, 2, 2), 3))
    monkeypatch.setattr(load, "MAX_SCENE_FACES", 100)
    monkeypatch.setattr(load, "MAX_SCENE_FACE_VERTICES", 47)
    with pytest.raises(SceneError, match=r"instances\[1\]: 48 face vertices drawn over the instances so far, "
                                         r"more than the 47 a scene may have"):
        parse_scene(one(box_model(2, 2, 2), 2))


def test_a_smooth_model_counts_the_triangles_it_is_drawn_as(monkeypatch):
    monkeypatch.setattr(load, "MAX_SCENE_FACES", 11)
    parse_scene(one(box_model(2, 2, 2)))  # 6 quads
    smooth = {**box_model(2, 2, 2), "smooth": True}  # 12 triangles
    with pytest.raises(SceneError, match=r"instances\[0\]: 12 faces drawn"):
        parse_scene(one(smooth))


def test_scene_file_size_at_the_limit_loads_and_one_more_byte_is_refused(tmp_path, monkeypatch):
    text = json.dumps(one(box_model(2, 2, 2)))
    monkeypatch.setattr(load, "MAX_SCENE_BYTES", len(text) + 10)
    path = tmp_path / "s.json"
    path.write_text(text + " " * 10)
    assert load_scene(path).feature_count == 6
    path.write_text(text + " " * 11)
    with pytest.raises(SceneError, match=rf"s.json: more than {len(text) + 10} bytes, the most a scene file"):
        load_scene(path)


def test_the_real_file_limit_is_16_mib():
    assert load.MAX_SCENE_BYTES == 16 * 1024 * 1024


@pytest.mark.parametrize("text,pattern", [
    ("[" * 100_000 + "]" * 100_000, r"invalid JSON: nested too deeply"),
    ('{"format": ' + "1" * 5000 + "}", r"invalid JSON: Exceeds the limit"),
])
def test_json_a_parser_cannot_hold_is_a_scene_error(tmp_path, text, pattern):
    path = tmp_path / "s.json"
    path.write_text(text)
    with pytest.raises(SceneError, match=pattern):
        load_scene(path)


def test_an_integer_beyond_float64_is_not_finite():
    doc = one(box_model(2, 2, 2))
    doc["instances"][0]["position"] = [10 ** 400, 0, 0]
    with pytest.raises(SceneError, match=r"instances\[0\].position\[0\]: 1000.* is not finite"):
        parse_scene(doc)


@pytest.mark.parametrize("name", ["airfield.json", "airfield_terrain.json"])
def test_bundled_scenes_are_well_within_the_limits(name):
    path = load.bundled_scene_path().parent / name
    doc = json.loads(path.read_text())
    assert path.stat().st_size < load.MAX_SCENE_BYTES / 100
    models = doc["models"].values()
    assert max(len(f["indices"]) for m in models for f in m["faces"]) <= load.MAX_FACE_VERTICES // 4
    assert max(len(m["vertices"]) for m in models) <= load.MAX_MODEL_VERTICES // 100
    faces = sum(len(doc["models"][i["model"]]["faces"]) for i in doc["instances"])
    assert faces <= load.MAX_SCENE_FACES // 100
