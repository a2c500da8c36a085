"""Polygons merged with the terrain and haze in render_frame: the terrain is every sample's
nearest opaque feature to begin with (pushed back by the scene's polygon margin), so polygons
behind it are hidden, polygons lying on it win, translucent ones blend over it, and haze
covers polygons by their range.

Scenes are flat-lit (ambient 1), so a face's colour is its scene colour exactly.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from channel_worker.pipeline.background.haze import haze_amount_py
from channel_worker.pipeline.geometry.view import make_view, screen_mapping
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
from channel_worker.testing.terrain_reference import single_level_database
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions
from services.rig.report import FrameReport

from ..conftest import box_model
from ..terrain_fixtures import RGSS4, flat_nodes, linear, render_terrain, scene

CHANNEL = ChannelSpec.symmetric("c", 160, 120, 60.0)
NARROW = ChannelSpec.symmetric("n", 160, 120, 10.0)
RUNWAY = "#303030"
MAGENTA = "#ff00ff"


def quad(w: float, length: float, *, z: float = 0.0, colour: str = RUNWAY,
         opacity: float = 1.0) -> dict:
    """A horizontal w x length rectangle facing up, centred on the model origin."""
    x, y = w / 2.0, length / 2.0
    return {"vertices": [[-x, -y, z], [x, -y, z], [x, y, z], [-x, y, z]],
            "faces": [{"indices": [0, 1, 2, 3], "colour": colour, "opacity": opacity}]}


def wall(w: float, h: float, *, colour: str, opacity: float = 1.0) -> dict:
    """A vertical w x h rectangle in the x-z plane facing south (-y), base on the origin."""
    x = w / 2.0
    return {"vertices": [[-x, 0.0, 0.0], [x, 0.0, 0.0], [x, 0.0, h], [-x, 0.0, h]],
            "faces": [{"indices": [0, 1, 2, 3], "colour": colour, "opacity": opacity}]}


def pad(height: float = 0.0, *, n: int = 100, spacing: float = 30.0):
    """A flat terrain pad 3 km square around the runway (x -1500..1500, y -500..2500)."""
    h, c = flat_nodes(n, height)
    return single_level_database(h, c, spacing, np.array([-1500.0, -500.0, 0.0]), page_size=32)


def hill(peak: float = 120.0):
    """Flat ground with one round hill `peak` metres high centred on (0, 1000)."""
    n, s = 100, 30.0
    y, x = np.mgrid[0:n + 1, 0:n + 1] * s
    x, y = x - 1500.0, y - 500.0
    h = (peak * np.exp(-(x ** 2 + (y - 1000.0) ** 2) / (2.0 * 200.0 ** 2))).astype(np.float32)
    c = np.zeros((n + 1, n + 1, 3), np.uint8)
    c[...] = (90, 140, 60)
    return single_level_database(h, c, s, np.array([-1500.0, -500.0, 0.0]), page_size=32)


def fully_covered(img, colour: str) -> np.ndarray:
    """Pixels of a render whose every sample shows an opaque face of this colour."""
    return np.all(np.abs(img.rgb - linear(colour)) < 1e-6, axis=2)


# ----------------------------------------------------------------------------- lying on terrain

RUNWAY_SCENE = {"models": {"rwy": quad(45.0, 2400.0)},
                "instances": [{"model": "rwy", "position": [0.0, 1100.0, 0.0]}]}

@pytest.mark.parametrize("channel", [NARROW, CHANNEL], ids=["10deg", "60deg"])
@pytest.mark.parametrize("height, pitch", [(3.0, -1.0), (20.0, -5.0)])
def test_a_runway_lying_on_the_terrain_is_seen(channel, height, pitch):
    """Every pixel the runway covers entirely without terrain shows the runway with it, out to
    the runway's far end 2.3 km away; where the runway is not, the terrain is."""
    with_t = scene(terrain=pad(), sky=MAGENTA, earth=MAGENTA, **RUNWAY_SCENE)
    without = scene(sky=MAGENTA, earth=MAGENTA, **RUNWAY_SCENE)
    eye = Eyepoint.of(0.0, -50.0, height, 0.0, pitch, 0.0)
    a, b = render_frame(with_t, channel, eye), render_frame(without, channel, eye)
    runway = fully_covered(b, RUNWAY)
    assert runway.sum() > 1000 and b.range_m[runway].max() > 300.0
    err = np.abs(a.rgb - linear(RUNWAY)).max(axis=2)[runway]
    assert err.max() <= 1e-5, f"{int((err > 1e-5).sum())} runway pixels show terrain ({err.max()})"
    bare = np.all(np.abs(b.rgb - linear(MAGENTA)) < 1e-6, axis=2)  # no polygon sample at all
    ground = render_terrain(with_t, make_view(channel, eye), RGSS4)
    assert np.allclose(a.rgb[bare], ground.rgb[bare], atol=1e-5)


@pytest.mark.parametrize("offset, seen", [(0.5, True), (-0.5, True), (-3.0, False)])
def test_the_polygon_margin_decides_what_lies_on_the_terrain(offset, seen):
    """The runway `offset` metres above (+) or below (-) the pad: within the scene's margin
    (1 m) it is drawn over the pad, 3 m under it is hidden by it."""
    models = {"rwy": quad(45.0, 2400.0, z=offset)}
    db = scene(terrain=pad(), models=models, margin_m=1.0,
               instances=[{"model": "rwy", "position": [0.0, 1100.0, 0.0]}])
    eye = Eyepoint.of(0.0, -50.0, 20.0, 0.0, -5.0, 0.0)
    img = render_frame(db, NARROW, eye)
    bare = render_frame(scene(models=models, sky=MAGENTA, earth=MAGENTA,
                              instances=[{"model": "rwy", "position": [0.0, 1100.0, 0.0]}]),
                        NARROW, eye)
    runway = fully_covered(bare, RUNWAY)
    assert runway.sum() > 1000
    shows = np.abs(img.rgb - linear(RUNWAY)).max(axis=2)[runway] <= 1e-5
    assert shows.all() if seen else not shows.any(), shows.mean()


# ----------------------------------------------------------------------------- hidden and seen


def test_a_box_behind_a_hill_is_hidden_and_one_before_it_is_seen():
    red, blue = "#ff0000", "#0000ff"
    # An 80 m high box 600 m behind the 120 m hill (its top edge 50 m below the line of sight
    # over the hill), and a 40 m box before it.
    models = {"behind": box_model(200.0, 60.0, 80.0, red),
              "before": box_model(40.0, 40.0, 40.0, blue)}
    instances = [{"model": "behind", "position": [0.0, 1600.0, 0.0]},
                 {"model": "before", "position": [60.0, 400.0, 0.0]}]
    eye = Eyepoint.of(0.0, -300.0, 20.0, 0.0, 2.0, 0.0)
    img = render_frame(scene(terrain=hill(), models=models, instances=instances), CHANNEL, eye)
    bare = render_frame(scene(models=models, instances=instances, sky=MAGENTA, earth=MAGENTA),
                        CHANNEL, eye)
    assert fully_covered(bare, red).sum() > 20  # the far box is in view without the hill
    reddish = (img.rgb[..., 0] > 0.5) & (img.rgb[..., 2] < 0.2)
    assert not reddish.any(), int(reddish.sum())
    near = fully_covered(bare, blue)
    assert near.sum() > 20
    assert fully_covered(img, blue)[near].all()


def test_a_translucent_polygon_blends_over_the_terrain():
    glass = "#2040ff"
    models = {"glass": wall(200.0, 150.0, colour=glass, opacity=0.4)}
    instances = [{"model": "glass", "position": [0.0, 300.0, 0.0]}]
    db = scene(terrain=hill(), models=models, instances=instances)
    eye = Eyepoint.of(0.0, -300.0, 30.0, 0.0, 0.0, 0.0)
    img = render_frame(db, CHANNEL, eye)
    ground = render_terrain(db, make_view(CHANNEL, eye), RGSS4)
    bare = render_frame(scene(models={"glass": wall(200.0, 150.0, colour=glass)},
                              instances=instances, sky=MAGENTA, earth=MAGENTA), CHANNEL, eye)
    inside = fully_covered(bare, glass)
    # Pixels behind the glass whose samples all see terrain (not the sky above the hill).
    covered = inside & np.all(ground.inv_z > 0, axis=2)
    assert covered.sum() > 200
    want = 0.4 * linear(glass) + 0.6 * ground.rgb[covered]
    assert np.allclose(img.rgb[covered], want, atol=1e-5)


# ----------------------------------------------------------------------------- ranges and paths


def test_range_is_the_terrains_or_the_polygons():
    red = "#ff0000"
    models = {"box": box_model(40.0, 40.0, 40.0, red)}
    instances = [{"model": "box", "position": [60.0, 400.0, 0.0]}]
    db = scene(terrain=hill(), models=models, instances=instances)
    eye = Eyepoint.of(0.0, -300.0, 20.0, 0.0, -2.0, 0.0)
    img = render_frame(db, CHANNEL, eye)
    ground = render_terrain(db, make_view(CHANNEL, eye), RGSS4)
    bare = render_frame(scene(models=models, instances=instances, sky=MAGENTA, earth=MAGENTA),
                        CHANNEL, eye)
    box = fully_covered(bare, red)
    no_polygon = np.all(np.abs(bare.rgb - linear(MAGENTA)) < 1e-6, axis=2)
    assert box.sum() > 20 and no_polygon.sum() > 10000
    # Only terrain (or sky): the terrain stage's range, +inf for sky.
    assert np.array_equal(np.isinf(img.range_m[no_polygon]), np.isinf(ground.range_m[no_polygon]))
    fin = no_polygon & np.isfinite(ground.range_m)
    assert np.allclose(img.range_m[fin], ground.range_m[fin], rtol=1e-5)
    # The box: its own range (nearest sample), as without terrain.
    assert np.allclose(img.range_m[box], bare.range_m[box], rtol=1e-5)


@pytest.mark.parametrize("haze", [None, {"visibility_m": 3000.0, "colour": "#c0c8d0"}])
def test_the_fused_and_the_resolve_paths_agree(haze):
    """The default path (box filter, pixels straight from the sub-areas) and the sample store +
    resolve path (taken when a trace is asked for, same box filter) give the same image."""
    models = {"box": box_model(20.0, 20.0, 20.0, "#ff0000"),
              "glass": wall(120.0, 60.0, colour="#2040ff", opacity=0.5),
              "rwy": quad(45.0, 1000.0)}
    instances = [{"model": "box", "position": [30.0, 400.0, 0.0]},
                 {"model": "glass", "position": [-60.0, 250.0, 0.0]},
                 {"model": "box", "position": [0.0, 1600.0, 0.0]},
                 {"model": "rwy", "position": [0.0, 300.0, 0.0]}]
    db = scene(terrain=hill(), models=models, instances=instances, haze=haze)
    for eye in (Eyepoint.of(0.0, -300.0, 20.0, 0.0, -2.0, 0.0),
                Eyepoint.of(0.0, -300.0, 60.0, 10.0, -10.0, 30.0)):
        fused = render_frame(db, CHANNEL, eye)
        trace: dict = {}
        stored = render_frame(db, CHANNEL, eye, trace=trace)
        assert trace["background"].on
        assert np.allclose(fused.rgb, stored.rgb, atol=1e-5), np.abs(fused.rgb - stored.rgb).max()
        assert np.array_equal(np.isinf(fused.range_m), np.isinf(stored.range_m))
        fin = np.isfinite(fused.range_m)
        assert np.allclose(fused.range_m[fin], stored.range_m[fin], rtol=1e-5)


# ----------------------------------------------------------------------------- haze


def test_haze_turns_far_polygons_to_the_haze_colour():
    """Three red walls at 0.3, 3 and 12 km under haze of 2 km visibility (homogeneous, so H
    depends on range only): each wall's pixel is red (1 - H) + haze H, H from haze_amount."""
    haze = {"visibility_m": 2000.0, "colour": "#c0c8d0", "scale_height_m": None}
    red = "#ff0000"
    distances = (300.0, 3000.0, 12000.0)
    models = {f"w{i}": wall(0.2 * d, 0.1 * d, colour=red) for i, d in enumerate(distances)}
    instances = [{"model": f"w{i}", "position": [(i - 1) * 0.3 * d, d, 0.0]}
                 for i, d in enumerate(distances)]
    db = scene(haze=haze, models=models, instances=instances)
    eye = Eyepoint.of(0.0, 0.0, 5.0, 0.0, 0.0, 0.0)
    img = render_frame(db, CHANNEL, eye)
    bare = render_frame(scene(models=models, instances=instances, sky=MAGENTA, earth=MAGENTA),
                        CHANNEL, eye)
    view = make_view(CHANNEL, eye)
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    haze_colour = linear("#c0c8d0")
    gaps = []
    for d in distances:
        walls = fully_covered(bare, red) & (np.abs(bare.range_m - d) < 0.05 * d)
        assert walls.sum() >= 4, d
        y, x = np.argwhere(walls)[0]
        # The pixel centre's ray: its range to the wall plane y = d and its elevation sine.
        ray = np.array([(x + 0.5 - sx_off) / sx_scale, (y + 0.5 - sy_off) / sy_scale, 1.0])
        ray = ray @ view.world_to_eye
        ray /= np.linalg.norm(ray)
        h = haze_amount_py(db.haze, 5.0, d / ray[1], ray[2])
        want = linear(red) * (1.0 - h) + haze_colour * h
        assert np.allclose(img.rgb[y, x], want, atol=2e-3), (d, img.rgb[y, x], want)
        gaps.append(float(np.abs(img.rgb[walls] - haze_colour).max()))
    assert gaps[0] > gaps[1] > gaps[2], gaps
    assert gaps[0] > 0.5 and gaps[2] < 0.02, gaps  # H(12 km) = 1 - 2**-6 = 0.984


def test_haze_only_runs_the_terrain_stage_for_the_sky():
    db = scene(haze={"visibility_m": 2000.0, "colour": "#c0c8d0"}, sky="#2050c0", earth="#406020")
    trace: dict = {}
    img = render_frame(db, CHANNEL, Eyepoint.of(0.0, 0.0, 100.0, 0.0, 0.0, 0.0), trace=trace)
    assert trace["background"].on
    assert np.isfinite(img.rgb).all()


# ----------------------------------------------------------------------------- without terrain


def test_a_scene_without_terrain_or_haze_skips_the_stage():
    db = load_scene(bundled_scene_path())
    assert db.terrain is None and db.haze is None
    eye = Eyepoint.of(0.0, -200.0, 30.0, 0.0, -3.0, 0.0)
    trace: dict = {}
    report = FrameReport()
    render_frame(db, CHANNEL, eye, trace=trace, report=report)
    assert not trace["background"].on
    img = render_frame(db, CHANNEL, eye)
    assert not any(k.startswith("terrain") for k in report.counters)
    assert "background" not in report.stage_seconds
    explicit = render_frame(dataclasses.replace(db, terrain=None, haze=None), CHANNEL, eye)
    assert np.array_equal(img.rgb, explicit.rgb)
    assert np.array_equal(img.range_m, explicit.range_m)
    # The resolve path agrees too (no Background anywhere).
    trace: dict = {}
    stored = render_frame(db, CHANNEL, eye, trace=trace)
    assert not trace["background"].on
    assert np.allclose(stored.rgb, img.rgb, atol=1e-6)


@pytest.mark.parametrize("what", ["terrain", "haze"])
def test_the_scanline_renderer_refuses_terrain_and_haze(what):
    db = (scene(terrain=pad()) if what == "terrain"
          else scene(haze={"visibility_m": 2000.0, "colour": "#c0c8d0"}))
    with pytest.raises(ValueError, match="scanline"):
        render_frame(db, CHANNEL, Eyepoint.of(0.0, -50.0, 20.0, 0.0, -5.0, 0.0),
                     RenderOptions(renderer="scanline", samples="centre"))


def test_terrain_margin_grows_with_grazing():
    """Sanity of the margin's conversion to range: at every sample the pushed-back terrain
    1/z stays positive and below the flat pad's own exact 1/z (no sign flip near the
    horizon), and the push is margin / sin(depression) of range."""
    db = scene(terrain=pad(), margin_m=1.0)
    view = make_view(CHANNEL, Eyepoint.of(0.0, -50.0, 3.0, 0.0, 0.0, 0.0))
    bg = render_terrain(db, view, RGSS4)
    seen = bg.inv_z > 0
    assert seen.any()
    # The pad is the plane z = 0 under an eye 3 m up: along the eye ray (tx, ty, 1), whose
    # world z component is ez < 0, the depth is 3 / -ez, so 1/z = -ez / 3.
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    tx = (np.arange(view.width)[None, :, None] + RGSS4[None, None, :, 0] - sx_off) / sx_scale
    ty = (np.arange(view.height)[:, None, None] + RGSS4[None, None, :, 1] - sy_off) / sy_scale
    r0, r1, r2 = view.world_to_eye[:, 2]
    ez = r0 * tx + r1 * ty + r2
    surface = -ez / 3.0
    # Only rays that meet the plane on the pad (x -1500..1500, y -500..2500): past its far
    # edge a sample sees the edge, nearer than the plane would be.
    m = view.world_to_eye
    wx = m[0, 0] * tx + m[1, 0] * ty + m[2, 0]
    wy = m[0, 1] * tx + m[1, 1] * ty + m[2, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        on_pad = (ez < 0) & (np.abs(3.0 * wx / -ez) < 1400.0) & (-50.0 + 3.0 * wy / -ez < 2400.0)
    seen = seen & on_pad
    assert seen.sum() > 1000
    assert np.all(surface[seen] > 0.0)
    assert np.all(bg.inv_z[seen] < surface[seen])
    # Pushed back by 1 m of height: range + 1 / sin(depression), depression from ez.
    ray = np.sqrt(tx ** 2 + ty ** 2 + 1.0)
    sin_dep = np.maximum(-ez / ray, 1e-3)
    expected = ray / (ray / surface + 1.0 / sin_dep)
    near = seen & (sin_dep > 0.02)  # well below the horizon: interpolation is exact there
    np.testing.assert_allclose(bg.inv_z[near], expected[near], rtol=2e-3)
    assert math.isfinite(float(bg.inv_z.max()))
