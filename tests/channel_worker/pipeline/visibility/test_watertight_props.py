"""Watertightness properties: meshes sharing edges cover every sample exactly once.

Screen-space meshes are built directly in the rasterizer's fixed-point units (1/256 pixel)
and checked with visibility.coverage_counts (the renderer's sub-area classification and
per-sample edge tests) and with the renderer's sample store itself (sample_store: the
mesh made translucent, so each sample's store count is its coverage, and opaque, where the
row-span solver of the opaque-only path decides). The expected coverage is computed independently,
exactly, in integers: a sample strictly inside the mesh's outer boundary (winding number of the
edges no two triangles share) must be covered once, one strictly outside never, one exactly
on the outer boundary at most once.

Hard cases are drawn on purpose: vertices on sub-area corners (multiples of subarea * 256) and
on sample points, edges through sample points (sample positions are on the 1/16-pixel grid),
sliver triangles thinner than the sample spacing, several sub-area sizes. End-to-end, a closed
room seen from inside (faces crossing the near plane, 1000 km from the origin, an edge-on
partition through the eye) must show every sample exactly one wall.
"""

from __future__ import annotations

import itertools
from collections import Counter

import numpy as np
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.contract import SUBPIXEL, ScreenPolygons
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.visibility.visibility import coverage_counts
from services.rig.frame import ChannelSpec, Eyepoint, hpr_matrix
from services.rig.options import RenderOptions

from ..conftest import store

W, H = 50, 38  # not a multiple of any sub-area size: partial sub-areas on the right and bottom
SUBAREAS = [1, 4, 8, 16, 32]
#: d3d16 plus the pixel corner (a sub-area corner for pixels on sub-area boundaries), the pixel
#: centre and edge midpoints, so every point of the half-pixel grid is a sample point; every
#: position is on the 1/16-pixel grid.
HARD_OFFSETS = np.unique(np.concatenate([
    RenderOptions(samples="d3d16").sample_offsets(),
    np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [0.5, 0.5], [15 / 16, 15 / 16]]),
]), axis=0)
#: Every position of the 1/16-pixel grid.
ALL_OFFSETS = np.stack(np.meshgrid(np.arange(16), np.arange(16)), axis=-1).reshape(-1, 2) / 16.0
GRID = 16  # sample grid step in fixed units

PROPS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ---------------------------------------------------------------------------------------------
# Meshes and the exact expected coverage


def mesh_polygons(tris: np.ndarray) -> tuple[ScreenPolygons, np.ndarray]:
    """ScreenPolygons of a triangle mesh and its outer boundary edges.

    tris: (T, 3, 2) int64 fixed-point vertices, all wound the same way (zero-area triangles
    allowed). Returns the polygons (degenerate ones skipped, every one wound with negative
    doubled area as project.py leaves them) and (B, 4) directed boundary edges x0, y0, x1, y1:
    the edges whose reverse no other triangle has. Calls hypothesis.assume(False) on a mesh
    that folds over itself (triangles wound both ways).
    """
    tris = np.asarray(tris, np.int64)
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    signs = set(np.sign(area2[area2 != 0]).tolist())
    assume(len(signs) == 1)
    if signs == {1}:
        tris = tris[:, ::-1]
    edges = Counter()
    for t in tris:
        for i in range(3):
            edges[(*t[i], *t[(i + 1) % 3])] += 1
    assume(all(v == 1 for v in edges.values()))  # no edge used twice the same way: no overlap
    boundary = [e for e in edges if (e[2], e[3], e[0], e[1]) not in edges]
    keep = tris[area2 != 0]
    n = keep.shape[0]
    screen = ScreenPolygons(
        fixed=keep.reshape(-1, 2).copy(), start=np.arange(n + 1, dtype=np.int64) * 3,
        inv_z=np.tile([0.0, 0.0, 1.0], (n, 1)), colour=np.zeros((n, 3), np.float32),
        opacity=np.ones(n, np.float32), feature_id=np.arange(n, dtype=np.int32), layer=np.zeros(n, np.int16))
    return screen, np.array(boundary, np.int64).reshape(-1, 4)


def expected_coverage(boundary: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inside, on_boundary) (H, W, S) bool, exact in integers, at every sample of the raster.

    Inside: non-zero winding number of the boundary edges (Sunday's crossing rule), off them.
    """
    off = np.round(offsets * SUBPIXEL).astype(np.int64)
    ys, xs = np.mgrid[0:H, 0:W]
    px = (xs[..., None] * SUBPIXEL + off[:, 0]).ravel()
    py = (ys[..., None] * SUBPIXEL + off[:, 1]).ravel()
    winding = np.zeros(px.shape, np.int64)
    on = np.zeros(px.shape, bool)
    for x0, y0, x1, y1 in boundary:
        side = (x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)
        winding += ((y0 <= py) & (py < y1) & (side > 0)).astype(np.int64)
        winding -= ((y1 <= py) & (py < y0) & (side < 0)).astype(np.int64)
        on |= (side == 0) & (np.minimum(x0, x1) <= px) & (px <= np.maximum(x0, x1)) \
            & (np.minimum(y0, y1) <= py) & (py <= np.maximum(y0, y1))
    shape = (H, W, off.shape[0])
    return (winding != 0).reshape(shape) & ~on.reshape(shape), on.reshape(shape)


def check_watertight(tris: np.ndarray, subarea: int, offsets: np.ndarray = HARD_OFFSETS) -> None:
    screen, boundary = mesh_polygons(tris)
    counts = coverage_counts(screen, W, H, offsets, subarea=subarea)
    inside, on = expected_coverage(boundary, offsets)
    outside = ~inside & ~on

    def where(mask):
        y, x, s = np.argwhere(mask)[0]
        return (f"pixel ({x}, {y}) sample {offsets[s]} = fixed "
                f"({x * SUBPIXEL + round(offsets[s, 0] * SUBPIXEL)}, "
                f"{y * SUBPIXEL + round(offsets[s, 1] * SUBPIXEL)}), count {counts[y, x, s]}")

    assert (counts[inside] == 1).all(), \
        f"inside sample not covered once: {where(inside & (counts != 1))}"
    assert (counts[outside] == 0).all(), f"outside sample covered: {where(outside & (counts != 0))}"
    assert (counts[on] <= 1).all(), f"boundary sample covered twice: {where(on & (counts > 1))}"
    stored, seen = renderer_coverage(screen, W, H, offsets, subarea)
    assert (stored == counts).all(), f"renderer store differs: {where(stored != counts)}"
    assert (seen == (counts > 0)).all(), f"opaque path differs: {where(seen != (counts > 0))}"


def renderer_coverage(screen: ScreenPolygons, w: int, h: int, offsets: np.ndarray,
                      subarea: int) -> tuple[np.ndarray, np.ndarray]:
    """What the renderer's sample store makes of a mesh at one depth: (H, W, S) translucent
    count with every polygon at opacity 0.5 (the coverage, up to the store size 2), and
    whether the opaque-only path gives the sample a polygon."""
    up = Eyepoint.of(0.0, 0.0, 10.0, 0.0, 90.0, 0.0)  # only sky behind the mesh
    view = make_view(ChannelSpec.symmetric("t", w, h, 60.0), up)
    glass = screen._replace(opacity=np.full(screen.polygon_count, 0.5, np.float32))
    stored = store(glass, view, offsets, max_translucent=2, subarea=subarea, with_range=False)
    solid = store(screen, view, offsets, max_translucent=2, subarea=subarea, with_range=False)
    return stored.translucent_count.astype(np.int32), solid.opaque >= 0


def grid_triangles(xs: np.ndarray, ys: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """Two triangles per cell of a vertex grid xs, ys (ny+1, nx+1); flip picks the diagonal."""
    tris = []
    for j in range(xs.shape[0] - 1):
        for i in range(xs.shape[1] - 1):
            p00, p10 = (xs[j, i], ys[j, i]), (xs[j, i + 1], ys[j, i + 1])
            p01, p11 = (xs[j + 1, i], ys[j + 1, i]), (xs[j + 1, i + 1], ys[j + 1, i + 1])
            if flip[j, i]:
                tris += [(p00, p10, p11), (p00, p11, p01)]
            else:
                tris += [(p00, p10, p01), (p10, p11, p01)]
    return np.array(tris, np.int64)


def fan_triangles(centre, points: np.ndarray) -> np.ndarray:
    """Triangles from centre to consecutive points (sorted by angle); a gap of half a turn
    or more is left open, so the centre is then on the boundary."""
    d = points - np.asarray(centre)
    order = np.argsort(np.arctan2(d[:, 1], d[:, 0]), kind="stable")
    pts = points[order]
    ang = np.arctan2(d[order, 1], d[order, 0])
    gaps = np.diff(np.concatenate([ang, ang[:1] + 2 * np.pi]))
    tris = [(centre, tuple(pts[i]), tuple(pts[(i + 1) % len(pts)]))
            for i in range(len(pts)) if gaps[i] < np.pi]
    return np.array(tris, np.int64).reshape(-1, 3, 2)


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Strictly convex hull in exact integers (Andrew's monotone chain), counter-clockwise."""
    pts = sorted(set(map(tuple, points.tolist())))
    if len(pts) < 3:
        return np.array(pts, np.int64)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], np.int64)


# ---------------------------------------------------------------------------------------------
# Strategies


@st.composite
def anchors(draw, subarea: int) -> tuple[int, int]:
    """A point on a sub-area corner, a sample point, the 1/16 grid or anywhere (fixed units)."""
    kind = draw(st.sampled_from(["subarea", "sample", "grid", "free"]))
    if kind == "subarea":
        step = subarea * SUBPIXEL
        return (step * draw(st.integers(0, W // subarea + 1)),
                step * draw(st.integers(0, H // subarea + 1)))
    if kind == "sample":
        off = HARD_OFFSETS[draw(st.integers(0, len(HARD_OFFSETS) - 1))]
        return (draw(st.integers(0, W - 1)) * SUBPIXEL + round(off[0] * SUBPIXEL),
                draw(st.integers(0, H - 1)) * SUBPIXEL + round(off[1] * SUBPIXEL))
    q = GRID if kind == "grid" else 1
    return (q * draw(st.integers(0, W * SUBPIXEL // q)),
            q * draw(st.integers(0, H * SUBPIXEL // q)))


@st.composite
def grid_meshes(draw, subarea: int) -> np.ndarray:
    """A jittered triangulated grid; its outer boundary is a rectangle."""
    nx, ny = draw(st.integers(1, 6)), draw(st.integers(1, 5))
    if draw(st.booleans()):  # vertices on sub-area corners
        spacing = max(subarea * SUBPIXEL // draw(st.sampled_from([1, 2, 4])), GRID)
    else:
        spacing = draw(st.integers(64, 12 * SUBPIXEL))
    ox, oy = draw(anchors(subarea))
    ox -= draw(st.integers(0, nx // 2)) * spacing  # may start left of / above the raster
    oy -= draw(st.integers(0, ny // 2)) * spacing
    quantum = draw(st.sampled_from([1, GRID, 128]))  # jitter onto the sample grid, or not
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    amp = spacing // 5 // quantum * quantum
    jx = rng.integers(-amp // quantum, amp // quantum + 1, (ny + 1, nx + 1)) * quantum
    jy = rng.integers(-amp // quantum, amp // quantum + 1, (ny + 1, nx + 1)) * quantum
    jx[:, [0, -1]] = 0  # boundary vertices slide along the boundary only
    jy[[0, -1], :] = 0
    gy, gx = np.mgrid[0:ny + 1, 0:nx + 1]
    xs, ys = ox + gx * spacing + jx, oy + gy * spacing + jy
    return grid_triangles(xs, ys, rng.random((ny, nx)) < 0.5)


@st.composite
def fan_meshes(draw, subarea: int) -> np.ndarray:
    """Triangles around one vertex; clustered angles make slivers."""
    centre = draw(anchors(subarea))
    k = draw(st.integers(3, 20))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    ang = rng.uniform(0, 2 * np.pi, k)
    if draw(st.booleans()):  # slivers: some spokes a few thousandths of a radian apart
        ang[: k // 2] = ang[0] + rng.uniform(0, 0.004, k // 2)
    radius = rng.uniform(32, 20 * SUBPIXEL, k)
    pts = np.round(np.asarray(centre) + radius[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1))
    quantum = draw(st.sampled_from([1, GRID, 128]))  # 128: every grid point is a sample point
    pts = np.round(pts / quantum) * quantum
    pts = np.unique(pts.astype(np.int64), axis=0)
    pts = pts[(pts != np.asarray(centre)).any(axis=1)]
    assume(len(pts) >= 2)
    tris = fan_triangles(centre, pts)
    assume(len(tris) > 0)
    return tris


@st.composite
def split_convex_polygons(draw, subarea: int) -> np.ndarray:
    """A random convex polygon cut into triangles from a vertex, from an inner point, or as a
    zigzag strip (long thin triangles)."""
    cx, cy = draw(anchors(subarea))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    sx, sy = rng.integers(16, 30 * SUBPIXEL, 2)
    pts = np.stack([cx + rng.integers(-sx, sx + 1, 12), cy + rng.integers(-sy, sy + 1, 12)], 1)
    quantum = draw(st.sampled_from([1, GRID, 128]))
    pts = pts // quantum * quantum
    hull = convex_hull(pts[: draw(st.integers(4, 12))])
    assume(len(hull) >= 3)
    m = len(hull)
    how = draw(st.sampled_from(["vertex", "inner", "zigzag"]))
    if how == "vertex":
        tris = [(hull[0], hull[i], hull[i + 1]) for i in range(1, m - 1)]
    elif how == "inner":
        inner = np.round(hull.mean(axis=0)).astype(np.int64)
        tris = [(inner, hull[i], hull[(i + 1) % m]) for i in range(m)]
    else:
        lo, hi, tris = 0, m - 1, []
        while hi - lo >= 2:
            tris.append((hull[lo], hull[lo + 1], hull[hi]))
            lo += 1
            if hi - lo >= 2:
                tris.append((hull[lo], hull[hi - 1], hull[hi]))
                hi -= 1
    return np.array(tris, np.int64)


@st.composite
def sliver_stacks(draw, subarea: int) -> np.ndarray:
    """Layers of sliver triangles between parallel lines a fraction of a pixel apart, zipped
    together: every line but the outer two is shared, and with a step of 16 every line passes
    through sample points."""
    dx, dy = draw(st.integers(-9, 9)), draw(st.integers(-9, 9))
    assume((dx, dy) != (0, 0))
    gap = draw(st.sampled_from([1, 2, GRID]))
    ox, oy = draw(anchors(subarea))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    length = int(rng.integers(GRID, 40 * SUBPIXEL // max(abs(dx), abs(dy))))
    chains = []
    for level in range(draw(st.integers(2, 5))):
        t = np.unique(np.concatenate([[0, length], rng.integers(0, length, rng.integers(0, 6))]))
        base = np.array([ox - level * gap * dy, oy + level * gap * dx])
        chains.append(base + t[:, None] * np.array([dx, dy]))
    tris = []
    for a, b in itertools.pairwise(chains):
        # Zip two chains by position along the direction (the shared t runs from 0 to length).
        ta = (a - a[0]) @ np.array([dx, dy])
        tb = (b - b[0]) @ np.array([dx, dy])
        i = j = 0
        while i < len(a) - 1 or j < len(b) - 1:
            if j == len(b) - 1 or (i < len(a) - 1 and ta[i + 1] <= tb[j + 1]):
                tris.append((a[i], a[i + 1], b[j]))
                i += 1
            else:
                tris.append((a[i], b[j + 1], b[j]))
                j += 1
    return np.array(tris, np.int64)


def _sq(x0, y0, x1, y1, diagonal="main"):
    """A rectangle as two triangles (fixed units)."""
    if diagonal == "main":
        return [((x0, y0), (x1, y0), (x1, y1)), ((x0, y0), (x1, y1), (x0, y1))]
    return [((x0, y0), (x1, y0), (x0, y1)), ((x1, y0), (x1, y1), (x0, y1))]


S16 = 16 * SUBPIXEL
SAMPLE = (5 * SUBPIXEL + 128, 7 * SUBPIXEL + 128)  # the centre sample of pixel (5, 7)
ROW = 3 * SUBPIXEL + 128  # the row of pixel centres of raster row 3
#: Hand-made hard cases: diagonals through sub-area corners and sample points, a fan around a
#: sub-area corner and one around a sample point, a needle of width 1/256 px along a sample row.
EXAMPLES = [
    np.array(_sq(0, 0, 2 * S16, 2 * S16), np.int64),
    np.array(_sq(S16, 0, 3 * S16, 2 * S16, "anti") + _sq(S16, 2 * S16, 3 * S16, 3 * S16), np.int64),
    fan_triangles((S16, S16), np.array([[S16 + dx * 8 * SUBPIXEL, S16 + dy * 8 * SUBPIXEL]
                                        for dx, dy in [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0),
                                                       (-1, -1), (0, -1), (1, -1)]])),
    fan_triangles(SAMPLE, np.array([[SAMPLE[0] + dx, SAMPLE[1] + dy]
                                    for dx, dy in [(256, 0), (256, 16), (0, 512), (-16, 256),
                                                   (-256, 0), (-512, -16), (0, -256), (16, -256)]])),
    np.array([((0, ROW), (W * SUBPIXEL, ROW), (W * SUBPIXEL, ROW + 1)),
              ((0, ROW), (W * SUBPIXEL, ROW + 1), (0, ROW + 1))], np.int64),
]


@st.composite
def with_subarea(draw, meshes):
    subarea = draw(st.sampled_from(SUBAREAS))
    return draw(meshes(subarea)), subarea


# ---------------------------------------------------------------------------------------------
# Screen-space properties


@PROPS
@given(case=with_subarea(grid_meshes))
@example(case=(EXAMPLES[0], 16)).via("diagonal through two sub-area corners")
@example(case=(EXAMPLES[0], 32)).via("diagonal through a sub-area corner")
@example(case=(EXAMPLES[1], 4)).via("rectangles meeting on sub-area boundaries")
def test_triangulated_grids_cover_each_sample_once(case):
    check_watertight(*case)


@PROPS
@given(case=with_subarea(fan_meshes))
@example(case=(EXAMPLES[2], 16)).via("fan around a sub-area corner")
@example(case=(EXAMPLES[2], 8)).via("fan around a sub-area corner, smaller sub-areas")
@example(case=(EXAMPLES[3], 4)).via("fan around a sample point, spokes through samples")
def test_fans_cover_each_sample_once(case):
    check_watertight(*case)


@PROPS
@given(case=with_subarea(split_convex_polygons))
def test_split_convex_polygons_cover_each_sample_once(case):
    check_watertight(*case)


@PROPS
@given(case=with_subarea(sliver_stacks))
@example(case=(EXAMPLES[4], 16)).via("needle 1/256 px wide on a row of pixel centres")
def test_sliver_stacks_cover_each_sample_once(case):
    check_watertight(*case)


@settings(max_examples=25, deadline=None)
@given(subarea=st.sampled_from([4, 8, 16]), nx=st.integers(1, 5), ny=st.integers(1, 4),
       seed=st.integers(0, 2**32 - 1), quantum=st.sampled_from([1, GRID]))
def test_a_mesh_over_the_whole_raster_covers_every_subpixel_position_once(subarea, nx, ny, seed,
                                                                          quantum):
    """All 256 positions of the 1/16-pixel grid, pixel corners included, on a small raster that
    a jittered grid mesh covers entirely: every one is covered exactly once."""
    w, h = 24, 20
    rng = np.random.default_rng(seed)
    margin = int(rng.integers(0, 3 * SUBPIXEL))
    xs = np.linspace(-margin, w * SUBPIXEL + margin, nx + 1).round().astype(np.int64)
    ys = np.linspace(-margin, h * SUBPIXEL + margin, ny + 1).round().astype(np.int64)
    gx, gy = np.meshgrid(xs, ys)
    amp = min(np.diff(xs).min(), np.diff(ys).min()) // 5 // quantum
    jx = rng.integers(-amp, amp + 1, gx.shape) * quantum
    jy = rng.integers(-amp, amp + 1, gy.shape) * quantum
    jx[:, [0, -1]] = 0
    jy[[0, -1], :] = 0
    screen, _ = mesh_polygons(grid_triangles(gx + jx, gy + jy, rng.random((ny, nx)) < 0.5))
    counts = coverage_counts(screen, w, h, ALL_OFFSETS, subarea=subarea)
    stored, seen = renderer_coverage(screen, w, h, ALL_OFFSETS, subarea)
    assert seen.all() and (stored == 1).all(), "the renderer's store differs from coverage_counts"
    bad = np.argwhere(counts != 1)
    assert bad.size == 0, f"{len(bad)} samples not covered once, first (y, x, s) {bad[0]}, " \
                          f"count {counts[tuple(bad[0])]}, offset {ALL_OFFSETS[bad[0][2]]}"


# ---------------------------------------------------------------------------------------------
# End to end: a closed room seen from inside

RW, RH = 32, 24
ROOM_CH = ChannelSpec.symmetric("room", RW, RH, 60.0)
FAR = (1.0e6, -1.0e6, 50.0)
#: Box corners and faces counter-clockwise from outside (conftest.box_model's order).
_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], np.float64)
_WALLS = [[3, 2, 1, 0], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
_COLOURS = ["#c04040", "#40c040", "#4040c0", "#c0c040", "#40c0c0", "#c040c0"]


def room_model(half: np.ndarray, rng: np.random.Generator, fin_x: float | None = None) -> dict:
    """Inward-facing walls of a box of half-sizes `half` (metres), each a fan of four triangles
    around a jittered point of the wall, sharing only the box corners with its neighbours; with
    fin_x, also a double-sided partition in the plane x = fin_x."""
    verts = [list(c) for c in _CORNERS * half]
    faces = []
    for w, quad in enumerate(_WALLS):
        corners = _CORNERS[quad] * half
        axis = int(np.argmax(np.ptp(corners, axis=0) == 0))  # the wall's constant coordinate
        centre = corners.mean(axis=0) + rng.uniform(-0.4, 0.4, 3) * half
        centre[axis] = corners[0, axis]  # exactly in the wall's plane
        verts.append(list(centre))
        inward = quad[::-1]  # counter-clockwise seen from inside
        for i in range(4):
            faces.append({"indices": [len(verts) - 1, inward[i], inward[(i + 1) % 4]],
                          "colour": _COLOURS[w]})
    if fin_x is not None:
        y, z = half[1] * 0.6, half[2] * 0.6
        base = len(verts)
        verts += [[fin_x, -y, -z], [fin_x, y, -z], [fin_x, y, z], [fin_x, -y, z]]
        faces.append({"indices": [base, base + 1, base + 2, base + 3], "colour": "#ffffff"})
        faces.append({"indices": [base + 3, base + 2, base + 1, base], "colour": "#000000"})
    return {"vertices": verts, "faces": faces}


def render_room(make_scene, half, local_eye, hpr_room, hpr_eye, origin, seed, fin_x=None):
    rng = np.random.default_rng(seed)
    model = room_model(np.asarray(half, np.float64), rng, fin_x=fin_x)
    db = make_scene({"room": model},
                    [{"model": "room", "position": list(origin), "hpr": list(hpr_room)}])
    eye_world = np.asarray(origin) + hpr_matrix(*hpr_room) @ np.asarray(local_eye, np.float64)
    trace: dict = {}
    image = render_frame(db, ROOM_CH, Eyepoint.of(*eye_world, *hpr_eye), RenderOptions(samples="d3d16", filter="box"),
                         trace=trace)
    return image, trace, 6 * 4  # room faces come first: feature ids below 24


def room_only(screen: ScreenPolygons, n_room_faces: int) -> ScreenPolygons:
    """The polygons of the room's walls (feature ids below n_room_faces)."""
    idx = np.nonzero(screen.feature_id < n_room_faces)[0]
    counts = np.diff(screen.start)[idx]
    rows = np.concatenate([np.arange(screen.start[i], screen.start[i + 1]) for i in idx])
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return ScreenPolygons(screen.fixed[rows], start,
                          screen.inv_z[idx], screen.colour[idx], screen.opacity[idx],
                          screen.feature_id[idx], screen.layer[idx])


def check_room(image, trace, n_room_faces, half):
    screen, buf = trace["screen"], trace["buffer"]
    assert np.isfinite(image.rgb).all() and np.isfinite(screen.inv_z).all()
    assert (buf.opaque >= 0).all(), f"{(buf.opaque < 0).sum()} samples see through the room"
    counts = coverage_counts(room_only(screen, n_room_faces), RW, RH, buf.offsets)
    assert (counts == 1).all(), f"walls cover samples {np.unique(counts)} times"
    diagonal = 2.0 * float(np.linalg.norm(half))
    assert np.isfinite(image.range_m).all()
    assert image.range_m.min() >= 0.25 and image.range_m.max() <= diagonal * 1.001


def room_props(n: int) -> settings:
    # make_scene is a stateless factory: sharing it between generated inputs is safe.
    return settings(max_examples=n, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


attitudes = st.tuples(st.floats(-180, 360), st.floats(-90, 90), st.floats(-180, 180))


@room_props(30)
@given(half=st.tuples(*[st.floats(1.0, 8.0)] * 3), where=st.tuples(*[st.floats(-1, 1)] * 3),
       hpr_room=attitudes, hpr_eye=attitudes, far=st.booleans(), seed=st.integers(0, 2**32 - 1))
@example(half=(2.0, 3.0, 1.5), where=(0.0, 0.0, 0.0), hpr_room=(0.0, 0.0, 0.0),
         hpr_eye=(0.0, 90.0, 0.0), far=True, seed=1).via("straight up, 1000 km out")
@example(half=(2.0, 3.0, 1.5), where=(1.0, -1.0, 1.0), hpr_room=(30.0, 0.0, 0.0),
         hpr_eye=(45.0, -90.0, 0.0), far=True, seed=2).via("straight down from a corner")
@example(half=(4.0, 4.0, 4.0), where=(0.0, 0.0, 0.0), hpr_room=(0.0, 0.0, 0.0),
         hpr_eye=(45.0, 35.26438968, 0.0), far=False, seed=3).via("looking into a corner")
def test_a_closed_room_seen_from_inside_shows_every_sample_one_wall(make_scene, half, where,
                                                                    hpr_room, hpr_eye, far, seed):
    """Every wall the eye sees crosses the near plane or the frustum sides somewhere; the eye
    is at least 0.5 m from every wall, so near-plane clipping cannot open a hole (a wall
    point inside a 60 x 45 degree frustum is at least 0.81 times its distance ahead)."""
    half = np.array(half)
    local_eye = np.array(where) * (half - 0.5)
    origin = FAR if far else (0.0, 0.0, 50.0)
    image, trace, n = render_room(make_scene, half, local_eye, hpr_room, hpr_eye, origin, seed)
    check_room(image, trace, n, half)


@room_props(20)
@given(hpr_eye=attitudes, far=st.booleans(), seed=st.integers(0, 2**32 - 1))
@example(hpr_eye=(90.0, 0.0, 0.0), far=True, seed=0).via("looking along the partition's normal")
@example(hpr_eye=(0.0, 0.0, 0.0), far=True, seed=0).via("looking along the partition")
def test_an_edge_on_partition_through_the_eye_hides_nothing(make_scene, hpr_eye, far, seed):
    """A double-sided partition whose plane contains the eye exactly is seen edge-on: it covers
    no area, so backface elimination drops both its faces (backface.py), and it must leave no
    NaN, hole or double coverage in the room around it."""
    half = np.array([3.0, 4.0, 2.5])
    local_eye = np.array([0.75, -0.5, 0.25])
    origin = FAR if far else (0.0, 0.0, 50.0)
    image, trace, n = render_room(make_scene, half, local_eye, (0.0, 0.0, 0.0), hpr_eye, origin,
                                  seed, fin_x=local_eye[0])
    check_room(image, trace, n, half)
    assert not (trace["screen"].feature_id >= n).any(), "an edge-on partition face was kept"


def test_the_partition_is_seen_when_not_edge_on(make_scene):
    """Control for the edge-on test: half a metre off its plane, looking at it, the eye sees
    the partition over most of the picture, and the room still covers every sample once."""
    half = np.array([3.0, 4.0, 2.5])
    image, trace, n = render_room(make_scene, half, np.array([0.25, -0.5, 0.25]), (0.0, 0.0, 0.0),
                                  (90.0, 0.0, 0.0), FAR, 0, fin_x=0.75)
    check_room(image, trace, n, half)
    seen = trace["screen"].feature_id[trace["buffer"].opaque]
    assert (seen >= n).mean() > 0.5
