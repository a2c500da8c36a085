"""Sutherland-Hodgman clipping, near plane first."""

import numpy as np
from hypothesis import assume, given
from hypothesis import strategies as st

from channel_worker.pipeline.contract import Polygons
from channel_worker.pipeline.geometry.clip import clip, frustum_planes
from channel_worker.pipeline.geometry.view import make_view
from services.rig.frame import ChannelSpec, Eyepoint

coord = st.floats(-100, 100, allow_nan=False)
VIEW = make_view(ChannelSpec.symmetric("c", 100, 100, 90.0, 90.0), Eyepoint.of(0, 0, 0, 0, 0, 0))


def polys(*faces):
    verts = np.concatenate([np.asarray(f, float) for f in faces])
    start = np.concatenate([[0], np.cumsum([len(f) for f in faces])]).astype(np.int64)
    n = len(faces)
    return Polygons(verts, start, np.ones((n, 3), np.float32), np.ones(n, np.float32),
                    np.arange(n, dtype=np.int32), np.tile([0, 0, -1.0, -1.0], (n, 1)), np.zeros(n, np.int16))


def inside(v, view=VIEW, eps=1e-9):
    x, y, z = v.T
    return ((z >= view.near - eps) & (x >= view.tan_left * z - eps) & (x <= view.tan_right * z + eps)
            & (y >= view.tan_bottom * z - eps) & (y <= view.tan_top * z + eps) & (z <= view.far + eps)).all()


def test_polygon_inside_is_untouched():
    tri = [[0, 0, 5], [1, 0, 5], [0, 1, 5]]
    out = clip(polys(tri), VIEW)
    np.testing.assert_array_equal(out.verts, tri)


def test_polygon_behind_the_eye_is_dropped():
    out = clip(polys([[0, 0, -5], [1, 0, -5], [0, 1, -1]]), VIEW)
    assert out.polygon_count == 0


def test_polygon_through_the_eye_plane_is_cut_at_near():
    # a floor quad under the eye running from behind to in front of it
    quad = [[-1, -1, -10], [1, -1, -10], [1, -1, 10], [-1, -1, 10]]
    out = clip(polys(quad), VIEW)
    assert out.polygon_count == 1
    assert out.verts[:, 2].min() >= VIEW.near - 1e-12
    assert inside(out.verts)
    # the near-plane cut lies on the quad's plane y = -1
    np.testing.assert_allclose(out.verts[:, 1], -1.0)


def test_polygon_through_the_eye_point_is_clipped_without_nan():
    tri = [[0, 0, 0], [5, 0, 10], [-5, 0, 10]]  # one vertex exactly at the eye
    out = clip(polys(tri), VIEW)
    assert np.isfinite(out.verts).all()
    assert inside(out.verts)


@given(st.tuples(coord, coord, st.floats(-5, 60)), st.tuples(coord, coord, st.floats(-5, 60)))
def test_shared_edge_clips_to_bit_identical_points_both_ways(p, q):
    """Two polygons sharing edge pq, traversed in opposite directions, must cut it at exactly
    the same points, or the snapped screen edges could differ and leave a crack."""
    p, q = np.array(p), np.array(q)
    apex = (p + q) / 2 + [0.0, 0.0, 30.0]
    assume(np.linalg.norm(np.cross(q - p, apex - p)) > 1e-3)  # a real triangle on each side
    # endpoints clearly off every plane, so a cut near an endpoint on another edge is not
    # mistaken for a cut of pq
    assume(np.abs(frustum_planes(VIEW) @ np.append(p, 1.0)).min() > 1e-6)
    assume(np.abs(frustum_planes(VIEW) @ np.append(q, 1.0)).min() > 1e-6)
    out = clip(polys([p, q, apex], [q, p, apex - [0.0, 0.0, 60.0]]), VIEW)
    if out.polygon_count < 2:
        return
    pa = {tuple(v) for v in out.verts[out.start[0]:out.start[1]]}
    pb = {tuple(v) for v in out.verts[out.start[1]:out.start[2]]}
    d = q - p
    def on_pq(v):
        w = np.asarray(v) - p
        return np.linalg.norm(np.cross(w, d)) <= 1e-9 * (1 + np.linalg.norm(d) * np.linalg.norm(w))
    on_a = {v for v in pa if on_pq(v)}
    on_b = {v for v in pb if on_pq(v)}
    assert on_a == on_b



@given(st.lists(st.tuples(coord, coord, coord), min_size=3, max_size=3))
def test_clipped_vertices_are_inside_and_finite(tri):
    out = clip(polys(tri), VIEW)
    assert np.isfinite(out.verts).all()
    if out.polygon_count:
        assert inside(out.verts, eps=1e-6)
        assert (np.diff(out.start) >= 3).all()
