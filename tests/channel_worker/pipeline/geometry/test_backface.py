"""Backface elimination."""

import numpy as np

from channel_worker.pipeline.contract import Polygons
from channel_worker.pipeline.geometry.backface import eliminate_backfaces


def face(verts, normal):
    v = np.asarray(verts, float)
    n = np.asarray(normal, float)
    return v, np.array([*n, n @ v[0]])


def build(*faces):
    verts = np.concatenate([f[0] for f in faces])
    start = np.concatenate([[0], np.cumsum([len(f[0]) for f in faces])]).astype(np.int64)
    k = len(faces)
    return Polygons(verts, start, np.ones((k, 3), np.float32), np.ones(k, np.float32),
                    np.arange(k, dtype=np.int32), np.array([f[1] for f in faces]), np.zeros(k, np.int16))


def test_front_kept_back_and_edge_on_dropped():
    tri = [[0, 0, 5], [1, 0, 5], [0, 1, 5]]
    front = face(tri, [0, 0, -1])  # normal towards the eye at the origin
    back = face(tri, [0, 0, 1])
    edge_on = face([[0, 0, 5], [0, 1, 5], [0, 0, 6]], [1, 0, 0])  # plane x = 0 contains the eye
    out = eliminate_backfaces(build(front, back, edge_on))
    assert out.feature_id.tolist() == [0]
    np.testing.assert_array_equal(out.verts, tri)


def test_far_away_face_keeps_its_vertices():
    a = face([[1e6, 0, 1e6], [1e6 + 1, 0, 1e6], [1e6, 1, 1e6]], [0, 0, -1])
    b = face([[0, 0, 2], [1, 0, 2], [0, 1, 2], [-1, 0.5, 2]], [0, 0, -1])
    out = eliminate_backfaces(build(a, b))
    assert out.polygon_count == 2
    assert out.start.tolist() == [0, 3, 7]
