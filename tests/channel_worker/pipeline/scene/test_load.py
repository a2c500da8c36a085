"""Scene loading: malformed files give errors that name the JSON path and the value."""

import json

import numpy as np
import pytest

from channel_worker.pipeline.scene.load import SceneError, load_scene, parse_scene

from ..conftest import box_model, scene_doc


def doc():
    return scene_doc({"box": box_model(2, 2, 2)}, [{"model": "box", "position": [1, 2, 0], "name": "b1"}])


def test_valid_scene_loads():
    db = parse_scene(doc())
    assert db.feature_count == 6
    assert db.models[0].radius == pytest.approx(np.sqrt(3.0))
    np.testing.assert_allclose(db.models[0].normal[1], [0, 0, 1])  # roof faces up
    np.testing.assert_allclose(db.models[0].normal[0], [0, 0, -1])  # floor faces down


@pytest.mark.parametrize("mutate,pattern", [
    (lambda d: d.update(format="ig-scene/9"), r"format: \"ig-scene/9\" is not 'ig-scene/1'"),
    (lambda d: d["sky"].update(colour="blue"), r"sky.colour: expected a colour '#rrggbb', got \"blue\""),
    (lambda d: d["models"]["box"]["faces"][3]["indices"].__setitem__(2, 17),
     r"models.box.faces\[3\].indices\[2\]: index 17 out of range \(model has 8 vertices\)"),
    (lambda d: d["models"]["box"]["vertices"][0].__setitem__(1, "x"),
     r"models.box.vertices\[0\]\[1\]: expected a number, got \"x\""),
    (lambda d: d["instances"][0].update(model="shed"), r"instances\[0\].model: \"shed\" is not a model"),
    (lambda d: d["instances"][0].update(position=[0, 0]), r"instances\[0\].position: expected \[x, y, z\]"),
    (lambda d: d["instances"][0].update(colour="#ffffff"), r"instances\[0\].colour: unknown key"),
    (lambda d: d["models"]["box"]["faces"][0].update(opacity=1.5), r"faces\[0\].opacity: 1.5 is outside"),
    (lambda d: d["models"]["box"]["vertices"][6].__setitem__(2, 2.5), r"faces\[1\].indices: the face is not planar"),
    (lambda d: d["models"]["box"]["vertices"].__setitem__(6, [-0.5, -0.5, 2]),
     r"faces\[1\].indices: the face is not convex"),
    (lambda d: d["models"]["box"]["faces"][1].update(indices=[4, 6, 5, 7]),
     r"faces\[1\].indices: the face has no area"),
    (lambda d: d["models"]["box"]["faces"][1].update(indices=[4, 5, 4]),
     r"faces\[1\].indices: \[4, 5, 4\] repeats a vertex"),
    (lambda d: d.pop("earth"), r"missing key 'earth'"),
])
def test_malformed_scene_names_path_and_value(mutate, pattern):
    d = doc()
    mutate(d)
    with pytest.raises(SceneError, match=pattern):
        parse_scene(d, source="s.json")


def test_invalid_json_names_line(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"format": "ig-scene/1",\n "sky": }')
    with pytest.raises(SceneError, match=r"bad.json: line 2 column 9: invalid JSON"):
        load_scene(p)


def test_missing_file(tmp_path):
    with pytest.raises(SceneError, match="cannot read"):
        load_scene(tmp_path / "none.json")


def test_nan_in_file_is_rejected(tmp_path):
    d = doc()
    text = json.dumps(d).replace('"position": [1, 2, 0]', '"position": [1, NaN, 0]')
    p = tmp_path / "nan.json"
    p.write_text(text)
    with pytest.raises(SceneError, match=r"instances\[0\].position\[1\]: nan is not finite"):
        load_scene(p)


def _layered(face_extra: dict, *, z2: float = 0.0) -> dict:
    v = [[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0], [2, 2, z2], [4, 2, z2], [4, 4, z2]]
    faces = [{"indices": [0, 1, 2, 3], "colour": "#000000"},
             {"indices": [4, 5, 6], "colour": "#ffffff", **face_extra}]
    return {"format": "ig-scene/1", "sky": {"colour": "#0000ff"}, "earth": {"colour": "#00ff00"},
            "models": {"pad": {"vertices": v, "faces": faces}},
            "instances": [{"model": "pad", "position": [0, 0, 0]}]}


def test_a_face_on_another_shares_its_plane_and_layers_above_it():
    db = parse_scene(_layered({"on": 0, "layer": 3}))
    assert list(db.faces.layer) == [0, 3]
    np.testing.assert_array_equal(db.faces.plane_xyz[1], db.faces.plane_xyz[0])
    np.testing.assert_array_equal(db.faces.normal[1], db.faces.normal[0])


@pytest.mark.parametrize("extra, z2, message", [
    ({"layer": 1}, 0.0, r"faces\[1\]\.layer: a layer needs \"on\""),
    ({"on": 1}, 0.0, r"faces\[1\]\.on: expected the index of an earlier face .* got 1"),
    ({"on": 0, "layer": 0}, 0.0, r"faces\[1\]\.layer: .* got 0"),
    ({"on": 0}, 0.5, r"faces\[1\]\.on: the face is not on face 0 \(a vertex lies 0\.5 m"),
])
def test_bad_layers_are_named(extra, z2, message):
    with pytest.raises(SceneError, match=message):
        parse_scene(_layered(extra, z2=z2))


@pytest.mark.parametrize("text,message", [
    ('{"polygons": "nope"}', "wrongtype.json: (top level): missing key "),
    ('[1, 2]', "wrongtype.json: (top level): expected an object, got [1, 2]"),
    ('"a scene"', 'wrongtype.json: (top level): expected an object, got "a scene"'),
])
def test_an_error_of_the_whole_document_names_the_top_level(tmp_path, text, message):
    # The document's own JSON path is empty: the message once read "wrongtype.json: : missing key".
    path = tmp_path / "wrongtype.json"
    path.write_text(text)
    with pytest.raises(SceneError) as exc:
        load_scene(path)
    assert str(exc.value).startswith(f"{tmp_path}/{message}")
