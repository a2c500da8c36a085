"""The host's environment (CIGI) as the scene's atmosphere: visibility to haze, fog layers to
strata, cloud layers to a cloud database, the sun; cached per environment; bad values named;
and a fog layer around the eye seen in a rendered frame."""

from __future__ import annotations

import math

import numpy as np
import pytest

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.atmosphere import KOSCHMIEDER
from channel_worker.pipeline.scene.environment import (
    CLOUD_HALF_EXTENT_M,
    CLOUD_SEED_BASE,
    DEFAULT_HAZE_SCALE_HEIGHT_M,
    EnvironmentCache,
    with_environment,
)
from services.rig.environment import Environment, WeatherLayer
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

from ..conftest import box_model
from ..terrain_fixtures import HILLS_N, HILLS_ORIGIN, HILLS_SPACING, hills_db, linear, scene

FOG = "#b0b4b8"
HAZE = {"visibility_m": 9000.0, "colour": "#c4ccd6", "scale_height_m": 800.0, "base_height_m": 25.0}


def fog_layer(base, thickness, visibility, coverage=1.0, layer_id=0):
    return WeatherLayer(layer_id=layer_id, base_m=base, thickness_m=thickness, visibility_m=visibility,
                        coverage=coverage, cloud=False)


def cloud(base, thickness, visibility=40.0, coverage=0.5, layer_id=1):
    return WeatherLayer(layer_id=layer_id, base_m=base, thickness_m=thickness, visibility_m=visibility,
                        coverage=coverage, cloud=True)


def sigma_at(fog, z):
    """The strata's extinction at world height z (linear between planes, ends held)."""
    planes = fog.origin[2] + np.arange(fog.extinction.size) * fog.spacing_m
    return np.interp(z, planes, fog.extinction)


def test_visibility_becomes_the_haze_half_distance_keeping_the_scenes_haze():
    db = scene(haze=HAZE)
    out = with_environment(db, Environment(visibility_m=5000.0))
    # Koschmieder: beta = 3.912 / V; the haze's half distance is ln 2 / beta.
    assert out.haze.visibility_m == pytest.approx(math.log(2) / (KOSCHMIEDER / 5000.0))
    assert out.haze.visibility_m == pytest.approx(885.9, abs=0.1)
    assert (out.haze.scale_height_m, out.haze.base_height_m) == (800.0, 25.0)
    np.testing.assert_array_equal(out.haze.colour, db.haze.colour)
    assert db.haze.visibility_m == 9000.0  # the scene is not changed


def test_visibility_without_scene_haze_uses_the_defaults():
    out = with_environment(scene(), Environment(visibility_m=20_000.0))
    assert out.haze.scale_height_m == DEFAULT_HAZE_SCALE_HEIGHT_M
    assert out.haze.base_height_m == 0.0  # the earth plane
    assert out.haze.colour.dtype == np.float32 and out.haze.colour.shape == (3,)


def test_a_fog_layer_becomes_strata_with_its_extinction_inside_and_none_outside():
    db = scene(fog={"extinction_per_m": [0.001], "colour": FOG})
    out = with_environment(db, Environment(layers=(fog_layer(100.0, 300.0, 500.0, coverage=0.8),)))
    fog = out.fog
    np.testing.assert_allclose(fog.axis, [0, 0, 1])
    inside = KOSCHMIEDER / 500.0 * 0.8
    z_in = np.linspace(100.0 + fog.spacing_m, 400.0 - fog.spacing_m, 50)
    np.testing.assert_allclose(sigma_at(fog, z_in), inside, rtol=1e-12)
    assert fog.spacing_m <= 300.0 / 4
    z_out = np.concatenate([np.linspace(-1e4, 100.0 - fog.spacing_m, 50), np.linspace(400.0 + fog.spacing_m, 1e4, 50)])
    np.testing.assert_array_equal(sigma_at(fog, z_out), 0.0)
    # Boundaries ramp over one spacing, the layer's optical depth is exact.
    assert fog.extinction.sum() * fog.spacing_m == pytest.approx(inside * 300.0, rel=1e-12)
    np.testing.assert_array_equal(fog.colour, db.fog.colour)  # the scene's fog colour
    assert out.clouds is db.clouds and out.haze is db.haze


def test_two_fog_layers_thin_and_far_apart_keep_each_layers_depth():
    layers = (fog_layer(0.0, 20.0, 200.0), fog_layer(3000.0, 600.0, 2000.0, layer_id=4))
    fog = with_environment(scene(), Environment(layers=layers)).fog
    assert fog.spacing_m == pytest.approx(5.0)
    assert sigma_at(fog, 10.0) == pytest.approx(KOSCHMIEDER / 200.0)
    assert sigma_at(fog, 3300.0) == pytest.approx(KOSCHMIEDER / 2000.0)
    assert sigma_at(fog, 1500.0) == 0.0
    depth = fog.extinction.sum() * fog.spacing_m
    assert depth == pytest.approx(KOSCHMIEDER / 200.0 * 20.0 + KOSCHMIEDER / 2000.0 * 600.0, rel=1e-12)
    np.testing.assert_allclose(fog.colour, linear("#c8c8c8"), atol=1e-6)  # neutral grey default


def test_fog_layers_holding_nothing_clear_the_scenes_fog_and_no_fog_layer_keeps_it():
    db = scene(fog={"extinction_per_m": [0.001], "colour": FOG})
    assert with_environment(db, Environment(layers=(fog_layer(0.0, 100.0, 500.0, coverage=0.0),))).fog is None
    assert with_environment(db, Environment(layers=(cloud(1000.0, 300.0),))).fog is db.fog


def test_the_plane_count_is_bounded():
    from channel_worker.pipeline.scene.atmosphere import MAX_FOG_PLANES
    layers = (fog_layer(0.0, 0.01, 100.0), fog_layer(5e6, 1.0, 100.0, layer_id=2))
    fog = with_environment(scene(), Environment(layers=layers)).fog
    assert fog.extinction.size <= MAX_FOG_PLANES
    assert fog.extinction[0] == 0.0 and fog.extinction[-1] == 0.0
    assert fog.extinction.sum() * fog.spacing_m == pytest.approx(KOSCHMIEDER / 100.0 * 1.01, rel=1e-9)


def test_a_cloud_layer_becomes_clouds_at_its_base_over_the_default_extent():
    layer = cloud(1500.0, 400.0, visibility=50.0, coverage=0.4, layer_id=2)
    out = with_environment(scene(), Environment(layers=(layer,)))
    clouds = out.clouds
    np.testing.assert_array_equal(clouds.origin, [-CLOUD_HALF_EXTENT_M, -CLOUD_HALF_EXTENT_M])
    cloudy = clouds.density > 0
    assert 0.3 < cloudy.mean() < 0.5  # about the coverage
    assert clouds.base_m[cloudy].min() == pytest.approx(1500.0)
    assert clouds.top_m.max() == pytest.approx(1900.0)
    assert clouds.density.max() == pytest.approx(KOSCHMIEDER / 50.0, rel=1e-6)
    assert out.fog is None  # the scene has none, and no fog layer came
    # The same layer gives the same clouds (its seed is fixed by its id), another id others.
    again = with_environment(scene(), Environment(layers=(layer,))).clouds
    np.testing.assert_array_equal(again.density, clouds.density)
    other = with_environment(scene(), Environment(layers=(cloud(1500.0, 400.0, 50.0, 0.4, layer_id=3),))).clouds
    assert not np.array_equal(other.density, clouds.density)
    assert CLOUD_SEED_BASE >= 0


def test_the_lowest_cloud_layer_that_shows_is_drawn_over_the_terrain():
    db = scene(terrain=hills_db())
    layers = (cloud(3000.0, 500.0, layer_id=1), cloud(800.0, 0.0, layer_id=2),
              cloud(2000.0, 300.0, layer_id=3), cloud(500.0, 300.0, coverage=0.0, layer_id=4))
    clouds = with_environment(db, Environment(layers=layers)).clouds
    assert clouds.base_m[clouds.density > 0].min() == pytest.approx(2000.0)
    np.testing.assert_array_equal(clouds.origin, HILLS_ORIGIN[:2])
    size = HILLS_N * HILLS_SPACING
    assert clouds.origin[0] + (clouds.density.shape[1] - 1) * clouds.cell_m >= size + HILLS_ORIGIN[0]


def test_the_sun_is_set_and_an_empty_environment_changes_nothing():
    db = scene()
    s = math.sqrt(0.5)
    out = with_environment(db, Environment(sun=(0.0, s, s)))
    np.testing.assert_allclose(out.sun, [0.0, s, s])
    assert out.models is db.models and out.faces is db.faces  # geometry shared
    assert with_environment(db, Environment()) is db


def test_the_cache_returns_the_same_database_for_an_unchanged_environment():
    cache = EnvironmentCache(size=2)
    db = scene()
    a = Environment(visibility_m=3000.0, layers=(fog_layer(0.0, 50.0, 200.0),))
    b = Environment(visibility_m=8000.0)
    first = cache.get(db, a)
    assert cache.get(db, Environment(visibility_m=3000.0, layers=(fog_layer(0.0, 50.0, 200.0),))) is first
    second = cache.get(db, b)
    assert cache.get(db, a) is first and cache.get(db, b) is second  # both remembered
    cache.get(db, Environment(visibility_m=1.0))  # a third evicts the least recently used (a)
    assert cache.get(db, b) is second and cache.get(db, a) is not first
    other = scene()
    assert cache.get(other, b) is not second  # another database starts afresh


@pytest.mark.parametrize(("env", "field"), [
    (Environment(visibility_m=0.0), r"environment\.visibility_m: 0\.0"),
    (Environment(visibility_m=1e-320), r"environment\.visibility_m: 1e-320"),
    (Environment(layers=(fog_layer(0.0, 10.0, -5.0),)), r"environment\.layers\[0\]\.visibility_m: -5\.0"),
    (Environment(layers=(cloud(0.0, 10.0), fog_layer(0.0, 10.0, 1e-320))),
     r"environment\.layers\[1\]\.visibility_m: 1e-320"),
    (Environment(layers=(fog_layer(1e308, 1e308, 100.0),)), r"environment\.layers\[0\]\.thickness_m: 1e\+308"),
    (Environment(layers=(fog_layer(0.0, 10.0, 100.0, coverage=1.5),)), r"environment\.layers\[0\]\.coverage: 1\.5"),
    (Environment(layers=(fog_layer(float("nan"), 10.0, 100.0),)), r"environment\.layers\[0\]\.base_m: nan"),
    (Environment(sun=(0.0, 0.0, 2.0)), r"environment\.sun"),
])
def test_bad_values_are_named(env, field):
    with pytest.raises(ValueError, match=field):
        with_environment(scene(), env)
    with pytest.raises(ValueError, match=field):
        EnvironmentCache().get(scene(), env)


def test_a_fog_layer_around_the_eye_turns_the_frame_to_fog_colour():
    """A box ahead on an earth plane under a blue sky, seen from inside a 450 m deep fog layer
    of 60 m visibility: the frame is the fog colour; without it, not."""
    db = scene(models={"box": box_model(40, 40, 30, "#c03020")}, instances=[{"model": "box", "position": [0, 300, 0]}],
               sky="#2050c0", earth="#406020", fog={"extinction_per_m": [0.0], "colour": FOG})
    channel = ChannelSpec.symmetric("c", 64, 48, 60.0)
    eye = Eyepoint.of(0.0, 0.0, 100.0, 0.0, 0.0, 0.0)
    options = RenderOptions(samples=1)
    clear = render_frame(db, channel, eye, options).rgb
    fogged_db = with_environment(db, Environment(layers=(fog_layer(-50.0, 450.0, 60.0),)))
    fogged = render_frame(fogged_db, channel, eye, options).rgb
    assert clear.shape == fogged.shape == (48, 64, 3)
    fog = linear(FOG)
    assert np.abs(clear - fog).max() > 0.2  # sky, earth and box differ from the fog
    # The eye is 100 m up in 0.065/m fog: the box and earth are 300 m or more away (tau >= 19),
    # the sky lies through 300 m of fog or more at <= 17 deg up (tau >= 66): fog colour.
    np.testing.assert_allclose(fogged, np.broadcast_to(fog, fogged.shape), atol=2e-3)
