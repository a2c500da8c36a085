"""The Voxel Space peer of bench/bench_terrain.py (bench/voxel_space.py) on cases with a known
answer: a flat map seen level and pitched (the horizon row, the ground-plane range of each
row), a wall that hides what is behind it, and the maps taken from a database (also where the
database left level-0 pages out). Correctness only: no test times anything."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

# The benches are scripts in bench/, not an installed package: their folder's parent (the
# checkout) goes on the path so that `bench.voxel_space` imports as bench_terrain.py imports it.
REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from bench.voxel_space import VoxelMaps, render_voxel_space, voxel_maps  # noqa: E402
from channel_worker.pipeline.geometry.view import make_view, screen_mapping  # noqa: E402
from channel_worker.pipeline.scene.terrain.build import build_terrain  # noqa: E402
from services.rig.frame import ChannelSpec, Eyepoint  # noqa: E402

SPACING = 10.0
CELLS = 2000  # 20 km of map each way, the eye in the middle
EYE_Z = 100.0
SKY = np.array([0.2, 0.4, 0.8])
EARTH = np.array([0.1, 0.3, 0.1])
GREY = 128
CHANNEL = ChannelSpec.symmetric("test", 256, 192, 60.0)


def flat_maps(height: float = 0.0) -> VoxelMaps:
    h = np.full((CELLS, CELLS), height, np.float32)
    rgb = np.full((CELLS, CELLS, 3), GREY, np.uint8)
    half = 0.5 * CELLS * SPACING
    return VoxelMaps(h, rgb, np.array([-half, -half, 0.0]), SPACING, float(h.max()))


def view_at(pitch_deg: float = 0.0, heading_deg: float = 0.0):
    eye = Eyepoint(position=np.array([0.0, 0.0, EYE_Z]), heading_deg=heading_deg,
                   pitch_deg=pitch_deg, roll_deg=0.0)
    return make_view(CHANNEL, eye)


def k_and_horizon(view, pitch_deg: float) -> tuple[float, float]:
    """The classic's projection: row = horizon + k (eye_z - h) / depth."""
    _, _, sy_scale, sy_off = screen_mapping(view)
    return -sy_scale, sy_off - sy_scale * math.tan(math.radians(pitch_deg))


def column_tangent(view, col: int) -> float:
    sx_scale, sx_off, _, _ = screen_mapping(view)
    return (col + 0.5 - sx_off) / sx_scale


@pytest.mark.parametrize("growth", [0.0, 0.01])
@pytest.mark.parametrize("pitch_deg", [0.0, -5.0, 4.0])
def test_flat_ground_rows_and_ranges(pitch_deg: float, growth: float) -> None:
    """Flat map at height 0, eye 100 m up: rows above the horizon are sky in every column;
    below it each row's range is the ground-plane range of the row (at pitch 0 the exact
    perspective's; pitched, the classic's horizon shift: the same rows moved by k tan(pitch))
    to within one step of the march (one voxel with growth 0)."""
    view = view_at(pitch_deg)
    frame = render_voxel_space(flat_maps(), view, sky=SKY, earth=EARTH, growth=growth)
    k, horizon = k_and_horizon(view, pitch_deg)
    rows = np.arange(view.height) + 0.5
    above = rows < horizon
    assert np.isinf(frame.range_m[above]).all()
    np.testing.assert_allclose(frame.rgb[above], np.broadcast_to(SKY, frame.rgb[above].shape),
                               atol=1e-6)
    grey = ((GREY / 255.0 + 0.055) / 1.055) ** 2.4
    for col in (0, view.width // 2, view.width - 1):
        tx = column_tangent(view, col)
        lateral = math.hypot(1.0, tx)
        # The first terrain row: the ground at the map's far (north) edge, 10 km deep in every
        # column (the edge is square to the view).
        top = math.ceil(horizon + k * EYE_Z / (0.5 * CELLS * SPACING) - 0.5)
        seen = np.isfinite(frame.range_m[:, col])
        first = int(np.argmax(seen))
        assert abs(first - top) <= 1, (col, first, top)
        assert seen[first:].all()
        np.testing.assert_allclose(frame.rgb[first:, col], grey, atol=1e-6)
        # Each row's depth on the ground: horizon + k eye_z / depth = row centre.
        depth = k * EYE_Z / (rows[first:] - horizon)
        expected = np.hypot(depth * lateral, EYE_Z)
        got = frame.range_m[first:, col].astype(np.float64)
        step = SPACING + growth * depth  # the march's step at that depth
        # Drawn by the first sample at or beyond the row's depth: never nearer, at most one
        # step farther (float32 ranges: a few millimetres).
        assert (got >= expected - 0.01).all(), (col, (expected - got).max())
        assert (got <= expected + step * lateral + 0.01).all(), (col, (got - expected - step * lateral).max())


def test_pitch_shifts_the_picture_by_whole_rows() -> None:
    """Pitch is a horizon shift: a pitch of atan(m / k) moves the ground picture up m rows."""
    level = view_at(0.0)
    k, _ = k_and_horizon(level, 0.0)
    m = 20
    pitched = view_at(-math.degrees(math.atan(m / k)))
    maps = flat_maps()
    a = render_voxel_space(maps, level, sky=SKY, earth=EARTH, growth=0.0)
    b = render_voxel_space(maps, pitched, sky=SKY, earth=EARTH, growth=0.0)
    fa, fb = np.isfinite(a.range_m), np.isfinite(b.range_m)
    np.testing.assert_array_equal(fb[:-m], fa[m:])
    # The same rows see the same ground, to within one step of the march.
    both = fa[m:] & fb[:-m]
    assert np.abs(b.range_m[:-m][both] - a.range_m[m:][both]).max() <= SPACING * 1.2


def test_a_wall_hides_what_is_behind_it() -> None:
    """A 300 m wall 1 km ahead of an eye 100 m up: every column sees the ground up to the
    wall, the wall from its foot to its top, then sky; nothing beyond the wall. (Five cells
    thick: a march whose step has grown past a feature's depth can step over it, the
    classic's known weakness, which this test is not about.)"""
    maps = flat_maps()
    red = np.array([200, 0, 0], np.uint8)
    wall = slice(CELLS // 2 + 100, CELLS // 2 + 105)  # 1000 to 1050 m north of the eye
    maps.height[wall, :] = 300.0
    maps.rgb[wall, :] = red
    maps = maps._replace(z_max=300.0)
    view = view_at(0.0)
    frame = render_voxel_space(maps, view, sky=SKY, earth=EARTH, growth=0.01)
    k, horizon = k_and_horizon(view, 0.0)
    red_linear = ((200 / 255.0 + 0.055) / 1.055) ** 2.4
    for col in range(0, view.width, 17):
        tx = column_tangent(view, col)
        lateral = math.hypot(1.0, tx)
        ranges = frame.range_m[:, col]
        seen = np.isfinite(ranges)
        # Nothing beyond the wall's far face (depth 1050 m).
        assert ranges[seen].max() <= math.hypot(1050.0 * lateral, 200.0) + 0.01
        # The wall's rows: from its top (300 m, 1000 m deep) down to the ground at its foot;
        # above it sky, below it the grey ground.
        red_rows = np.flatnonzero(np.abs(frame.rgb[:, col, 0] - red_linear) < 1e-6)
        top = math.ceil(horizon + k * (EYE_Z - 300.0) / 1000.0 - 0.5)
        foot = math.ceil(horizon + k * EYE_Z / 1000.0 - 0.5)
        assert abs(red_rows[0] - top) <= 1, (col, red_rows[0], top)
        assert abs(red_rows[-1] + 1 - foot) <= 1, (col, red_rows[-1], foot)
        assert np.array_equal(red_rows, np.arange(red_rows[0], red_rows[-1] + 1))
        assert np.isinf(ranges[:red_rows[0]]).all()
        assert seen[red_rows[0]:].all()


def test_maps_from_a_database_also_where_level_0_pages_are_left_out() -> None:
    """Cell height = the surface at the voxel's centre, colour = the mean of its corners (in
    linear light); a plane's level-0 pages are reproduced by level 1 and left out by the
    build's pruning, and the maps take them from the coarser level."""
    n = 64
    j, i = np.mgrid[0:n + 1, 0:n + 1].astype(np.float64)
    heights = 0.5 * i + 0.25 * j
    colours = np.full((n + 1, n + 1, 3), 0.25)
    colours[..., 0] = i / n  # linear in x: the voxel mean is the value at the centre
    for prune in (None, (0.001, 0.001)):
        db = build_terrain(heights, colours, spacing_m=2.0, origin=(100.0, 200.0, 0.0),
                           page_size=8, prune_tolerance=prune)
        if prune is not None:
            assert db.info["build"]["pruned_pages_per_level"][0] > 0
        maps = voxel_maps(db)
        assert maps.height.shape == (n, n) and maps.rgb.shape == (n, n, 3)
        centre_i, centre_j = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
        np.testing.assert_allclose(maps.height, 0.5 * centre_i + 0.25 * centre_j, atol=1e-3)
        red = ((maps.rgb[..., 0] / 255.0 + 0.055) / 1.055) ** 2.4
        np.testing.assert_allclose(red, centre_i / n, atol=0.012)  # two sRGB 8-bit roundings
        np.testing.assert_array_equal(maps.origin, [100.0, 200.0, 0.0])
        assert maps.spacing_m == 2.0 and maps.z_max == pytest.approx(maps.height.max())


def test_rolled_view_is_refused() -> None:
    eye = Eyepoint(position=np.array([0.0, 0.0, EYE_Z]), heading_deg=0.0, pitch_deg=0.0,
                   roll_deg=10.0)
    with pytest.raises(ValueError, match="roll"):
        render_voxel_space(flat_maps(), make_view(CHANNEL, eye), sky=SKY, earth=EARTH)
