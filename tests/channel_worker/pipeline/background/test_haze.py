"""Haze (channel_worker/pipeline/haze.py): H(range, elevation) of an exponential atmosphere,
checked against its closed form and its limits, and the hazed sky the terrain stage paints."""

from __future__ import annotations

import math

import numpy as np
import pytest

from channel_worker.pipeline.background.haze import (
    OPAQUE_TAU,
    beta_at,
    haze_amount,
    haze_amount_py,
    haze_params,
)
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.scene.atmosphere import Haze
from services.rig.frame import ChannelSpec, Eyepoint

from ..terrain_fixtures import RGSS4, linear, render_terrain, scene

GREY = np.array([0.5, 0.55, 0.6], np.float32)
VIS, HS, BASE = 5000.0, 1200.0, 100.0


def haze(visibility: float = VIS, scale: float = HS, base: float = BASE) -> Haze:
    return Haze(visibility_m=visibility, scale_height_m=scale, base_height_m=base, colour=GREY)


def closed_form(hz: Haze, eye_z: float, r: float, s: float) -> float:
    """H = 1 - exp(-tau), tau = integral of beta along the ray, computed independently:
    beta(z) = ln 2 / Vis exp(-(z - base) / Hs), z = eye_z + t s, t in [0, r]."""
    beta_eye = (math.log(2.0) / hz.visibility_m
                * math.exp(-(eye_z - hz.base_height_m) / hz.scale_height_m))
    k = s / hz.scale_height_m
    tau = beta_eye * (r if k == 0.0 else -math.expm1(-k * r) / k)
    return -math.expm1(-tau)


def test_no_haze_at_zero_range():
    for s in (-1.0, -0.3, 0.0, 0.2, 1.0):
        assert haze_amount_py(haze(), 500.0, 0.0, s) == 0.0


def test_haze_grows_with_range_and_tends_to_one():
    ranges = np.geomspace(1.0, 1e7, 60)
    for s in (-0.5, -1e-3, 0.0, 1e-3):
        h = np.array([haze_amount_py(haze(), 300.0, r, s) for r in ranges])
        assert np.all(np.diff(h) > 0) or np.all(np.diff(h[h < 1.0]) > 0), s
        assert h[-1] > 0.999, (s, h[-1])
    assert haze_amount_py(haze(), 300.0, 1e12, 0.0) == pytest.approx(1.0)


def test_matches_the_closed_form():
    hz = haze()
    for eye_z in (0.0, 100.0, 2500.0):
        for r in (10.0, 1000.0, 20000.0):
            for s in (-0.9, -0.1, 0.05, 0.7):
                want = closed_form(hz, eye_z, r, s)
                assert haze_amount_py(hz, eye_z, r, s) == pytest.approx(want, rel=1e-12, abs=1e-15)


def test_visibility_is_the_half_haze_distance():
    # A level path at the base height: H(Vis) = 1/2, for any scale height.
    for scale in (HS, 300.0, math.inf):
        assert haze_amount_py(haze(scale=scale), BASE, VIS, 0.0) == pytest.approx(0.5, rel=1e-12)


def test_looking_down_is_hazier_than_level_and_up_clearer():
    hz = haze()
    for r in (500.0, 5000.0, 30000.0):
        down, level, up = (haze_amount_py(hz, 1500.0, r, s) for s in (-0.2, 0.0, 0.2))
        assert down > level > up, (r, down, level, up)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_series_branch_is_continuous_with_the_exact_branch(side):
    """|x| = |R s / Hs| < 1e-4 takes the series; just either side of the switch the two
    branches agree to rounding (H changes by a few 1e-10 relative across it)."""
    hz = haze()
    r = 2000.0
    s0 = side * 1e-4 * HS / r  # x = +-1e-4 exactly
    below = haze_amount_py(hz, 200.0, r, s0 * (1.0 - 1e-9))
    above = haze_amount_py(hz, 200.0, r, s0 * (1.0 + 1e-9))
    assert below == pytest.approx(above, rel=1e-12)
    assert below == pytest.approx(closed_form(hz, 200.0, r, s0), rel=1e-12)
    # And the series near x = 0 agrees with the closed form (no 0/0 at exactly level).
    for s in (0.0, 1e-12, -1e-9, 3e-6):
        want = closed_form(hz, 200.0, r, s)
        assert haze_amount_py(hz, 200.0, r, s) == pytest.approx(want, rel=1e-12)


def test_homogeneous_haze_depends_on_range_only():
    hz = haze(scale=math.inf)
    for r in (100.0, 5000.0, 50000.0):
        want = 1.0 - 2.0 ** (-r / VIS)
        for s in (-1.0, -0.01, 0.0, 0.5, 1.0):
            assert haze_amount_py(hz, 3000.0, r, s) == pytest.approx(want, rel=1e-12)
    assert haze_amount_py(hz, 3000.0, math.inf, 1.0) == 1.0  # homogeneous sky is all haze


def test_sky_overhead_keeps_its_colour_and_the_horizon_is_haze():
    hz = haze()
    overhead = haze_amount_py(hz, BASE, math.inf, 1.0)
    # tau = beta(eye) Hs / s: ln 2 * 1200 / 5000 = 0.166, H = 0.153
    assert overhead == pytest.approx(1.0 - math.exp(-math.log(2.0) * HS / VIS), rel=1e-12)
    assert overhead < 0.2
    assert haze_amount_py(hz, BASE, math.inf, 0.0) == 1.0
    assert haze_amount_py(hz, BASE, math.inf, -0.5) == 1.0
    # Higher up the sky overhead is clearer.
    assert haze_amount_py(hz, 3000.0, math.inf, 1.0) < overhead


def _extreme_cases():
    for scale in (HS, 1.0, math.inf):
        for eye_z in (-1e6, -1e4, 0.0, 1e4, 1e6):
            for r in (0.0, 1e-3, 1e9, math.inf):
                for s in (-1.0, -1e-7, 0.0, 1e-7, 1.0):
                    # Among them: beta underflowing to 0 (eye far above the base) while
                    # exp(-x) overflows (looking far down), which once gave 0 * inf = NaN.
                    yield pytest.param(eye_z, r, s, scale,
                                       id=f"z{eye_z:g}-r{r:g}-s{s:g}-hs{scale:g}")


@pytest.mark.parametrize("eye_z, r, s, scale", list(_extreme_cases()))
def test_extreme_values_stay_in_range(eye_z, r, s, scale):
    h = haze_amount_py(haze(scale=scale), eye_z, r, s)
    assert math.isfinite(h) and 0.0 <= h <= 1.0, h


def test_a_thin_haze_layer_seen_from_above_is_not_nan():
    # Ordinary numbers: 1 m scale height (the scene parser's minimum), eye 800 m above the
    # base looking straight down at a point 2 km away (1200 m below the base: H = 1).
    h = haze_amount_py(haze(scale=1.0), BASE + 800.0, 2000.0, -1.0)
    assert math.isfinite(h) and 0.0 <= h <= 1.0, h


def test_extremes_saturate_sensibly():
    hz = haze()
    assert haze_amount_py(hz, -1e6, 10.0, 0.0) == 1.0  # far below the base: opaque air
    assert haze_amount_py(hz, 1e6, 1e9, 0.0) == 0.0  # far above it: no air
    assert haze_amount_py(hz, 0.0, 1e9, -1.0) == 1.0


def test_params_and_beta():
    hz = haze()
    assert np.array_equal(haze_params(None, 123.0), np.zeros(7))
    p = haze_params(hz, 700.0)
    assert p[0] == 1.0 and p[1] == pytest.approx(beta_at(hz, 700.0), rel=1e-15)
    assert p[2] == pytest.approx(1.0 / HS) and np.allclose(p[3:6], GREY) and p[6] == 700.0
    assert beta_at(hz, BASE) == pytest.approx(math.log(2.0) / VIS, rel=1e-15)
    assert beta_at(hz, BASE + HS) == pytest.approx(math.log(2.0) / VIS / math.e, rel=1e-12)
    assert math.isfinite(beta_at(hz, -1e9)) and beta_at(hz, 1e9) == 0.0
    assert haze_params(haze(scale=math.inf), 5.0)[2] == 0.0
    # The numba kernel and the Python wrapper are one function.
    assert haze_amount(p, 1234.0, -0.05) == haze_amount_py(hz, 700.0, 1234.0, -0.05)
    # Beyond OPAQUE_TAU a surface is 99.9 % haze (the terrain scan stops there).
    assert 1.0 - math.exp(-OPAQUE_TAU) > 0.999


SKY, EARTH, HAZE_HEX = "#2050c0", "#406020", "#c0c8d0"
SMALL = ChannelSpec.symmetric("c", 80, 60, 60.0)


def _sky_haze_error(db, eye: Eyepoint) -> float:
    """Largest difference between the haze share of the sky in a render (from the red
    channel: sky 0.014, haze 0.527) and haze_amount at each pixel centre's elevation, over
    the pixels whose centre is more than 2 degrees above the horizon."""
    from channel_worker.pipeline.geometry.view import screen_mapping

    view = make_view(SMALL, eye)
    bg = render_terrain(db, view, RGSS4)
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    tx = (np.arange(view.width) + 0.5 - sx_off) / sx_scale
    ty = (np.arange(view.height) + 0.5 - sy_off) / sy_scale
    d = np.stack(np.broadcast_arrays(tx[None, :], ty[:, None], np.ones((1, 1))), -1)
    d = d @ view.world_to_eye
    sin_el = d[..., 2] / np.linalg.norm(d, axis=-1)
    sky = (sin_el > math.sin(math.radians(2.0))) & ~(bg.inv_z > 0).any(axis=2)
    assert sky.sum() > 100
    want = np.array([haze_amount_py(db.haze, float(eye.position[2]), math.inf, float(v))
                     for v in sin_el[sky]])
    s_r, h_r = linear(SKY)[0], linear(HAZE_HEX)[0]
    got = (bg.rgb[..., 0][sky] - s_r) / (h_r - s_r)
    return float(np.abs(got - want).max())


@pytest.mark.parametrize("pitch", [0.0, 40.0, 90.0])
def test_the_sky_is_hazed_by_elevation_under_terrain(pitch):
    # A small terrain out of sight behind the eye makes the stage cast its lines.
    from channel_worker.testing.terrain_reference import single_level_database

    from ..terrain_fixtures import flat_nodes

    h, c = flat_nodes(4)
    t = single_level_database(h, c, 10.0, np.array([-20.0, -500.0, 0.0]), page_size=4)
    db = scene(terrain=t, haze={"visibility_m": 5000.0, "colour": HAZE_HEX}, sky=SKY, earth=EARTH)
    # Measured: 0.0005 at most (the per-row table interpolated between row centres).
    assert _sky_haze_error(db, Eyepoint.of(0.0, 0.0, 50.0, 0.0, pitch, 0.0)) < 0.01


@pytest.mark.parametrize("pitch", [0.0, 90.0])
def test_the_sky_is_hazed_by_elevation_without_terrain(pitch):
    db = scene(haze={"visibility_m": 5000.0, "colour": HAZE_HEX}, sky=SKY, earth=EARTH)
    assert _sky_haze_error(db, Eyepoint.of(0.0, 0.0, 50.0, 0.0, pitch, 0.0)) < 0.01


def test_the_horizon_is_haze_and_the_near_earth_keeps_its_colour():
    """A haze-only scene looking level: the sky just above the horizon is the haze colour, the
    earth plane below is hazed by its range, and nothing hides a polygon."""
    db = scene(haze={"visibility_m": 5000.0, "colour": HAZE_HEX}, sky=SKY, earth=EARTH)
    level = render_terrain(db, make_view(SMALL, Eyepoint.of(0.0, 0.0, 50.0, 0.0, 0.0, 0.0)), RGSS4)
    h_col = linear(HAZE_HEX)
    # The sky within 1.5 degrees above the horizon (rows 28 and 29; the horizon is between rows
    # 29 and 30): tau = beta Hs / sin(elevation) >= 5, so H > 0.99.
    low_sky = level.rgb[28:30].reshape(-1, 3)
    assert np.abs(low_sky - h_col).max() < 0.01
    # Half a pixel below it (tan = 0.5 * 2 tan 30 / 80) the earth plane, 6.9 km away, hazed by
    # H(6.9 km) looking down (the pixel centre's range and elevation stand for the pixel).
    sin_el = math.sin(math.atan(math.tan(math.radians(30.0)) / 80.0))
    earth_h = haze_amount_py(db.haze, 50.0, 50.0 / sin_el, -sin_el)
    assert 0.5 < earth_h < 0.7
    want = linear(EARTH) * (1 - earth_h) + h_col * earth_h
    assert np.abs(level.rgb[30, 40] - want).max() < 0.002
    # Bottom row: the earth plane about 90 m away: mostly earth.
    bottom = level.rgb[-1].mean(axis=0)
    assert np.linalg.norm(bottom - linear(EARTH)) < np.linalg.norm(bottom - h_col)
    assert not (level.inv_z > 0).any()  # sky and earth never hide a polygon
