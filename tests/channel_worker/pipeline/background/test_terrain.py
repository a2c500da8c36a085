"""The terrain stage (channel_worker/pipeline/terrain.py) against the exact reference ray caster
(channel_worker/testing/terrain_reference.py), and its level selection, page fallback, hard
views and channel seams.

Sky and earth share one grey in these scenes and there is no haze, so a sample that misses the
terrain has the same colour in the renderer and in the reference (see terrain_fixtures.compare).
Rasters are 160 x 120 (60 degrees wide, 4 rotated-grid samples) unless said otherwise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.background.terrain import MIN_CLEARANCE_M
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.scene.terrain.database import Pattern
from channel_worker.testing.terrain_reference import reference_terrain, single_level_database
from services.rig.frame import ChannelSpec, Eyepoint

from ..terrain_fixtures import (
    CENTRE,
    HILLS_ORIGIN,
    HILLS_SPACING,
    RGSS4,
    Comparison,
    coarse_levels,
    compare,
    flat_nodes,
    hills_db,
    hills_nodes,
    hit_points,
    level_coloured_db,
    level_of,
    multi_level,
    render_terrain,
    scene,
    surface_z,
    uphill_heading,
    without_pages,
)

CHANNEL = ChannelSpec.symmetric("c", 160, 120, 60.0)
#: Wide and off-axis: 120 degrees across, 35 below and 10 above the axis, turned 35 right.
WIDE = ChannelSpec("wide", 200, 100, -60.0, 60.0, -35.0, 10.0, yaw_deg=35.0)
#: The default rig's right channel: 60 x 45 degrees, turned 60 degrees right.
YAWED = ChannelSpec("right", 160, 120, -30.0, 30.0, -22.5, 22.5, yaw_deg=60.0)

# Bounds of the accuracy tests, from measurement on the views below (default settings,
# 2026-11 kernels) with a margin of about 2 to 3 times the worst case:
#   colour mean abs error per pixel (linear): measured <= 0.0013 (wide channel)  -> bound 0.004
#   its 99th percentile:                      measured <= 0.022  (wide channel)  -> bound 0.05
#   samples whose coverage disagrees:         measured <= 0.0008 (wide channel)  -> bound 0.003
#     (silhouette samples: the reference point-samples, the renderer interpolates coverage)
#   pixel-centre range, median rel. error:    measured <= 0.006  (grazing)       -> bound 0.015
#   pixel-centre range, 95th pct rel. error:  measured <= 0.016  (grazing)       -> bound 0.04
COLOUR_MEAN, COLOUR_P99, COVERAGE, RANGE_MEDIAN, RANGE_P95 = 0.004, 0.05, 0.003, 0.015, 0.04


def assert_accurate(c: Comparison, *, colour_mean: float = COLOUR_MEAN,
                    colour_p99: float = COLOUR_P99, coverage: float = COVERAGE) -> None:
    assert c.finite, str(c)
    assert c.colour_mean <= colour_mean, str(c)
    assert c.colour_p99 <= colour_p99, str(c)
    assert c.coverage_disagree <= coverage, str(c)
    assert c.range_median <= RANGE_MEDIAN, str(c)
    assert c.range_p95 <= RANGE_P95, str(c)


def _grazing_eye(*, downhill: bool = False) -> Eyepoint:
    """3 m above a slope of the hills, looking level along it (up or down the slope)."""
    t = hills_db()
    x, y = 300.0, -1500.0
    heading = uphill_heading(t, x, y) + (180.0 if downhill else 0.0)
    return Eyepoint.of(x, y, surface_z(t, x, y) + 3.0, heading, 0.0, 0.0)


HILLS_VIEWS = {
    "level": (CHANNEL, lambda: Eyepoint.of(0.0, -2400.0, 320.0, 20.0, 0.0, 0.0)),
    "roll30": (CHANNEL, lambda: Eyepoint.of(0.0, -2400.0, 320.0, 20.0, -10.0, 30.0)),
    "roll90": (CHANNEL, lambda: Eyepoint.of(0.0, -2400.0, 320.0, 20.0, -10.0, 90.0)),
    "roll180": (CHANNEL, lambda: Eyepoint.of(0.0, -2400.0, 320.0, 20.0, -10.0, 180.0)),
    "straight-down": (CHANNEL, lambda: Eyepoint.of(100.0, 200.0, 1500.0, 30.0, -90.0, 0.0)),
    "straight-up": (CHANNEL, lambda: Eyepoint.of(100.0, 200.0, 300.0, 30.0, 90.0, 0.0)),
    "yawed-60": (YAWED, lambda: Eyepoint.of(0.0, -2400.0, 320.0, 20.0, -5.0, 10.0)),
    "wide-off-axis": (WIDE, lambda: Eyepoint.of(-1000.0, -2000.0, 350.0, 10.0, -5.0, 0.0)),
    "grazing-uphill": (CHANNEL, lambda: _grazing_eye()),
    "grazing-downhill": (CHANNEL, lambda: _grazing_eye(downhill=True)),
    "outside-looking-in": (CHANNEL, lambda: Eyepoint.of(0.0, -6000.0, 400.0, 0.0, -5.0, 0.0)),
    "inside-looking-out": (CHANNEL, lambda: Eyepoint.of(300.0, 2000.0, 350.0, 10.0, -20.0, 0.0)),
}


@pytest.mark.parametrize("name", list(HILLS_VIEWS))
def test_hills_match_the_reference(name):
    channel, eye = HILLS_VIEWS[name]
    db = scene(terrain=hills_db())
    c = compare(db, make_view(channel, eye()))
    assert_accurate(c)
    if name == "straight-up":
        assert c.coverage_ours == 0.0 and c.coverage_ref == 0.0
    else:
        assert c.coverage_ref > 0.05, f"{name}: the view should see terrain ({c})"


@pytest.mark.parametrize("height, pitch", [(5.0, -10.0), (20.0, -30.0), (300.0, -10.0)])
def test_flat_field_matches_the_reference(height, pitch):
    # A flat field (every point at the database's highest height) is where an early end of the
    # column scan would show first: all of it lies at the horizon the scan has reached.
    h, c = flat_nodes(64)
    t = single_level_database(h, c, 10.0, np.array([-320.0, -320.0, 0.0]), page_size=16)
    eye = Eyepoint.of(0.0, -300.0, height, 10.0, pitch, 0.0)
    res = compare(scene(terrain=t), make_view(CHANNEL, eye))
    assert_accurate(res)
    assert res.coverage_ours > 0.1, str(res)


def _checker_db():
    """20 m voxels whose nodes alternate red and blue: strong colour variation in every voxel."""
    n = 32
    j, i = np.mgrid[0:n + 1, 0:n + 1]
    c = np.where(((i + j) % 2 == 0)[..., None], np.array([220, 40, 40], np.uint8),
                 np.array([40, 40, 220], np.uint8)).astype(np.uint8)
    return single_level_database(np.zeros((n + 1, n + 1), np.float32), c, 20.0,
                                 np.array([-320.0, -320.0, 0.0]), page_size=8)


@pytest.mark.parametrize("eye", [Eyepoint.of(3.0, -250.0, 10.0, 10.0, -20.0, 0.0),
                                 Eyepoint.of(3.0, 7.0, 30.0, 10.0, -90.0, 0.0)],
                         ids=["oblique", "straight-down"])
def test_magnified_voxels_are_coloured_bilinearly(eye):
    # Level 0 near the eye: each 20 m voxel covers tens of pixels.
    assert_accurate(compare(scene(terrain=_checker_db()), make_view(CHANNEL, eye)))


# ----------------------------------------------------------------------------- no voxel missed

SPIKE_N, SPIKE_SPACING = 64, 10.0
RED = np.array([255, 0, 0], np.uint8)


def _spike_db(i: int, j: int, tall: float):
    """A flat field with one pattern voxel (i, j): a red box `tall` metres high (none if 0)."""
    h, c = flat_nodes(SPIKE_N)
    mask = np.zeros((SPIKE_N, SPIKE_N), np.uint8)
    mask[j, i] = 1 if tall > 0.0 else 0
    spike = Pattern("spike", np.array([tall], np.float32), RED[None, :])
    return single_level_database(h, c, SPIKE_SPACING, np.zeros(3), page_size=16,
                                 pattern_mask=mask, patterns=(spike,))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(i=st.integers(0, SPIKE_N - 1), j=st.integers(0, SPIKE_N - 1),
       tall=st.floats(5.0, 80.0), distance=st.floats(15.0, 1400.0),
       bearing=st.floats(0.0, 360.0), height=st.floats(1.0, 400.0),
       aim_h=st.floats(-25.0, 25.0), aim_p=st.floats(-15.0, 15.0), roll=st.floats(-180.0, 180.0))
@example(i=0, j=0, tall=5.0, distance=741.0, bearing=0.0, height=9.0, aim_h=3.0, aim_p=0.0,
         roll=2.0)  # at the database corner, grazing: the spike spreads over two pixels
def test_no_voxel_is_missed(i, j, tall, distance, bearing, height, aim_h, aim_p, roll):
    """Wherever the reference sees the spike in more than half of a pixel's samples, the
    renderer shows spike colour at that pixel or a neighbour.

    The spike is kept within 1400 m, where its 10 m voxel is at least one pixel wide
    (60 degrees / 160 px = 6.5 mrad): the cast has one line per pixel across, so a voxel
    narrower than a pixel in azimuth can fall between two lines (JP H07-76990 samples one ray
    per column too); the level selection is there to keep voxels a pixel wide or more.
    """
    t = _spike_db(i, j, tall)
    sx, sy = (i + 0.5) * SPIKE_SPACING, (j + 0.5) * SPIKE_SPACING
    b = math.radians(bearing)
    eye_x, eye_y = sx - distance * math.sin(b), sy - distance * math.cos(b)
    depression = math.degrees(math.atan2(height - 0.5 * tall, distance))
    view = make_view(CHANNEL, Eyepoint.of(eye_x, eye_y, height, bearing + aim_h,
                                          -depression + aim_p, roll))
    ref = reference_terrain(t, view, RGSS4)
    spike = ref.hit & (ref.rgb[..., 0] > 0.9) & (ref.rgb[..., 1] < 0.1)
    seen = spike.mean(axis=2) > 0.5
    if not seen.any():
        return
    bg = render_terrain(scene(terrain=t), view, RGSS4)
    flat = render_terrain(scene(terrain=_spike_db(i, j, 0.0)), view, RGSS4)
    # Spike red is r - g = 1; the ground (r - g = -0.16) and the grey background (0) are not
    # red. What the spike adds to r - g, summed over each pixel and its 8 neighbours, must be
    # at least a quarter of a pixel's worth (the reference saw more than half a pixel's worth:
    # the renderer's resampling may spread it over two pixels).
    added = np.pad((bg.rgb[..., 0] - bg.rgb[..., 1]) - (flat.rgb[..., 0] - flat.rgb[..., 1]), 1)
    h, w = seen.shape
    nearby = np.sum([added[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)], axis=0)
    missed = seen & (nearby < 0.25)
    assert not missed.any(), (f"spike missed at pixels {np.argwhere(missed)[:5].tolist()} "
                              f"({int(missed.sum())} of {int(seen.sum())})")


# ----------------------------------------------------------------------------- level selection

PIXEL = math.radians(60.0) / 160.0  # CHANNEL's pixel angle (radians)


@pytest.fixture(scope="module")
def level_field():
    """32.8 km of flat ground, 2 m voxels, 7 levels, each level its own colour."""
    return scene(terrain=level_coloured_db(16384, 2.0, page_size=256), sky="#000000",
                 earth="#000000")


def _switch_range(bg, level: int, column: int) -> float:
    """Slant range (metres) where level + 1 takes over along an image column: where the
    fractional level crosses level + 1/2, interpolated between pixel centres (log range)."""
    lev = level_of(bg.rgb[::-1, column, 0].astype(np.float64))  # near (bottom) to far
    rng = np.log(bg.range_m[::-1, column].astype(np.float64))
    k = np.flatnonzero((lev[:-1] < level + 0.5) & (lev[1:] >= level + 0.5))
    assert k.size == 1, f"level {level}: no single crossing in column {column}: {lev.round(2)}"
    k = int(k[0])
    f = (level + 0.5 - lev[k]) / (lev[k + 1] - lev[k])
    return math.exp(rng[k] + f * (rng[k + 1] - rng[k]))


def _switch_ranges(level_field, bias: int, predicted) -> list[float]:
    """Measured slant range of the switch from level L to L + 1, L = 0..4, each from a view
    looking down 35 degrees at predicted(L) (about 0.8 % of range per pixel row)."""
    out = []
    for level in range(5):
        guess = predicted(level)
        eye = Eyepoint.of(16384.0, 16384.0, guess * math.sin(math.radians(35.0)), 30.0, -35.0, 0.0)
        bg = render_terrain(level_field, make_view(CHANNEL, eye), CENTRE, level_bias=bias)
        out.append(float(np.median([_switch_range(bg, level, x) for x in (40, 80, 120)])))
    return out


#: Where level L + 1 takes over (terrain._scan: slant = spacing 2**(L - bias) / pixel angle):
#: a level-L voxel has shrunk to 2**bias pixels there.
def _switch_now(level: int, bias: int) -> float:
    return 2.0 * 2.0 ** (level - bias) / PIXEL


@pytest.mark.parametrize("bias", [-1, 0, 1])
def test_level_switch_range_doubles_per_level_and_per_bias_step(level_field, bias):
    """Level L + 1 takes over twice as far as level L did, and one step of bias moves every
    switch by a factor of 2.

    Measured: every switch within 0.3 % of _switch_now (and so the ratios within 0.5 % of 2);
    bound 2 %.
    """
    ranges = _switch_ranges(level_field, bias, lambda lv: _switch_now(lv, bias))
    ratios = np.array(ranges[1:]) / np.array(ranges[:-1])
    assert np.allclose(ratios, 2.0, rtol=0.02), ratios
    if bias != 0:
        base = _switch_ranges(level_field, 0, lambda lv: _switch_now(lv, 0))
        shift = np.log2(np.array(ranges) / np.array(base))
        assert np.allclose(np.abs(shift), 1.0, atol=0.03), shift


@pytest.mark.parametrize("bias", [-1, 0, 1])
def test_level_switch_keeps_voxels_as_wide_as_documented(level_field, bias):
    """Voxels are kept 2**bias to 2**(bias + 1) pixels wide: level L + 1 takes over where a
    level-L voxel has shrunk to 2**bias pixels, at slant range spacing 2**(L - bias) / pixel."""
    spacing = level_field.terrain.spacing_m
    ranges = _switch_ranges(level_field, bias, lambda lv: _switch_now(lv, bias))
    width_px = [spacing * 2.0 ** lv / r / PIXEL for lv, r in enumerate(ranges)]
    assert np.allclose(width_px, 2.0 ** bias, rtol=0.05), width_px


def test_voxels_visited_grow_by_a_constant_per_doubling_of_range(level_field):
    """Each doubling of the visible range adds one level's worth of voxels (measured: +32,080
    per doubling from 2 to 16 km, to within 0.02 %); scanning level 0 to the far plane would
    add 2, 4, 8 times as many. Shallower views see farther and visit more voxels."""
    visits = {}
    for pitch in (-10.0, -30.0, -60.0):
        for far in (2000.0, 4000.0, 8000.0, 16000.0):
            eye = Eyepoint.of(16384.0, 16384.0, 50.0, 30.0, pitch, 0.0)
            view = make_view(CHANNEL, eye, far=far)
            visits[pitch, far] = render_terrain(level_field, view, CENTRE).stats["terrain_voxels"]
    steps = np.diff([visits[-10.0, f] for f in (2000.0, 4000.0, 8000.0, 16000.0)])
    assert steps.min() > 0, steps
    assert steps.max() <= 1.25 * steps.min(), steps  # roughly constant per doubling
    assert visits[-10.0, 16000.0] < 2.5 * visits[-10.0, 2000.0], visits  # 8 x the range
    assert visits[-60.0, 16000.0] < visits[-30.0, 16000.0] < visits[-10.0, 16000.0], visits


def test_a_coarser_bias_visits_fewer_voxels(level_field):
    view = make_view(CHANNEL, Eyepoint.of(16384.0, 16384.0, 50.0, 30.0, -10.0, 0.0), far=16000.0)
    v = [render_terrain(level_field, view, CENTRE, level_bias=b).stats["terrain_voxels"]
         for b in (-1, 0, 1)]
    assert v[0] > v[1] > v[2], v


def test_level_bias_out_of_range_is_refused():
    db = scene(terrain=hills_db())
    view = make_view(CHANNEL, Eyepoint.of(0.0, -2400.0, 320.0, 0.0, -10.0, 0.0))
    for bad in (5, -5, 0.5, True):
        with pytest.raises(ValueError, match="terrain_bias"):
            render_terrain(db, view, RGSS4, level_bias=bad)


# ----------------------------------------------------------------------------- page fallback


@pytest.fixture(scope="module")
def hills_levels():
    """The hills built into 4 levels of 16 x 16 voxel pages (level 0: 8 x 8 pages)."""
    h, c = hills_nodes()
    return multi_level(h, c, HILLS_SPACING, HILLS_ORIGIN, page_size=16)


HOLE_VIEWS = [(0.0, 4000.0, -90.0, 0.0), (-600.0, 500.0, -30.0, 0.0), (-600.0, 500.0, -30.0, 40.0)]


def _hole_renders(full, hole: range, dy: float, height: float, pitch: float, roll: float):
    """Renders of the full database, the one lacking level-0 pages hole x hole, and its
    levels 1.. alone, from an eye over (or before) the hole; and the hole's world square."""
    page_m = full.page_size * full.spacing_m
    x0 = full.origin[0] + hole.start * page_m
    x1 = full.origin[0] + hole.stop * page_m
    holes = without_pages(full, 0, [(px, py) for px in hole for py in hole])
    mid = 0.5 * (x0 + x1)
    y = mid if dy == 0.0 else x0 + dy
    view = make_view(CHANNEL, Eyepoint.of(mid, y, height, 10.0, pitch, roll))
    out = [render_terrain(scene(terrain=t), view, RGSS4)
           for t in (full, holes, coarse_levels(full, 1))]
    return view, out, (x0, x1)


@pytest.mark.parametrize("hole", [range(2, 6), range(2, 5)], ids=["coarse-page", "fine-pages"])
@pytest.mark.parametrize("where", HOLE_VIEWS, ids=["above", "before", "before-rolled"])
def test_missing_fine_pages_render_like_the_coarser_level(hills_levels, hole, where):
    view, (full, holes, coarse), (x0, x1) = _hole_renders(hills_levels, hole, *where)
    p = hit_points(view, holes.range_m)
    m = 2.0 * hills_levels.spacing_m  # one level-1 voxel inside the border
    inside = ((p[..., 0] > x0 + m) & (p[..., 0] < x1 - m)
              & (p[..., 1] > x0 + m) & (p[..., 1] < x1 - m))
    assert inside.sum() > 1000
    # Inside the hole: the level-1 data, as a database of only the coarse levels draws it
    # (measured: identical; bound 1e-3, against 0.013 mean between level 0 and level 1 there).
    d = np.abs(holes.rgb - coarse.rgb).max(axis=2)[inside]
    assert d.mean() <= 1e-4 and d.max() <= 1e-2, (d.mean(), d.max())
    assert np.abs(full.rgb - coarse.rgb).max(axis=2)[inside].mean() > 0.005  # levels differ
    # Across the borders nothing is lost and nothing breaks.
    for a in (holes.rgb, holes.inv_z):
        assert np.isfinite(a).all()
    assert not np.isnan(holes.range_m).any()
    assert np.mean((holes.inv_z > 0) != (full.inv_z > 0)) <= 0.001


@pytest.mark.parametrize("hole", [range(2, 6), range(2, 5)],
    ids=["coarse-page", "fine-pages"])
@pytest.mark.parametrize("where", HOLE_VIEWS, ids=["above", "before", "before-rolled"])
def test_pages_beyond_a_hole_are_drawn_at_their_own_level(hills_levels, hole, where):
    view, (full, holes, _), (x0, x1) = _hole_renders(hills_levels, hole, *where)
    p = hit_points(view, holes.range_m)
    m = 2.0 * hills_levels.spacing_m
    near = ((p[..., 0] > x0 - m) & (p[..., 0] < x1 + m)
            & (p[..., 1] > x0 - m) & (p[..., 1] < x1 + m))
    # A pixel whose centre lands outside may still take part of its colour from inside the
    # hole (behind a crest, along a silhouette): leave out the pixels next to those inside.
    grown = np.pad(near, 1)
    near = np.any([grown[1 + dy:grown.shape[0] - 1 + dy, 1 + dx:grown.shape[1] - 1 + dx]
                   for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)
    outside = np.isfinite(p[..., 0]) & ~near
    assert outside.sum() > 1000
    d = np.abs(holes.rgb - full.rgb).max(axis=2)[outside]
    assert d.max() <= 0.01, (d.mean(), d.max())


# ----------------------------------------------------------------------------- hard cases


def test_eye_below_the_surface_is_clamped_and_counted():
    db = scene(terrain=hills_db())
    x, y = 300.0, -1500.0
    ground = surface_z(db.terrain, x, y)
    def at_height(z):
        return render_terrain(db, make_view(CHANNEL, Eyepoint.of(x, y, z, 20.0, -5.0, 0.0)), RGSS4)

    below = at_height(ground - 10.0)
    assert below.stats["terrain_eye_clamped"] == 1
    for a in (below.rgb, below.inv_z):
        assert np.isfinite(a).all()
    assert not np.isnan(below.range_m).any()
    # The picture is the one from the clamped eye (measured: identical).
    at = at_height(ground + MIN_CLEARANCE_M)
    assert np.allclose(below.rgb, at.rgb, atol=1e-5)
    assert np.allclose(below.inv_z, at.inv_z, rtol=1e-4)
    clear = at_height(ground + 1.0)
    assert clear.stats["terrain_eye_clamped"] == 0


def test_eye_exactly_on_the_surface():
    db = scene(terrain=hills_db())
    x, y = 300.0, -1500.0
    ground = surface_z(db.terrain, x, y)
    heading = uphill_heading(db.terrain, x, y)
    bg = render_terrain(db, make_view(CHANNEL, Eyepoint.of(x, y, ground, heading, 0.0, 0.0)), RGSS4)
    assert bg.stats["terrain_eye_clamped"] == 1
    for a in (bg.rgb, bg.inv_z):
        assert np.isfinite(a).all()
    assert not np.isnan(bg.range_m).any()
    assert (bg.inv_z > 0).mean() > 0.3  # the slope ahead fills the lower half and more


@pytest.mark.parametrize("pitch", [-90.0, -89.999, 90.0, 89.999])
@pytest.mark.parametrize("heading, roll", [(0.0, 0.0), (37.0, 0.0), (90.0, 30.0)])
def test_straight_down_and_up(pitch, heading, roll):
    db = scene(terrain=hills_db())
    c = compare(db, make_view(CHANNEL, Eyepoint.of(320.0, -1600.0, 400.0, heading, pitch, roll)))
    assert_accurate(c)
    assert c.coverage_ours == (1.0 if pitch < 0 else 0.0), str(c)


def test_a_database_1000_km_away_renders_like_one_at_the_origin():
    near, far = scene(terrain=hills_db()), scene(terrain=hills_db(1e6))
    for x, y, z, h, p, r in [(0.0, -2400.0, 320.0, 20.0, -10.0, 0.0),
                             (100.0, 200.0, 1500.0, 30.0, -90.0, 0.0),
                             (-500.0, -2000.0, 150.0, 30.0, -5.0, -35.0)]:
        a = render_terrain(near, make_view(CHANNEL, Eyepoint.of(x, y, z, h, p, r)), RGSS4)
        b = render_terrain(far, make_view(CHANNEL, Eyepoint.of(x + 1e6, y + 1e6, z, h, p, r)),
                           RGSS4)
        # Measured: bit-identical (the eye is made database-relative in float64 first).
        assert np.allclose(a.rgb, b.rgb, rtol=1e-6, atol=1e-6)
        assert np.allclose(a.inv_z, b.inv_z, rtol=1e-6, atol=0.0)
        assert np.array_equal(np.isinf(a.range_m), np.isinf(b.range_m))
        fin = np.isfinite(a.range_m)
        assert np.allclose(a.range_m[fin], b.range_m[fin], rtol=1e-6)


@pytest.mark.parametrize("heading", [0.0, 90.0, 180.0, 270.0])
@pytest.mark.parametrize("pitch", [0.0, -20.0])
def test_rays_along_grid_lines(heading, pitch):
    # The eye on a grid line crossing (x and y multiples of 40 m from the origin) and the
    # central cast line exactly along a grid line.
    db = scene(terrain=hills_db())
    x, y = 320.0, -1600.0
    assert (x - HILLS_ORIGIN[0]) % HILLS_SPACING == 0 and (y - HILLS_ORIGIN[1]) % HILLS_SPACING == 0
    c = compare(db, make_view(CHANNEL, Eyepoint.of(x, y, 400.0, heading, pitch, 0.0)))
    assert_accurate(c)  # includes: no NaN or infinity
    # No gap: every image column holds as much terrain as the reference's (measured <= 0.005;
    # a line lost along a grid line leaves an image column empty).
    assert c.column_gap <= 0.03, str(c)


@pytest.mark.parametrize("nx, ny", [(1, 1), (1, 24), (24, 1)])
def test_a_database_one_voxel_wide(nx, ny):
    """A ramp 5 m high across the voxel, red on the west side and blue on the east."""
    h = np.zeros((ny + 1, nx + 1), np.float32)
    h[:, 1:] = 5.0
    c = np.zeros((ny + 1, nx + 1, 3), np.uint8)
    c[...] = (200, 60, 40)
    c[:, 1:] = (40, 60, 200)
    t = single_level_database(h, c, 20.0, np.zeros(3), page_size=8)
    db = scene(terrain=t)
    # Far enough that the voxel spans few pixels (magnified voxels: see the test above).
    for eye in (Eyepoint.of(10.0, -160.0, 60.0, 0.0, -20.0, 0.0),
                Eyepoint.of(10.0, 10.0, 300.0, 0.0, -90.0, 0.0),
                Eyepoint.of(-300.0, 12.0 * ny, 60.0, 90.0, -10.0, 10.0)):
        c_ = compare(db, make_view(CHANNEL, eye))
        # Coverage: a one-voxel database is all silhouette; measured <= 0.0028.
        assert_accurate(c_, coverage=0.006)
        assert c_.coverage_ref > 0.0005, str(c_)


def test_an_empty_frustum_above_the_horizon_visits_no_voxels():
    db = scene(terrain=hills_db())
    def looking_up(z, pitch):
        eye = Eyepoint.of(0.0, -2400.0, z, 20.0, pitch, 0.0)
        return render_terrain(db, make_view(CHANNEL, eye), RGSS4)

    above = looking_up(400.0, 30.0)
    assert above.stats["terrain_voxels"] == 0
    assert not (above.inv_z > 0).any()
    # Below the highest hill, looking 60 degrees up: the scan stops where the highest point of
    # the database can no longer rise into the lowest row (measured 2,973 voxels for 528
    # columns, about 6 per column, against 15,734 looking 20 degrees down; the same bound holds
    # per line of the cast).
    low = looking_up(150.0, 89.0)
    assert low.stats["terrain_eye_clamped"] == 0
    assert low.stats["terrain_voxels"] <= 10 * low.stats["terrain_lines"]
    assert not (low.inv_z > 0).any()


# ----------------------------------------------------------------------------- seams

SEAM_W, SEAM_H = 120, 90


@pytest.mark.parametrize("eye", [
    Eyepoint.of(0.0, -2400.0, 320.0, 0.0, -10.0, 0.0),
    Eyepoint.of(0.0, -2400.0, 320.0, 0.0, -10.0, 20.0),
    Eyepoint.of(-500.0, -2000.0, 150.0, 30.0, -5.0, -35.0),
    Eyepoint.of(0.0, -2400.0, 320.0, 0.0, -10.0, 90.0),
    Eyepoint.of(0.0, 0.0, 1500.0, 0.0, -70.0, 0.0),
], ids=["level", "roll20", "roll-35", "roll90", "steep"])
def test_terrain_continues_across_a_channel_seam(eye):
    """Two juxtaposed channels (yaw -30 and +30, 60 degrees each): the last column of the left
    image and the first of the right see neighbouring directions, so they differ by no more
    than the terrain itself does between those directions (the reference's difference).

    Measured: our seam difference (max over RGB, mean along the seam) is at most the
    reference's in every view, and differs from it by at most 0.005 on average.
    """
    db = scene(terrain=hills_db())
    left = ChannelSpec("left", SEAM_W, SEAM_H, -30.0, 30.0, -22.5, 22.5, yaw_deg=-30.0)
    right = ChannelSpec("right", SEAM_W, SEAM_H, -30.0, 30.0, -22.5, 22.5, yaw_deg=30.0)
    va, vb = make_view(left, eye), make_view(right, eye)
    a, b = render_terrain(db, va, RGSS4), render_terrain(db, vb, RGSS4)
    ra = reference_terrain(db.terrain, va, RGSS4).pixel_rgb(db.sky_colour)
    rb = reference_terrain(db.terrain, vb, RGSS4).pixel_rgb(db.sky_colour)
    ours = np.abs(a.rgb[:, -1] - b.rgb[:, 0]).max(axis=1)
    ref = np.abs(ra[:, -1] - rb[:, 0]).max(axis=1)
    assert (a.inv_z[:, -1] > 0).any() or (b.inv_z[:, 0] > 0).any()  # terrain at the seam
    assert ours.mean() <= ref.mean() + 0.003, (ours.mean(), ref.mean())
    assert np.abs(ours - ref).mean() <= 0.01, np.abs(ours - ref).mean()
    assert ours.max() <= ref.max() + 0.03, (ours.max(), ref.max())
