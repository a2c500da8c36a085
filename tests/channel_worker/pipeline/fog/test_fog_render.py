"""Layered fog (US 5,535,374) through the whole pipeline: polygons, terrain, sky and earth seen
through the strata, checked pixel by pixel against the optical depth integrated independently
along each pixel's ray, on the hard cases of the issue; and the scene key's validation."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from channel_worker.pipeline.contract import F_ON
from channel_worker.pipeline.geometry.view import make_view, screen_mapping
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import SceneError, parse_scene
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions
from services.rig.report import FrameReport

from ..terrain_fixtures import CENTRE, RGSS4, flat_nodes, linear, render_terrain, scene

SKY, EARTH, WALL, FOG = "#2050c0", "#406020", "#a03020", "#c0c8d0"
SMALL = ChannelSpec.symmetric("c", 96, 72, 60.0)

#: Ground fog: dense at the ground, thinning to clear air at 80 m (20 m sample planes).
GROUND = {"spacing_m": 20.0, "extinction_per_m": [0.03, 0.02, 0.004, 0.0005, 0.0], "colour": FOG}


def exact_depth(fog, eye: np.ndarray, direction: np.ndarray, rng: float) -> float:
    """Optical depth from eye along a unit direction to range rng: trapezoids between the
    ray's ends and every sample plane it crosses, exact for the piecewise-linear strata
    (independent of fog.py's table)."""
    s0 = float(np.dot(eye - fog.origin, fog.axis))
    c = float(np.dot(direction, fog.axis))
    planes = np.arange(fog.extinction.size) * fog.spacing_m
    s1 = s0 + rng * c
    lo, hi = min(s0, s1), max(s0, s1)
    s = np.concatenate([[lo], planes[(planes > lo) & (planes < hi)], [hi]])
    sig = np.interp(s, planes, fog.extinction)
    if hi - lo <= 1e-9 * max(1.0, rng):
        return float(np.interp(s0, planes, fog.extinction)) * rng
    # Along the ray each axis interval is 1 / |c| times longer.
    return float(np.sum(0.5 * (sig[1:] + sig[:-1]) * np.diff(s))) * rng / (hi - lo)


def wall_scene(distance: float, shift=(0.0, 0.0, 0.0), fog: dict | None = None):
    """A 4 km square wall facing south, `distance` north of the point `shift`."""
    x, y, z = shift
    verts = [[-2000.0, 0.0, -2000.0], [2000.0, 0.0, -2000.0], [2000.0, 0.0, 2000.0],
             [-2000.0, 0.0, 2000.0]]
    models = {"wall": {"vertices": verts, "faces": [{"indices": [0, 1, 2, 3], "colour": WALL}]}}
    inst = [{"model": "wall", "position": [x, y + distance, z]}]
    return scene(models=models, instances=inst, sky=SKY, earth=EARTH,
                 fog=dict(GROUND if fog is None else fog))


def pixel_rays(view):
    """(H, W, 3) unit world directions of the pixel centres."""
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    tx = (np.arange(view.width) + 0.5 - sx_off) / sx_scale
    ty = (np.arange(view.height) + 0.5 - sy_off) / sy_scale
    d = np.stack(np.broadcast_arrays(tx[None, :], ty[:, None], np.ones((1, 1))), -1)
    d = d @ view.world_to_eye
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def expected(fog, eye, dirs, ranges, colour):
    t = np.array([math.exp(-exact_depth(fog, eye, d, r)) if np.isfinite(r) else np.nan
                  for d, r in zip(dirs.reshape(-1, 3), ranges.ravel(), strict=True)]).reshape(ranges.shape)
    return t[..., None] * colour + (1.0 - t[..., None]) * fog.colour


def wall_error(db, eye: Eyepoint, distance: float) -> tuple[float, int]:
    """Largest colour error over the pixels whose centre sees the wall (wall_scene with the
    eye at its south point), and how many do."""
    img = render_frame(db, SMALL, eye, RenderOptions(samples="centre"))
    dirs = pixel_rays(make_view(SMALL, eye))
    on = dirs[..., 1] > 1e-6
    rng = np.where(on, distance / np.where(on, dirs[..., 1], 1.0), np.inf)
    hit = dirs * rng[..., None]  # eye-relative
    on &= (np.abs(hit[..., 0]) < 1900.0) & (np.abs(hit[..., 2] + eye.position[2]) < 1900.0)
    want = expected(db.fog, np.asarray(eye.position), dirs[on], rng[on], linear(WALL))
    return float(np.abs(img.rgb[on] - want).max()), int(on.sum())


# Measured at the default table spacing (an eighth of the sample spacing): at most 5e-5 with
# the eye between resample grid points (13.7, 47.3 m), 3e-8 on them (a quarter of the spacing:
# 6e-4; US 5,535,374's linear interpolation of the average at the sample spacing: 0.06).
WALL_BOUND = 5e-4


@pytest.mark.parametrize("height", [10.0, 13.7, 20.0, 40.0, 47.3, 120.0])
@pytest.mark.parametrize("pitch", [-20.0, 0.0, 15.0])
def test_a_wall_through_ground_fog(height, pitch):
    """Eye inside the dense layer (10 m), exactly on sample planes (20, 40 m), between (55 m)
    and above the fog (120 m), looking level, down into and up out of the layers."""
    db = wall_scene(600.0)
    err, n = wall_error(db, Eyepoint.of(0.0, 0.0, height, 0.0, pitch, 0.0), 600.0)
    assert n > 1000
    assert err < WALL_BOUND, err


def test_the_wall_is_between_clear_and_fog_colour():
    """Not a test that cannot fail: inside the dense layer the wall 600 m away is mostly fog,
    above the fog it keeps most of its colour."""
    db = wall_scene(600.0)
    inside = render_frame(db, SMALL, Eyepoint.of(0.0, 0.0, 10.0, 0.0, 0.0, 0.0), RenderOptions(samples="centre"))
    above = render_frame(db, SMALL, Eyepoint.of(0.0, 0.0, 300.0, 0.0, 0.0, 0.0), RenderOptions(samples="centre"))
    fog, wall = linear(FOG), linear(WALL)
    centre_in, centre_above = inside.rgb[36, 48], above.rgb[36, 48]
    assert np.abs(centre_in - fog).max() < 0.02  # tau = 0.0226 * 600 = 13.6: all fog
    assert np.abs(centre_above - wall).max() < 1e-6  # level at 300 m: clear air


def test_homogeneous_fog_is_exp_of_range():
    """One plane: one constant coefficient everywhere, T = exp(-sigma R) for any direction."""
    sigma = 1.0 / 900.0
    db = wall_scene(700.0, fog={"extinction_per_m": [sigma], "colour": FOG})
    eye = Eyepoint.of(0.0, 0.0, 35.0, 0.0, 10.0, 5.0)
    img = render_frame(db, SMALL, eye, RenderOptions(samples="centre"))
    view = make_view(SMALL, eye)
    dirs = pixel_rays(view)
    rng = 700.0 / dirs[..., 1]
    t = np.exp(-sigma * rng)[..., None]
    want = t * linear(WALL) + (1 - t) * linear(FOG)
    on = np.abs(35.0 + dirs[..., 2] * rng) < 1900.0
    assert np.abs(img.rgb[on] - want[on]).max() < 2e-6


def test_a_tilted_axis():
    """Strata tilted 30 degrees from the vertical, origin away from the eye: the wall's
    colour still follows the exact integral along each ray."""
    axis = [math.sin(math.radians(30.0)), 0.2, math.cos(math.radians(30.0))]
    fog = dict(GROUND, axis=axis, origin_m=[150.0, -40.0, -10.37])
    db = wall_scene(500.0, fog=fog)
    for pitch in (-10.0, 0.0, 10.0):
        err, n = wall_error(db, Eyepoint.of(0.0, 0.0, 30.0, 0.0, pitch, 0.0), 500.0)
        assert n > 1000 and err < WALL_BOUND, (pitch, err)


def test_a_layer_thinner_than_the_table_spacing():
    """A 10 m thick layer (one dense plane between clear ones, 5 m spacing) seen through from
    above with a table spaced 40 m: the table entries are exact integrals, so the layer's
    whole optical depth reaches rays that cross it (no layer slips between resample planes)."""
    fog = {"spacing_m": 5.0, "extinction_per_m": [0.0, 0.0, 0.0, 0.2, 0.0, 0.0],
           "table_spacing_m": 40.0, "colour": FOG}
    db = wall_scene(400.0, fog=fog)
    eye = Eyepoint.of(0.0, 0.0, 200.0, 0.0, -30.0, 0.0)
    img = render_frame(db, SMALL, eye, RenderOptions(samples="centre"))
    view = make_view(SMALL, eye)
    dirs = pixel_rays(view)
    rng = 400.0 / dirs[..., 1]
    below = 200.0 + dirs[..., 2] * rng < 0.0  # wall points below the layer (z 10..20 m)
    assert below.sum() > 500
    # Through the whole layer: tau = 0.2 * 5 m (the triangle's area) / |cos| exactly.
    tau = 0.2 * 5.0 / np.abs(dirs[..., 2][below])
    t = np.exp(-tau)[:, None]
    want = t * linear(WALL) + (1 - t) * linear(FOG)
    assert np.abs(img.rgb[below] - want).max() < 1e-5


def test_a_thousand_kilometres_from_the_origin():
    """The eye, the wall and the fog origin 1000 km out: the same picture as at the origin
    (the eye's axis position is taken in float64)."""
    far = (1.0e6, -1.0e6, 0.0)
    fog_far = dict(GROUND, origin_m=list(far))
    near = render_frame(wall_scene(600.0), SMALL, Eyepoint.of(0.0, 0.0, 30.0, 0.0, -5.0, 0.0),
                        RenderOptions(samples="rgss4"))
    away = render_frame(wall_scene(600.0, shift=far, fog=fog_far), SMALL,
                        Eyepoint.of(far[0], far[1], 30.0, 0.0, -5.0, 0.0), RenderOptions(samples="rgss4"))
    assert np.abs(near.rgb - away.rgb).max() < 1e-5


def test_sky_above_the_fog_and_earth_below():
    """A fog-only scene: the sky (range infinite) through fog that ends in clear air keeps
    exp(-I / sin(elevation)) of its colour; the earth plane below is fogged by its range."""
    db = scene(sky=SKY, earth=EARTH, fog=GROUND)
    for height, pitch in ((10.0, 0.0), (40.0, 30.0), (40.0, -30.0), (200.0, -60.0),
                          (30.0, 90.0), (30.0, -90.0)):
        eye = Eyepoint.of(0.0, 0.0, height, 0.0, pitch, 0.0)
        view = make_view(SMALL, eye)
        bg = render_terrain(db, view, CENTRE)
        dirs = pixel_rays(view)
        up = dirs[..., 2] > 0.02
        down = dirs[..., 2] < -0.02
        pos = np.array([0.0, 0.0, height])
        if up.any():
            want = expected(db.fog, pos, dirs[up], np.full(up.sum(), 1e7), linear(SKY))
            assert np.abs(bg.rgb[up] - want).max() < WALL_BOUND, (height, pitch)
        if down.any():
            rng = height / -dirs[..., 2][down]
            want = expected(db.fog, pos, dirs[down], rng, linear(EARTH))
            assert np.abs(bg.rgb[down] - want).max() < WALL_BOUND, (height, pitch)
        assert np.isfinite(bg.rgb).all()


def test_sky_where_the_fog_never_ends_is_fog():
    """An overcast that goes on upwards for ever (the top plane is foggy): every sky ray meets
    infinite optical depth, while level rays below the deck see their finite range."""
    deck = {"spacing_m": 100.0, "extinction_per_m": [0.0, 0.0, 0.01], "colour": FOG,
            "origin_m": [0.0, 0.0, 200.0]}
    db = scene(sky=SKY, earth=EARTH, fog=deck)
    bg = render_terrain(db, make_view(SMALL, Eyepoint.of(0.0, 0.0, 50.0, 0.0, 20.0, 0.0)),
                        CENTRE)
    dirs = pixel_rays(make_view(SMALL, Eyepoint.of(0.0, 0.0, 50.0, 0.0, 20.0, 0.0)))
    up = dirs[..., 2] > 1e-3
    assert up.sum() > 1000
    assert np.abs(bg.rgb[up] - linear(FOG)).max() < 1e-6


def test_rays_parallel_to_the_strata_are_continuous():
    """Level rays (d = 0 along the axis) take the extinction at the eye: across the horizon
    row the wall's colour changes smoothly, with no NaN and no jump."""
    db = wall_scene(800.0)
    eye = Eyepoint.of(0.0, 0.0, 30.0, 0.0, 0.0, 0.0)
    tall = ChannelSpec.symmetric("t", 8, 2001, 0.2, 20.0)  # rows 0.01 degree apart
    img = render_frame(db, tall, eye, RenderOptions(samples="centre"))
    col = img.rgb[:, 4, 0]
    assert np.isfinite(img.rgb).all()
    assert np.abs(np.diff(col)).max() < 2e-3
    # The middle row looks level: sigma at 30 m is 0.012 (linear between 0.02 at 20 m and
    # 0.004 at 40 m), so T = exp(-0.012 * 800).
    t = math.exp(-0.012 * 800.0)
    want = t * linear(WALL)[0] + (1 - t) * linear(FOG)[0]
    assert col[1000] == pytest.approx(want, abs=2e-4)


@pytest.mark.parametrize("pitch, roll", [(90.0, 0.0), (-90.0, 0.0), (0.0, 180.0), (45.0, 180.0)])
def test_extreme_attitudes_stay_finite(pitch, roll):
    fog = dict(GROUND, axis=[0.3, -0.2, 0.93], origin_m=[20.0, 30.0, 25.0])
    db = wall_scene(300.0, fog=fog)
    eye = Eyepoint.of(0.0, 0.0, 45.0, 30.0, pitch, roll)
    for filt in ("box", "tent"):
        img = render_frame(db, SMALL, eye, RenderOptions(samples="rgss4", filter=filt))
        assert np.isfinite(img.rgb).all() and img.rgb.min() >= 0.0 and img.rgb.max() <= 1.0


def test_the_resolve_path_agrees_with_the_fused_path():
    """The box-filtered fused visibility and the sample-store resolve shade the same fog."""
    db = wall_scene(500.0, fog=dict(GROUND, axis=[0.2, 0.1, 1.0]))
    eye = Eyepoint.of(0.0, 0.0, 25.0, 10.0, -5.0, 8.0)
    fused = render_frame(db, SMALL, eye, RenderOptions(samples="rgss4"))
    trace: dict = {}
    stored = render_frame(db, SMALL, eye, RenderOptions(samples="rgss4"), trace=trace)
    assert np.abs(fused.rgb - stored.rgb).max() < 1e-5


def test_terrain_is_fogged_by_its_range():
    """A flat terrain field: every texel is fogged by its range along its own ray, so the
    fogged picture is the clear one taken towards the fog colour by exp(-tau(range))."""
    from channel_worker.testing.terrain_reference import single_level_database

    h, c = flat_nodes(64, height=0.0)
    t = single_level_database(h, c, 20.0, np.array([-640.0, -640.0, 0.0]), page_size=16)
    clear = scene(terrain=t, sky=SKY, earth=EARTH)
    fogged = scene(terrain=t, sky=SKY, earth=EARTH, fog=GROUND)
    eye = Eyepoint.of(0.0, 0.0, 35.0, 20.0, -25.0, 0.0)
    view = make_view(SMALL, eye)
    a = render_terrain(clear, view, CENTRE)
    b = render_terrain(fogged, view, CENTRE)
    dirs = pixel_rays(view)
    covered = (a.inv_z > 0).all(axis=2) & np.isfinite(a.range_m) & (dirs[..., 2] < -0.05)
    assert covered.sum() > 2000
    tau = np.array([exact_depth(fogged.fog, np.array([0.0, 0.0, 35.0]), d, r)
                    for d, r in zip(dirs[covered], a.range_m[covered], strict=True)])
    t = np.exp(-tau)[:, None]
    want = t * a.rgb[covered] + (1 - t) * linear(FOG)
    # A terrain pixel is fogged at the range of its line's point (within half a pixel of its
    # centre).
    assert np.abs(b.rgb[covered] - want).max() < 0.001
    # And it is fog, not nothing: the far field differs from the clear one.
    assert np.abs(b.rgb[covered] - a.rgb[covered]).max() > 0.2


def test_a_scene_without_fog_pays_nothing():
    db = wall_scene(600.0)
    plain = dataclasses.replace(db, fog=None)
    eye = Eyepoint.of(0.0, 0.0, 30.0, 0.0, 0.0, 0.0)
    trace: dict = {}
    render_frame(plain, SMALL, eye, trace=trace)
    assert not trace["background"].on  # no background stage at all
    assert not trace["background"].air.any()  # clear air
    render_frame(db, SMALL, eye, trace=trace)
    assert trace["background"].on and trace["background"].air[F_ON] != 0.0


def test_a_coarsened_table_is_reported():
    db = wall_scene(600.0, fog={"spacing_m": 1.0, "extinction_per_m": [0.01, 0.0], "colour": FOG})
    near, far = FrameReport(), FrameReport()
    render_frame(db, SMALL, Eyepoint.of(0.0, 0.0, 30.0, 0.0, 0.0, 0.0), report=near)
    render_frame(db, SMALL, Eyepoint.of(0.0, 0.0, 20000.0, 0.0, -10.0, 0.0), report=far)
    assert near.counters["fog_table_coarsened"] == 0 and far.counters["fog_table_coarsened"] == 1


def test_the_scanline_renderer_refuses_fog():
    with pytest.raises(ValueError, match="fog"):
        render_frame(wall_scene(600.0), SMALL, Eyepoint.of(0.0, 0.0, 30.0, 0.0, 0.0, 0.0),
                     RenderOptions(samples="centre", renderer="scanline"))


def _doc(fog):
    return {"format": "ig-scene/1", "sky": {"colour": SKY}, "earth": {"colour": EARTH},
            "models": {}, "instances": [], "fog": fog}


def test_scene_fog_key():
    db = parse_scene(_doc({"spacing_m": 25.0, "visibility_m": [500.0, 2000.0, None],
                           "colour": FOG, "axis": [0.0, 0.0, 2.0], "table_spacing_m": 5.0}))
    f = db.fog
    assert np.allclose(f.axis, [0.0, 0.0, 1.0])
    assert f.extinction == pytest.approx([-math.log(0.02) / 500.0, -math.log(0.02) / 2000.0, 0.0])
    assert f.spacing_m == 25.0 and f.table_spacing_m == 5.0
    assert np.allclose(f.colour, linear(FOG))
    one = parse_scene(_doc({"extinction_per_m": [0.001], "colour": FOG})).fog
    assert one.extinction.tolist() == [0.001]


@pytest.mark.parametrize("fog, field, value", [
    ({"extinction_per_m": [0.01, -0.5], "spacing_m": 10.0, "colour": FOG},
     "fog.extinction_per_m[1]", "-0.5"),
    ({"extinction_per_m": [0.01, 0.02], "colour": FOG}, "fog.spacing_m", "2 sample planes"),
    ({"extinction_per_m": [0.01], "visibility_m": [100.0], "colour": FOG}, "fog", "exactly one"),
    ({"colour": FOG}, "fog", "exactly one"),
    ({"extinction_per_m": [], "colour": FOG}, "fog.extinction_per_m", "[]"),
    ({"extinction_per_m": [0.01], "colour": FOG, "axis": [0.0, 0.0, 0.0]}, "fog.axis", "[0.0"),
    ({"extinction_per_m": [0.01, 0.0], "spacing_m": 0.0, "colour": FOG}, "fog.spacing_m", "0"),
    ({"visibility_m": [0.0], "colour": FOG}, "fog.visibility_m[0]", "0"),
    ({"extinction_per_m": [float("nan")], "colour": FOG}, "fog.extinction_per_m[0]", "nan"),
    ({"extinction_per_m": [0.01], "colour": "grey"}, "fog.colour", "grey"),
    ({"extinction_per_m": [0.01], "colour": FOG, "density": 3}, "fog", "density"),
    ({"extinction_per_m": [0.01], "colour": FOG, "table_spacing_m": -1.0},
     "fog.table_spacing_m", "-1"),
])
def test_scene_fog_errors_name_the_field_and_value(fog, field, value):
    with pytest.raises(SceneError) as err:
        parse_scene(_doc(fog))
    assert field in str(err.value) and value in str(err.value), str(err.value)


@pytest.mark.parametrize("pitch, roll", [(0.0, 0.0), (-35.0, 20.0), (60.0, 180.0)])
def test_sky_and_earth_alike_with_and_without_terrain(pitch, roll):
    """Fog alone paints the sky and earth with its own per-pixel kernel; under terrain the cast
    paints them. Both are the same fog: a terrain out of sight (behind the eye) changes
    nothing in front."""
    from channel_worker.testing.terrain_reference import single_level_database

    h, c = flat_nodes(4)
    behind = single_level_database(h, c, 10.0, np.array([-20.0, -900.0, 0.0]), page_size=4)
    fog = dict(GROUND, axis=[0.3, -0.2, 0.93], origin_m=[20.0, 30.0, 5.0])
    bare = scene(sky=SKY, earth=EARTH, fog=fog)
    with_terrain = scene(terrain=behind, sky=SKY, earth=EARTH, fog=fog)
    view = make_view(SMALL, Eyepoint.of(0.0, 0.0, 45.0, 0.0, pitch, roll))
    a = render_terrain(bare, view, RGSS4)
    b = render_terrain(with_terrain, view, RGSS4)
    assert not (b.inv_z > 0).any()  # the terrain is out of sight
    assert np.abs(a.rgb - b.rgb).max() < 1e-5
    assert np.array_equal(np.isinf(a.range_m), np.isinf(b.range_m))
    finite = np.isfinite(a.range_m)
    assert np.allclose(a.range_m[finite], b.range_m[finite], rtol=1e-5)


def test_dense_fog_stops_the_terrain_scan_where_all_is_fog():
    """An eye in dense ground fog over a 5 km field: the scan stops where even the clearest
    path to the terrain is past optical depth 7 (about 350 m here), visiting far fewer voxels,
    and the picture is what the whole scan gives to within the 0.1 % of colour left there."""
    from channel_worker.pipeline.background import terrain as terrain_stage
    from channel_worker.pipeline.fog.fog import average_floor
    from channel_worker.testing.terrain_reference import single_level_database

    h, c = flat_nodes(256, height=0.0)
    t = single_level_database(h, c, 20.0, np.array([-2560.0, -2560.0, 0.0]), page_size=32)
    db = scene(terrain=t, sky=SKY, earth=EARTH, fog=GROUND)
    eye = Eyepoint.of(0.0, 0.0, 35.0, 20.0, -4.0, 0.0)
    view = make_view(SMALL, eye)
    floor = average_floor(db.fog, np.array([0.0, 0.0, 35.0]), -35.0, -35.0)
    # The floor is the exact average from 35 m down to the ground (all terrain is at 0 m).
    want = exact_depth(db.fog, np.array([0.0, 0.0, 35.0]), np.array([0.0, 0.0, -1.0]), 35.0) / 35.0
    assert floor == pytest.approx(want, rel=1e-6)
    cut = render_terrain(db, view, CENTRE)
    original = terrain_stage.average_floor
    terrain_stage.average_floor = lambda *args: 0.0  # no bound: the whole database
    try:
        whole = render_terrain(db, view, CENTRE)
    finally:
        terrain_stage.average_floor = original
    # Measured: 1760 voxels against 17013, colours within 9e-5.
    assert cut.stats["terrain_voxels"] < 0.2 * whole.stats["terrain_voxels"]
    assert np.abs(cut.rgb - whole.rgb).max() < 1e-3


def test_average_floor_is_a_lower_bound():
    """On random structures, eyes and bands: never above the exact average at any d."""
    from channel_worker.pipeline.fog.fog import average_floor
    from channel_worker.pipeline.scene.atmosphere import Fog

    rng = np.random.default_rng(3)
    for _ in range(40):
        n = int(rng.integers(1, 12))
        ext = rng.uniform(0.0, 0.05, n) * (rng.uniform(size=n) < 0.7)
        fog = Fog(axis=rng.normal(size=3), origin=rng.normal(size=3) * 100.0,
                  spacing_m=float(rng.uniform(2.0, 50.0)), extinction=ext,
                  colour=np.ones(3, np.float32))
        eye = rng.normal(size=3) * 200.0
        lo, hi = np.sort(rng.uniform(-600.0, 600.0, 2))
        floor = average_floor(fog, eye, float(lo), float(hi))
        for d in np.linspace(lo, hi, 301):
            if abs(d) < 1e-9:
                continue
            direction = fog.axis * np.sign(d)
            exact = exact_depth(fog, eye, direction, abs(d)) / abs(d)
            assert floor <= exact * (1 + 1e-9) + 1e-15, (floor, exact, d)
