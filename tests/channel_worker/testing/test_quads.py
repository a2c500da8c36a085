"""The overdraw scenes' quads (channel_worker/testing/quads.py, overdraw_model): their depth
complexity, translucent share, winding and depths, checked from the model's vertices alone.

Screen positions are computed here by the pinhole formula (x / z and y / z times the focal
length in pixels, an eye at the origin looking along +z), not with the pipeline.
"""

import math

import numpy as np
import pytest

from channel_worker.testing.quads import (
    OVERDRAW_FOV_DEG,
    OVERDRAW_SIZE,
    overdraw_model,
    overdraw_scene_doc,
)

COUNT = 500
WIDTH, HEIGHT = OVERDRAW_SIZE
FOCAL = WIDTH / (2.0 * math.tan(math.radians(OVERDRAW_FOV_DEG / 2.0)))


def quads(model: dict) -> np.ndarray:
    """(N, 4, 3) corners of the model's faces, in face order."""
    verts = np.asarray(model["vertices"], np.float64)
    return np.stack([verts[face["indices"]] for face in model["faces"]])


def screen_areas(q: np.ndarray) -> np.ndarray:
    """(N,) projected area of each quad, square pixels (shoelace on x/z, y/z times focal)."""
    p = q[..., :2] / q[..., 2:3] * FOCAL
    nxt = np.roll(p, -1, axis=1)
    return 0.5 * np.abs(np.sum(p[..., 0] * nxt[..., 1] - nxt[..., 0] * p[..., 1], axis=1))


@pytest.mark.parametrize("depth_complexity", [4.0, 8.0])
def test_projected_area_is_depth_complexity_times_the_frame(depth_complexity):
    q = quads(overdraw_model(depth_complexity, count=COUNT))
    areas = screen_areas(q)
    assert areas.sum() / (WIDTH * HEIGHT) == pytest.approx(depth_complexity, rel=0.02)
    # Small and large together: sizes log-uniform over a factor of 30 (areas over 900).
    assert areas.max() / areas.min() > 100.0


def test_quads_are_in_view():
    q = quads(overdraw_model(4.0, count=COUNT))
    sx, sy = q[..., 0] / q[..., 2] * FOCAL, q[..., 1] / q[..., 2] * FOCAL
    # Centred in the view, so a quad's box overlaps the frame (a large one's four corners may
    # all lie on one side of its centre: a few may miss it).
    overlaps = ((sx.min(axis=1) < WIDTH / 2) & (sx.max(axis=1) > -WIDTH / 2)
                & (sy.min(axis=1) < HEIGHT / 2) & (sy.max(axis=1) > -HEIGHT / 2))
    assert overlaps.mean() >= 0.99
    # Spread over the whole view: some quad reaches each edge's neighbourhood.
    assert sx.min() < -0.9 * WIDTH / 2 and sx.max() > 0.9 * WIDTH / 2
    assert sy.min() < -0.9 * HEIGHT / 2 and sy.max() > 0.9 * HEIGHT / 2


@pytest.mark.parametrize("translucent", [0.0, 0.25, 0.5])
def test_translucent_fraction(translucent):
    faces = overdraw_model(4.0, count=COUNT, translucent=translucent)["faces"]
    opacities = np.array([f["opacity"] for f in faces if "opacity" in f])
    # Binomial: 3 standard deviations of the fraction at 500 quads is at most 0.067.
    assert opacities.size / COUNT == pytest.approx(translucent, abs=0.067)
    if opacities.size:
        assert opacities.min() >= 0.3
        assert opacities.max() <= 0.8


def test_faces_are_convex_counter_clockwise_from_the_eye_at_distinct_depths():
    q = quads(overdraw_model(8.0, count=COUNT, translucent=0.25))
    # The normal (right-handed, from the winding) points back at the eye at the origin.
    normal = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    assert (np.einsum("ij,ij->i", normal, q[:, 0]) < 0).all()
    # Convex: every corner turns the same way as the first.
    edge = np.roll(q, -1, axis=1) - q
    turns = np.cross(edge, np.roll(edge, -1, axis=1))
    assert (np.einsum("ikj,ij->ik", turns, normal) > 0).all()
    # Each quad faces the eye (one depth for its four corners); no two share a depth.
    depth = q[:, :, 2]
    assert (depth == depth[:, :1]).all()
    assert np.unique(depth[:, 0]).size == COUNT


def test_deterministic_for_a_seed():
    assert overdraw_model(4.0, count=COUNT, translucent=0.25) == overdraw_model(
        4.0, count=COUNT, translucent=0.25)
    assert overdraw_model(4.0, count=COUNT, seed=1) != overdraw_model(4.0, count=COUNT, seed=2)


def test_scene_doc_holds_the_model():
    doc = overdraw_scene_doc(4.0, translucent=0.25, count=COUNT)
    assert doc["models"]["quads"] == overdraw_model(4.0, count=COUNT, translucent=0.25)
    assert doc["instances"] == [{"model": "quads", "position": [0.0, 0.0, 1.5]}]
