"""Perspective projection against a hand-computed pinhole, and the exact depth plane."""

import math

import numpy as np

from channel_worker.pipeline.contract import SUBPIXEL, Polygons
from channel_worker.pipeline.geometry.backface import eliminate_backfaces
from channel_worker.pipeline.geometry.project import project
from channel_worker.pipeline.geometry.view import make_view, screen_mapping
from services.rig.frame import ChannelSpec, Eyepoint


def test_screen_mapping_matches_a_pinhole():
    # 90 x 90 degree frustum, 200 x 200: focal length 100 px, principal point at the centre.
    view = make_view(ChannelSpec.symmetric("c", 200, 200, 90.0, 90.0), Eyepoint.of(0, 0, 0, 0, 0, 0))
    sxs, sxo, sys_, syo = screen_mapping(view)
    f = 100.0
    for x, y, z in [(1, 2, 10), (-3, 0.5, 7), (0, 0, 1)]:
        assert math.isclose(x / z * sxs + sxo, 100 + f * x / z)
        assert math.isclose(y / z * sys_ + syo, 100 - f * y / z)


def test_off_axis_frustum():
    # left -10, right 50 degrees: the view axis does not project to the middle of the raster
    ch = ChannelSpec("c", 600, 100, -10.0, 50.0, -20.0, 20.0)
    view = make_view(ch, Eyepoint.of(0, 0, 0, 0, 0, 0))
    sxs, sxo, _, _ = screen_mapping(view)
    t_l, t_r = math.tan(math.radians(-10)), math.tan(math.radians(50))
    assert math.isclose(0 * sxs + sxo, 600 * (0 - t_l) / (t_r - t_l))
    assert math.isclose(t_r * sxs + sxo, 600)


def test_project_snaps_and_interpolates_depth_exactly():
    view = make_view(ChannelSpec.symmetric("c", 200, 200, 90.0, 90.0), Eyepoint.of(0, 0, 0, 0, 0, 0))
    # a slanted quad facing the eye (normal towards -z and +x a bit)
    v = np.array([[-1, -1, 10.0], [1, -1, 12.0], [1, 1, 12.0], [-1, 1, 10.0]])
    n = np.cross(v[1] - v[0], v[2] - v[0])
    n /= np.linalg.norm(n)
    if n @ v[0] > 0:
        n = -n
        v = v[::-1].copy()
    polys = Polygons(v, np.array([0, 4]), np.ones((1, 3), np.float32), np.ones(1, np.float32),
                     np.zeros(1, np.int32), np.array([[*n, n @ v[0]]]), np.zeros(1, np.int16))
    polys = eliminate_backfaces(polys)
    screen = project(polys, view)
    assert screen.polygon_count == 1
    a, b, c = screen.inv_z[0]
    for p in v:
        sx, sy = 100 + 100 * p[0] / p[2], 100 - 100 * p[1] / p[2]
        assert math.isclose(1.0 / (a * sx + b * sy + c), p[2], rel_tol=1e-12)
    # vertices are on the 1/SUBPIXEL grid, within half a step of the exact projection
    exact = np.array([[100 + 100 * p[0] / p[2], 100 - 100 * p[1] / p[2]] for p in v])
    got = screen.fixed / SUBPIXEL
    assert np.abs(np.sort(got, axis=0) - np.sort(exact, axis=0)).max() <= 0.5 / SUBPIXEL + 1e-12


def test_degenerate_polygon_after_snapping_is_dropped():
    view = make_view(ChannelSpec.symmetric("c", 200, 200, 90.0, 90.0), Eyepoint.of(0, 0, 0, 0, 0, 0))
    v = np.array([[0, 0, 1e6], [1e-3, 0, 1e6], [0, 1e-3, 1e6]])  # far smaller than 1/256 px
    polys = Polygons(v, np.array([0, 3]), np.ones((1, 3), np.float32), np.ones(1, np.float32),
                     np.zeros(1, np.int32), np.array([[0, 0, -1.0, -1e6]]), np.zeros(1, np.int16))
    assert project(polys, view).polygon_count == 0
