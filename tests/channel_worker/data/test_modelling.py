"""The modelling toolkit: make_part refuses bad faces, the helpers wind faces outwards, and the
document writers produce JSON that reads back as written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from channel_worker.data import modelling
from channel_worker.data.modelling import Face, GeometryError, Instance, make_part

UP = (0.0, 0.0, 1.0)
UNIT_SQUARE = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]


def _normal(points) -> np.ndarray:
    """Right-hand normal from the first corner's edges: enough for the convex faces tested here,
    and independent of the toolkit's own Newell normal."""
    p = np.asarray(points, dtype=np.float64)
    n = np.cross(p[1] - p[0], p[2] - p[1])
    return n / np.linalg.norm(n)


def _signed_area(xy) -> float:
    p = np.asarray(xy, dtype=np.float64)[:, :2]
    q = np.roll(p, -1, axis=0)
    return 0.5 * float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]))


# --- make_part refuses what the scene format forbids ------------------------------------------

def test_make_part_accepts_a_flat_convex_decal_and_rounds_to_millimetres():
    part = make_part([(-0.0004, 0.0, 0.0), (1.00049, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)],
                     [Face((0, 1, 2, 3), "#ffffff")], facing=UP)
    assert part.vertices[:2] == ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    assert "-0.0" not in repr(part.vertices)  # -0.0004 rounds to 0.0, not -0.0
    assert part.facing == UP


def test_make_part_rejects_a_face_whose_vertices_are_not_coplanar():
    lifted = [*UNIT_SQUARE[:2], (1.0, 1.0, 0.01), UNIT_SQUARE[3]]  # 10 mm up: ~2.5 mm off plane
    with pytest.raises(GeometryError, match=r"face 0: a vertex lies .* m off the plane"):
        make_part(lifted, [Face((0, 1, 2, 3), "#ffffff")], facing=UP)


@pytest.mark.parametrize(("extra", "indices"), [
    ((0.5, 0.2, 0.0), (0, 1, 2, 4, 3)),  # a dent between the top corners
    ((0.5, 1.0, 0.0), (0, 1, 2, 4, 3)),  # a vertex on an edge: convex, but not strictly
])
def test_make_part_rejects_a_face_that_is_not_strictly_convex(extra, indices):
    with pytest.raises(GeometryError, match=r"face 0: not strictly convex at vertex"):
        make_part([*UNIT_SQUARE, extra], [Face(indices, "#ffffff")], facing=UP)


def test_make_part_rejects_a_solid_face_pointing_into_the_solid():
    walls = modelling.box(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, "#ffffff", top="#ffffff")
    roof = walls.faces[-1]
    flipped = [*walls.faces[:-1], Face(tuple(reversed(roof.indices)), roof.colour)]
    with pytest.raises(GeometryError, match=rf"face {len(flipped) - 1}: .* points into the solid"):
        make_part(walls.vertices, flipped)


def test_make_part_rejects_a_decal_facing_the_wrong_way():
    with pytest.raises(GeometryError, match=r"face 0: normal .* is not \(0\.0, 0\.0, 1\.0\)"):
        make_part(UNIT_SQUARE, [Face((3, 2, 1, 0), "#ffffff")], facing=UP)


@pytest.mark.parametrize(("vertices", "indices", "message"), [
    (UNIT_SQUARE, (0, 1, 1, 2), "are not >= 3 distinct vertices"),
    (UNIT_SQUARE, (0, 1), "are not >= 3 distinct vertices"),
    ([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0)], (0, 1, 2), "has no area"),
])
def test_make_part_rejects_degenerate_faces(vertices, indices, message):
    with pytest.raises(GeometryError, match=message):
        make_part(vertices, [Face(indices, "#ffffff")], facing=UP)


# --- the helpers wind faces outwards ------------------------------------------------------------

def test_box_faces_point_away_from_its_centroid():
    part = modelling.box(1.0, 4.0, -2.0, 3.0, 0.5, 2.5, "#888888", top="#444444", bottom="#222222")
    verts = np.array(part.vertices)
    centroid = np.array([2.5, 0.5, 1.5])
    normals = []
    for face in part.faces:
        pts = verts[list(face.indices)]
        n = _normal(pts)
        assert n @ (pts.mean(axis=0) - centroid) > 0.0, face
        normals.append(tuple(np.round(n, 12) + 0.0))
    axes = {tuple(float(s) * e) for s in (1, -1) for e in np.eye(3)}
    assert set(normals) == axes


def test_facing_face_finds_the_wall_to_paint_on():
    part = modelling.box(0.0, 2.0, 0.0, 1.0, 0.0, 1.0, "#888888", top="#444444")
    k = modelling.facing_face(part, (0.0, 1.0, 0.0))
    pts = np.array([part.vertices[i] for i in part.faces[k].indices])
    np.testing.assert_allclose(_normal(pts), [0.0, 1.0, 0.0], atol=1e-12)
    with pytest.raises(GeometryError, match="no face of the part faces"):
        modelling.facing_face(part, (0.0, 0.0, -1.0))  # the bottom was left out


@pytest.mark.parametrize(("n", "phase_deg"), [(3, 0.0), (5, 10.0), (8, 22.5)])
def test_ngon_is_counter_clockwise_from_above(n, phase_deg):
    pairs = modelling.ngon(10.0, -5.0, 3.0, n, phase_deg=phase_deg)
    assert len(pairs) == n and all(len(p) == 2 for p in pairs)
    assert _signed_area(pairs) > 0.0
    np.testing.assert_allclose(np.hypot(*(np.array(pairs) - [10.0, -5.0]).T), 3.0)
    triples = modelling.ngon(10.0, -5.0, 3.0, n, phase_deg=phase_deg, z=7.0)
    assert [p[:2] for p in triples] == pairs and {p[2] for p in triples} == {7.0}


def test_square_and_rect_are_counter_clockwise_from_above():
    sq = modelling.square(2.0, 5.0)
    assert _signed_area(sq) == pytest.approx(16.0)
    assert {p[2] for p in sq} == {5.0}
    assert _signed_area(modelling.rect(1.0, 3.0, 2.0, 7.0)) == pytest.approx(10.0)


# --- the document writers ---------------------------------------------------------------------

def test_model_doc_rebases_indices_and_writes_only_what_differs_from_the_defaults():
    base = modelling.ground_rect(0.0, 10.0, 0.0, 10.0, 0.0, "#333333")
    paint = modelling.ground_rects([(1.0, 2.0, 1.0, 2.0)], 0.0, "#ffffff", on=0)
    glass = modelling.prism(modelling.rect(0.0, 1.0, 0.0, 1.0), 0.0, 1.0, "#5f95ad", opacity=0.4)
    doc = modelling.model_doc([base, paint, glass])
    assert len(doc["vertices"]) == 4 + 4 + 8
    assert doc["faces"][0] == {"indices": [0, 1, 2, 3], "colour": "#333333"}
    assert doc["faces"][1] == {"indices": [4, 5, 6, 7], "colour": "#ffffff", "on": 0, "layer": 1}
    assert all(f["opacity"] == 0.4 and min(f["indices"]) >= 8 for f in doc["faces"][2:])


def test_instance_doc_leaves_out_a_zero_hpr():
    assert modelling.instance_doc(Instance("m", (1.0, 2.0, 3.0), "a")) == {
        "model": "m", "position": [1.0, 2.0, 3.0], "name": "a"}
    assert modelling.instance_doc(Instance("m", (0.0, 0.0, 0.0), "b", (90.0, 0.0, 0.0)))["hpr"] == [
        90.0, 0.0, 0.0]


def test_render_json_round_trips_and_puts_one_face_per_line():
    model = modelling.model_doc([modelling.box(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, "#888888",
                                               top="#444444")])
    doc = {"format": "ig-scene/1", "name": "tiny — ünïcode", "sky": {"colour": "#a4c8ea"},
           "fog": {"origin_m": [0.0, 0.0, -120.0], "visibility_m": [1200.0, None]},
           "models": {"box": model},
           "instances": [modelling.instance_doc(Instance("box", (0.1, -2.5, 0.0), "b1"))]}
    text = modelling.render_json(doc)
    assert text.endswith("}\n")
    assert json.loads(text) == doc
    lines = text.splitlines()
    for face in model["faces"]:
        assert sum(json.dumps(face) in line for line in lines) == 1
    assert modelling.render_json(json.loads(text)) == text


def test_statistics_counts_faces_and_instances():
    doc = {
        "models": {
            "a": {"vertices": [], "faces": [{"indices": [0, 1, 2]},
                                            {"indices": [0, 2, 3], "opacity": 0.5}]},
            "b": {"vertices": [], "faces": [{"indices": [0, 1, 2]}]},
            "unused": {"vertices": [], "faces": [{"indices": [0, 1, 2], "opacity": 0.2}]},
        },
        "instances": [{"model": "a"}, {"model": "a"}, {"model": "b"}],
    }
    assert modelling.statistics(doc) == {"models": 3, "model_faces": 4, "instances": 3,
                                         "instance_faces": 5, "translucent_faces": 2}
