"""The bundled airfield: checked in as generated, valid, facing outwards, loadable, renderable, and
laid out so that the bundled flight carries objects across the seams of the default rig."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from channel_worker.data import build_airfield, modelling
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import bundled_scene_path, demo_scene_path, load_scene
from host_sim.flight import bundled_flight
from services.rig.frame import ChannelSpec, Eyepoint, hpr_matrix
from services.rig.options import RenderOptions


@pytest.fixture(scope="module")
def doc():
    return json.loads(bundled_scene_path().read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def database():
    return load_scene(bundled_scene_path())


def _newell(points: np.ndarray) -> np.ndarray:
    nxt = np.roll(points, -1, axis=0)
    n = np.array([np.sum((points[:, 1] - nxt[:, 1]) * (points[:, 2] + nxt[:, 2])),
                  np.sum((points[:, 2] - nxt[:, 2]) * (points[:, 0] + nxt[:, 0])),
                  np.sum((points[:, 0] - nxt[:, 0]) * (points[:, 1] + nxt[:, 1]))])
    return n / np.linalg.norm(n)


# --- (a) the checked-in file is what the generator writes ---------------------------------------

def test_checked_in_json_is_what_the_generator_writes():
    assert bundled_scene_path() == build_airfield.OUTPUT
    assert demo_scene_path() == build_airfield.TERRAIN_OUTPUT
    expected = modelling.render_json(build_airfield.build_scene())
    assert bundled_scene_path().read_text(encoding="utf-8") == expected, (
        "airfield.json is stale: run python -m channel_worker.data.build_airfield")
    expected = modelling.render_json(build_airfield.build_terrain_scene())
    assert demo_scene_path().read_text(encoding="utf-8") == expected, (
        "airfield_terrain.json is stale: run python -m channel_worker.data.build_airfield")


def test_generator_check_mode(tmp_path, capsys):
    out = tmp_path / "airfield.json"
    out_t = tmp_path / "airfield_terrain.json"
    files = ["--output", str(out), "--terrain-output", str(out_t)]
    assert build_airfield.main(["--check", *files]) == 1  # missing
    assert build_airfield.main(files) == 0
    assert build_airfield.main(["--check", *files]) == 0
    for path in (out, out_t):
        text = path.read_text()
        path.write_text(text + " ")
        assert build_airfield.main(["--check", *files]) == 1
        assert "out of date" in capsys.readouterr().err
        path.write_text(text)


# --- (b) every face planar, convex, facing outwards ----------------------------------------------

def test_every_face_is_planar_and_strictly_convex(doc):
    for name, model in doc["models"].items():
        verts = np.array(model["vertices"], dtype=np.float64)
        for k, face in enumerate(model["faces"]):
            pts = verts[face["indices"]]
            n = _newell(pts)
            size = np.ptp(pts, axis=0).max()
            assert np.abs((pts - pts.mean(axis=0)) @ n).max() <= 1e-3 + 1e-3 * size, (name, k)
            edges = np.roll(pts, -1, axis=0) - pts
            turns = np.cross(edges, np.roll(edges, -1, axis=0)) @ n
            assert (turns > 0.0).all(), (name, k, "not strictly convex")


def test_solid_parts_face_away_from_their_centroid_and_decals_face_their_way():
    solids = decals = 0
    for name, parts in build_airfield.build_models().items():
        for part in parts:
            verts = np.array(part.vertices, dtype=np.float64)
            centroid = verts.mean(axis=0)
            for k, face in enumerate(part.faces):
                pts = verts[list(face.indices)]
                n = _newell(pts)
                if part.facing is None:
                    assert n @ (pts.mean(axis=0) - centroid) > 0.0, (name, k, "faces inwards")
                    solids += 1
                else:
                    np.testing.assert_allclose(n, part.facing, atol=1e-9,
                                               err_msg=f"{name} face {k}")
                    decals += 1
    assert solids > 200 and decals > 50


def test_file_models_are_their_parts_in_order(doc):
    for name, parts in build_airfield.build_models().items():
        model = doc["models"][name]
        assert len(model["vertices"]) == sum(len(p.vertices) for p in parts), name
        colours = [f.colour for p in parts for f in p.faces]
        assert [f["colour"] for f in model["faces"]] == colours, name


def test_ground_features_lie_where_the_brief_puts_them(doc):
    runway = np.array(doc["models"]["runway"]["vertices"])
    surface = runway[doc["models"]["runway"]["faces"][0]["indices"]]
    np.testing.assert_array_equal(surface.min(axis=0), [-22.5, -1000.0, 0.02])
    np.testing.assert_array_equal(surface.max(axis=0), [22.5, 1000.0, 0.02])
    # Markings lie in the runway's plane, declared on its surface (face 0) one layer up.
    assert {v[2] for v in doc["models"]["runway"]["vertices"]} == {0.02}
    markings = doc["models"]["runway"]["faces"][1:]
    assert len(markings) > 80
    assert all(f["on"] == 0 and f["layer"] == 1 for f in markings)


# --- (c) it loads and renders ---------------------------------------------------------------------

def test_loads_with_a_sensible_size(doc, database):
    stats = modelling.statistics(doc)
    assert database.feature_count == stats["instance_faces"]
    assert 300 <= database.feature_count <= 2000
    assert database.instance_model.shape[0] == stats["instances"]
    assert len(set(database.instance_names)) == len(database.instance_names)  # names are unique
    tower = next(m for m in database.models if m.name == "control_tower")
    glass = [op for op in tower.opacity if op < 1.0]
    assert glass and all(op == pytest.approx(0.4) for op in glass)


def test_the_threshold_view_renders(database):
    img = render_frame(database, ChannelSpec.symmetric("centre", 128, 96, 60.0, 45.0),
                       Eyepoint.of(0.0, -900.0, 3.0, 0.0, 0.0, 0.0), RenderOptions(samples=1))
    assert np.isfinite(img.rgb).all()
    background = (np.all(np.isclose(img.rgb, database.sky_colour), axis=-1)
                  | np.all(np.isclose(img.rgb, database.earth_colour), axis=-1))
    assert (~background).sum() > 1000  # runway, markings, buildings, trees, hills


# --- the scene and the flight are laid out together -----------------------------------------------

#: Azimuth of each seam or outer edge of the default rig (degrees from the nose) -> the yaw of a
#: channel that has it as an edge.
EDGES = {-90.0: -60.0, -30.0: 0.0, 30.0: 0.0, 90.0: 60.0}
TAN_HALF_V = math.tan(math.radians(22.5))
FLIGHT = bundled_flight()


def _cut_by(database, t_s: float, edge_deg: float) -> set[str]:
    """Instances standing up from the ground that the rig's edge at edge_deg cuts at time t_s:
    their vertices lie on both sides of the edge's plane, and within the channels' height."""
    eye = FLIGHT.eyepoint_at(t_s)
    body = hpr_matrix(eye.heading_deg, eye.pitch_deg, eye.roll_deg)
    yaw = math.radians(EDGES[edge_deg])
    axis = np.array([math.sin(yaw), math.cos(yaw)])  # the channel's forward, body x-y
    out = set()
    for i, name in enumerate(database.instance_names):
        model = database.models[database.instance_model[i]]
        if np.ptp(model.vertices[:, 2]) < 1.0:
            continue  # paint on the ground crosses every seam; it proves nothing
        world = model.vertices @ database.instance_rotation[i].T + database.instance_position[i]
        b = (world - eye.position) @ body  # body frame: x right, y forward, z up
        az = np.degrees(np.arctan2(b[:, 0], b[:, 1]))
        depth = b[:, :2] @ axis
        if np.abs(az).max() > 150.0 or (depth <= 0.0).any() or not az.min() < edge_deg < az.max():
            continue
        el = b[:, 2] / depth
        if el.max() >= -TAN_HALF_V and el.min() <= TAN_HALF_V:
            out.add(name)
    return out


@pytest.mark.parametrize("t_s, edge_deg, name", [
    (0.0, -30.0, "hill 4"),  # the skyline crosses the seams from the first frame
    (2.0, -30.0, "control tower"),  # take-off roll
    (3.0, 30.0, "hangar 2"),
    (5.0, 30.0, "hangar 3"),
    (7.5, -30.0, "fire station"),  # rotation
    (8.0, 30.0, "hangar 4"),
    (10.0, -30.0, "fuel tank 1"),  # climb
    (11.0, 30.0, "terminal"),  # roll-in
    (14.0, -30.0, "wood 8"),  # banked turn: the right seam looks at the sky
    (14.0, -90.0, "fire station"),
    (17.0, -30.0, "town block_tall 1"),  # roll-out, push-over, descent
    (20.0, 30.0, "factory"),
    (20.0, -30.0, "town block_mid 2"),
    (20.0, -90.0, "farm silo"),
    (20.0, 90.0, "cargo shed 1"),
])
def test_the_flight_carries_objects_across_the_seams(database, t_s, edge_deg, name):
    cut = _cut_by(database, t_s, edge_deg)
    assert name in cut, f"{FLIGHT.phase_at(t_s)}: the edge cuts {sorted(cut)}"
