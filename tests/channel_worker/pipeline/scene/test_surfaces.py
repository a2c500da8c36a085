"""Texture codes and smooth shading in the scene format (scene/surfaces.py, load.py), and
their per-frame maps (geometry/surface.py, project.py): exact, rotation-free, far from the
origin."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from channel_worker.pipeline.contract import SUBPIXEL, ScreenPolygons
from channel_worker.pipeline.geometry.backface import eliminate_backfaces
from channel_worker.pipeline.geometry.clip import clip
from channel_worker.pipeline.geometry.cull import cull
from channel_worker.pipeline.geometry.project import project
from channel_worker.pipeline.geometry.transform import to_eye
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.load import SceneError, parse_scene
from channel_worker.pipeline.scene.surfaces import (
    LOOK_AMPLITUDE,
    LOOK_DETAIL,
    LOOK_INTENSITY,
    LOOK_PER_COLOUR,
    LOOK_PRIMARY,
    LOOK_SMOOTH,
    LOOK_TEXTURE,
)
from services.rig.frame import ChannelSpec, Eyepoint

CODE = {"textures": ["chk", "noise"], "intensity": 0.8, "scale_m": [4.0, 2.0],
        "detail_scale_m": [40.0, 50.0], "detail_offset_m": [3.0, 7.0], "amplitudes": [0.5, 0.0],
        "modulation": "colour"}


def doc(models: dict, instances: list, *, codes: dict | None = None) -> dict:
    return {"format": "ig-scene/1", "sky": {"colour": "#8090a0"}, "earth": {"colour": "#405030"},
            "lighting": {"sun_heading_deg": 120.0, "sun_elevation_deg": 35.0, "ambient": 0.3},
            "textures": {"chk": {"procedural": "checker", "size": 64},
                         "noise": {"procedural": "noise", "size": 64, "seed": 2}},
            "texture_codes": {"ground": copy.deepcopy(CODE)} if codes is None else codes,
            "models": models, "instances": instances}


def ground(half: float = 200.0, *, texture: str | None = "ground", plane: dict | None = None) -> dict:
    face: dict = {"indices": [0, 1, 2, 3], "colour": "#808080"}
    if texture is not None:
        face["texture"] = texture
    if plane is not None:
        face["texture_plane"] = plane
    return {"vertices": [[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]],
            "faces": [face]}


def smooth_roof() -> dict:
    """Two quads meeting at a ridge, smooth: fanned into four triangles."""
    v = [[-10, -10, 0], [10, -10, 0], [10, 0, 6], [-10, 0, 6], [10, 10, 0], [-10, 10, 0]]
    return {"vertices": v, "smooth": {"crease_deg": 80.0},
            "faces": [{"indices": [0, 1, 2, 3], "colour": "#c08040"},
                      {"indices": [3, 2, 4, 5], "colour": "#c08040"}]}


def screen_of(db: Database, eye: Eyepoint, size: int = 256) -> tuple[ScreenPolygons, object]:
    view = make_view(ChannelSpec.symmetric("c", size, size, 60.0), eye)
    polys = to_eye(db, cull(db, view), view)
    return project(clip(eliminate_backfaces(polys), view), view), view


def at(screen: ScreenPolygons, p: int, sx: float, sy: float) -> np.ndarray:
    """(u, v, light) of polygon p at screen point (sx, sy), as the kernels evaluate them."""
    d = screen.inv_z[p, 0] * sx + screen.inv_z[p, 1] * sy + screen.inv_z[p, 2]
    m = screen.surface[p].reshape(3, 3)
    return (m[:, 0] * sx + m[:, 1] * sy + m[:, 2]) / d


def screen_point(view, world: np.ndarray) -> tuple[float, float]:
    """Where a world point appears on the screen, pixels."""
    e = view.world_to_eye @ (world - view.eye)
    tx, ty = e[0] / e[2], e[1] / e[2]
    w, h = view.width, view.height
    sx = (tx - view.tan_left) / (view.tan_right - view.tan_left) * w
    sy = (view.tan_top - ty) / (view.tan_top - view.tan_bottom) * h
    return sx, sy


# ---------------------------------------------------------------------------------------------
# The scene format.

def test_texture_code_becomes_a_look_row():
    db = parse_scene(doc({"g": ground()}, [{"model": "g", "position": [0, 0, 0]}]))
    assert db.faces.surface.look.tolist() == [0]
    row = db.looks[0]
    assert row[LOOK_SMOOTH] == 0.0
    assert row[LOOK_TEXTURE:LOOK_TEXTURE + 3].tolist() == [0.0, 1.0, -1.0]
    assert row[LOOK_INTENSITY] == pytest.approx(0.8)
    assert row[LOOK_PRIMARY:LOOK_PRIMARY + 2].tolist() == pytest.approx([0.25, 0.5])
    assert row[LOOK_DETAIL:LOOK_DETAIL + 2].tolist() == pytest.approx([1 / 40.0, 1 / 50.0])
    assert row[LOOK_AMPLITUDE:LOOK_AMPLITUDE + 2].tolist() == [0.5, 0.0]
    assert row[LOOK_PER_COLOUR] == 1.0
    # Default texture plane of a ground face: u along model x, v along y, from the origin.
    assert db.faces.surface.tex_map[0].tolist() == [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]


def test_plain_scene_has_no_look():
    db = parse_scene(doc({"g": ground(texture=None)}, [{"model": "g", "position": [0, 0, 0]}], codes={}))
    assert db.faces.surface.look.tolist() == [-1]
    screen, _ = screen_of(db, Eyepoint.of(0, -150, 20, 0, -10, 0))
    assert screen.polygon_count == 1
    assert screen.look.shape == (0,) and not screen.textured


@pytest.mark.parametrize(("mutate", "where", "words"), [
    (lambda d: d["texture_codes"]["ground"].update(textures=["nope"]), "texture_codes.ground.textures[0]",
     "not a texture"),
    (lambda d: d["texture_codes"]["ground"].update(textures=[]), "texture_codes.ground.textures", "1 to 3"),
    (lambda d: d["texture_codes"]["ground"].update(scale_m=[0.0, 1.0]), "texture_codes.ground.scale_m[0]",
     "outside"),
    (lambda d: d["texture_codes"]["ground"].update(modulation="hue"), "texture_codes.ground.modulation",
     "mono"),
    (lambda d: d["texture_codes"]["ground"].update(colour="#fff"), "texture_codes.ground.colour", "unknown"),
    (lambda d: d["models"]["g"]["faces"][0].update(texture="other"), "models.g.faces[0].texture",
     "not a texture code"),
    (lambda d: d["models"]["g"]["faces"][0].update(texture_plane={"u_axis": [0, 0, 1]}),
     "models.g.faces[0].texture_plane.u_axis", "along the face's normal"),
    (lambda d: d["textures"].update(bad={"procedural": "marble"}), "textures.bad.procedural", "marble"),
    (lambda d: d["textures"].update(bad={"image": "missing.png"}), "textures.bad.image", "missing.png"),
    (lambda d: d["textures"].update(bad={"image": "a.png", "bundled": "grass"}), "textures.bad",
     "exactly one"),
])
def test_bad_texture_input_is_named(mutate, where, words):
    d = doc({"g": ground()}, [{"model": "g", "position": [0, 0, 0]}])
    mutate(d)
    with pytest.raises(SceneError) as err:
        parse_scene(d, source="s.json")
    assert f"s.json: {where}" in str(err.value) and words in str(err.value)


def test_texture_plane_without_texture_is_refused():
    d = doc({"g": ground(texture=None, plane={"origin_m": [0, 0, 0]})}, [{"model": "g", "position": [0, 0, 0]}])
    with pytest.raises(SceneError, match=r"models.g.faces\[0\].texture_plane: a texture plane needs"):
        parse_scene(d)


def test_smooth_model_is_triangulated_and_refuses_painted_faces():
    db = parse_scene(doc({"r": smooth_roof()}, [{"model": "r", "position": [0, 0, 0]}]))
    assert db.models[0].face_count == 4
    assert np.all(np.diff(db.models[0].face_start) == 3)
    assert db.looks[db.faces.surface.look[0], LOOK_SMOOTH] == 1.0
    roof = smooth_roof()
    roof["faces"].append({"indices": [0, 1, 2], "colour": "#ffffff", "on": 0})
    with pytest.raises(SceneError, match=r"models.r.faces\[2\].on: a smooth model cannot have painted"):
        parse_scene(doc({"r": roof}, [{"model": "r", "position": [0, 0, 0]}]))


# ---------------------------------------------------------------------------------------------
# Per-frame maps: exact, the same under any screen rotation, far from the origin.

@pytest.mark.parametrize("origin", [0.0, 1.0e6])
@pytest.mark.parametrize("roll", [0.0, 37.0, 90.0, 180.0])
def test_texture_coordinates_are_exact_and_do_not_swim(origin, roll):
    """The texture-plane coordinates at the screen position of fixed world points are their
    true coordinates, whatever the roll (no swimming), 1000 km from the origin too."""
    off = np.array([origin, -origin, 0.0])
    plane = {"origin_m": [5.0, -3.0, 0.0], "u_axis": [1.0, 1.0, 0.0]}
    db = parse_scene(doc({"g": ground(plane=plane)}, [{"model": "g", "position": off.tolist()}]))
    eye = Eyepoint.of(off[0] + 1.0, off[1] - 120.0, 25.0, 10.0, -12.0, roll)
    screen, view = screen_of(db, eye)
    assert screen.textured
    u_axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    v_axis = np.cross([0.0, 0.0, 1.0], u_axis)
    rng = np.random.default_rng(4)
    for world in rng.uniform([-40, -40, 0], [40, 60, 0], size=(20, 3)):
        sx, sy = screen_point(view, off + world)
        if not (0 <= sx < 256 and 0 <= sy < 256):
            continue
        u, v, light = at(screen, 0, sx, sy)
        rel = world - np.array([5.0, -3.0, 0.0])
        assert u == pytest.approx(rel @ u_axis, abs=1e-6)
        assert v == pytest.approx(rel @ v_axis, abs=1e-6)
        assert light == 1.0


def lambert(db: Database, n: np.ndarray) -> float:
    return db.ambient + (1.0 - db.ambient) * max(0.0, float(n @ db.sun))


@pytest.mark.parametrize("roll", [0.0, 90.0, -63.0])
def test_gouraud_light_is_lambert_at_vertices_and_linear_whatever_the_roll(roll):
    """The light at a world point of a smooth triangle is the barycentric mix of its corners'
    Lambert values, at any roll: interpolated in the face, not along scan lines."""
    db = parse_scene(doc({"r": smooth_roof()}, [{"model": "r", "position": [0, 0, 0], "hpr": [20, 0, 0]}]))
    screen, view = screen_of(db, Eyepoint.of(3.0, -45.0, 18.0, 5.0, -18.0, roll))
    rot = db.instance_rotation[0]
    model = db.models[0]
    normals = db.faces.surface.normals
    for k in range(model.face_count):
        corners = model.vertices[model.face_index[model.face_start[k]:model.face_start[k + 1]]]
        lights = [lambert(db, rot @ normals[k, i]) for i in range(3)]
        p = int(np.nonzero(screen.feature_id == k)[0][0]) if (screen.feature_id == k).any() else -1
        if p < 0:
            continue
        for bary in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.3, 0.5], [0.6, 0.3, 0.1]):
            world = rot @ (np.array(bary) @ corners)
            sx, sy = screen_point(view, world)
            value = at(screen, p, sx, sy)[2]
            assert value == pytest.approx(float(np.array(bary) @ lights), abs=1e-9)


def test_screen_numerators_match_the_snapped_vertices():
    """At every projected vertex the map gives that vertex's texture coordinates (to the
    1/SUBPIXEL snap)."""
    db = parse_scene(doc({"g": ground(50.0)}, [{"model": "g", "position": [0, 0, 0]}]))
    screen, view = screen_of(db, Eyepoint.of(0, -30, 40, 0, -50, 0))
    p = 0
    for fx, fy in screen.fixed[screen.start[p]:screen.start[p + 1]] / SUBPIXEL:
        u, v, _ = at(screen, p, fx, fy)
        # Back-project the screen point onto the ground plane z = 0.
        tx = view.tan_left + fx / 256 * (view.tan_right - view.tan_left)
        ty = view.tan_top - fy / 256 * (view.tan_top - view.tan_bottom)
        ray = view.world_to_eye.T @ np.array([tx, ty, 1.0])
        world = view.eye + ray * (-view.eye[2] / ray[2])
        assert (u, v) == pytest.approx((world[0], world[1]), abs=1e-6)
