"""Watertight multi-sample rasterization: shared edges leave no crack and no double hit."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.backface import eliminate_backfaces
from channel_worker.pipeline.clip import clip
from channel_worker.pipeline.cull import cull
from channel_worker.pipeline.geometry import make_view, to_eye
from channel_worker.pipeline.project import project
from channel_worker.pipeline.raster import rasterize
from channel_worker.pipeline.samples import sample_pattern
from channel_worker.pipeline.scene import parse_scene
from channel_worker.pipeline.types import SKY_ID, SUBPIXEL, ChannelSpec, Eyepoint, SampleBuffer, ScreenPolygons


def screen_polys(polys_px, inv_z=None):
    """ScreenPolygons from pixel coordinates already on the 1/SUBPIXEL grid, wound for raster."""
    fixed, start = [], [0]
    for poly in polys_px:
        f = np.round(np.asarray(poly, float) * SUBPIXEL).astype(np.int64)
        area2 = np.sum(f[:, 0] * np.roll(f[:, 1], -1) - np.roll(f[:, 0], -1) * f[:, 1])
        fixed.append(f[::-1] if area2 > 0 else f)
        start.append(start[-1] + len(f))
    n = len(polys_px)
    abc = np.tile([0.0, 0.0, 1.0], (n, 1)) if inv_z is None else np.asarray(inv_z, float)
    return ScreenPolygons(np.concatenate(fixed), np.array(start, np.int64), abc,
                          np.ones((n, 3), np.float32), np.ones(n, np.float32), np.arange(n, dtype=np.int32))


def empty_buffer(w, h, offsets):
    s = offsets.shape[0]
    return SampleBuffer(np.zeros((h, w, s, 3), np.float32), np.zeros((h, w, s), np.float32),
                        np.full((h, w, s), SKY_ID, np.int32), offsets)


def hit_counts(polys: ScreenPolygons, w, h, offsets):
    """How many polygons cover each sample, drawing each polygon into its own buffer."""
    counts = np.zeros((h, w, offsets.shape[0]), np.int32)
    for i in range(polys.count):
        a, b = polys.start[i], polys.start[i + 1]
        one = ScreenPolygons(polys.fixed[a:b], np.array([0, b - a]), polys.inv_z[i:i + 1],
                             polys.colour[i:i + 1], polys.opacity[i:i + 1], polys.feature_id[i:i + 1])
        buf = rasterize(one, empty_buffer(w, h, offsets))
        counts += buf.feature != SKY_ID
    return counts


def test_two_triangles_sharing_an_edge_hit_every_sample_once():
    # the shared diagonal passes exactly through sample points of the 1-sample and 16-sample patterns
    tris = [[(0, 0), (16, 0), (16, 12)], [(0, 0), (16, 12), (0, 12)]]
    for name in ("centre", "rgss4", "d3d16"):
        offsets = sample_pattern(name)
        counts = hit_counts(screen_polys(tris), 16, 12, offsets)
        assert (counts == 1).all(), name


def test_vertical_and_horizontal_shared_edges_through_sample_points():
    # edges along x = 5.5 and y = 3.5 run exactly through pixel centres
    quads = [[(0, 0), (5.5, 0), (5.5, 3.5), (0, 3.5)], [(5.5, 0), (10, 0), (10, 3.5), (5.5, 3.5)],
             [(0, 3.5), (5.5, 3.5), (5.5, 8), (0, 8)], [(5.5, 3.5), (10, 3.5), (10, 8), (5.5, 8)]]
    counts = hit_counts(screen_polys(quads), 10, 8, sample_pattern("centre"))
    assert (counts == 1).all()


def test_depth_test_keeps_the_nearest():
    near_far = screen_polys([[(0, 0), (8, 0), (8, 8), (0, 8)]] * 2, inv_z=[[0, 0, 0.1], [0, 0, 0.5]])
    buf = rasterize(near_far, empty_buffer(8, 8, sample_pattern(4)))
    assert (buf.feature == 1).all()
    np.testing.assert_allclose(buf.inv_z, 0.5)


@st.composite
def jittered_grid(draw):
    """A mesh of triangles covering the whole raster exactly: border vertices on the border,
    inner vertices jittered on the sub-pixel grid (including onto sample points)."""
    w, h = draw(st.integers(4, 24)), draw(st.integers(4, 24))
    nx, ny = draw(st.integers(1, 5)), draw(st.integers(1, 5))
    xs = np.linspace(0, w, nx + 1)
    ys = np.linspace(0, h, ny + 1)
    jit = st.integers(-SUBPIXEL // 3, SUBPIXEL // 3)
    grid = np.zeros((ny + 1, nx + 1, 2))
    for j in range(ny + 1):
        for i in range(nx + 1):
            x, y = xs[i], ys[j]
            if 0 < i < nx:
                x = round(x * SUBPIXEL + draw(jit) * (w / nx) / 2) / SUBPIXEL
            if 0 < j < ny:
                y = round(y * SUBPIXEL + draw(jit) * (h / ny) / 2) / SUBPIXEL
            grid[j, i] = (x, y)
    tris = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = grid[j, i], grid[j, i + 1], grid[j + 1, i + 1], grid[j + 1, i]
            if draw(st.booleans()):
                tris += [[a, b, c], [a, c, d]]
            else:
                tris += [[a, b, d], [b, c, d]]
    pattern = draw(st.sampled_from(["centre", "rgss4", "d3d8", "d3d16"]))
    return w, h, tris, pattern


@settings(max_examples=60, deadline=None)
@given(jittered_grid())
def test_random_meshes_are_watertight(case):
    w, h, tris, pattern = case
    offsets = sample_pattern(pattern)
    polys = screen_polys(tris)
    counts = hit_counts(polys, w, h, offsets)
    assert (counts == 1).all(), f"{(counts == 0).sum()} cracks, {(counts > 1).sum()} double hits"


def room_scene(n: int, size: float, centre):
    """A closed cube of side `size` around `centre`, each wall split into n x n triangulated
    quads facing inwards, so every ray from inside meets exactly one front face."""
    verts, faces = [], []
    def idx(p):
        verts.append([float(c) for c in p])
        return len(verts) - 1
    h = size / 2
    u = np.linspace(-h, h, n + 1)
    # (fixed axis, sign); the two other axes span the wall. Winding chosen so normals point in.
    for axis in range(3):
        for sign in (-1.0, 1.0):
            a1, a2 = [k for k in range(3) if k != axis]
            grid = {}
            for i in range(n + 1):
                for j in range(n + 1):
                    p = [0.0, 0.0, 0.0]
                    p[axis], p[a1], p[a2] = sign * h, u[i], u[j]
                    grid[i, j] = idx(p)
            for i in range(n):
                for j in range(n):
                    q = [grid[i, j], grid[i + 1, j], grid[i + 1, j + 1], grid[i, j + 1]]
                    # (a1, a2, axis) is right-handed for axis 0 and 2, left-handed for axis 1
                    inward = -sign if axis != 1 else sign
                    if inward < 0:
                        q = q[::-1]
                    faces.append({"indices": [q[0], q[1], q[2]], "colour": "#808080"})
                    faces.append({"indices": [q[0], q[2], q[3]], "colour": "#808080"})
    doc = {"format": "ig-scene/1", "sky": {"colour": "#0000ff"}, "earth": {"colour": "#00ff00"},
           "models": {"room": {"vertices": verts, "faces": faces}},
           "instances": [{"model": "room", "position": list(centre)}]}
    return parse_scene(doc)


@settings(max_examples=25, deadline=None)
@given(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4), st.floats(-0.4, 0.4),
       st.floats(0, 360), st.floats(-90, 90), st.floats(-180, 180),
       st.sampled_from([0.0, 1.0e6]))
def test_pipeline_is_watertight_inside_a_closed_room(dx, dy, dz, h, p, r, far_offset):
    """Every sample inside a closed triangulated room sees exactly one wall, at any attitude,
    1000 km from the origin too; walls cross the near and side planes."""
    centre = np.array([far_offset, -far_offset, 500.0])
    db = room_scene(3, 6.0, centre)
    eye = Eyepoint(centre + np.array([dx, dy, dz]) * 6.0, h, p, r)
    view = make_view(ChannelSpec.symmetric("c", 40, 30, 100.0), eye)
    polys = clip(eliminate_backfaces(to_eye(db, cull(db, view), view)), view)
    screen = project(polys, view)
    counts = hit_counts(screen, 40, 30, sample_pattern("rgss4"))
    assert (counts == 1).all(), f"{(counts == 0).sum()} cracks, {(counts > 1).sum()} double hits"


def test_pixel_centres_sit_at_half_integers_from_the_top_left():
    offsets = sample_pattern("centre")
    np.testing.assert_array_equal(offsets, [[0.5, 0.5]])
    covers = hit_counts(screen_polys([[(0, 0), (0.5625, 0), (0.5625, 0.5625), (0, 0.5625)]]), 3, 2, offsets)
    assert covers[0, 0, 0] == 1 and covers.sum() == 1  # pixel (0, 0) is the top-left one
    misses = hit_counts(screen_polys([[(0, 0), (0.4375, 0), (0.4375, 0.4375), (0, 0.4375)]]), 3, 2, offsets)
    assert misses.sum() == 0
    # a quad over x in [1.4375, 3), y in [1.4375, 2) covers the pixels whose centres (x + .5, y + .5) it holds
    quad = hit_counts(screen_polys([[(1.4375, 1.4375), (3, 1.4375), (3, 2), (1.4375, 2)]]), 3, 2, offsets)
    assert quad[..., 0].tolist() == [[0, 0, 0], [0, 1, 1]]
