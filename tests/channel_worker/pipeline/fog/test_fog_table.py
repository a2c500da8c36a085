"""Layered fog (channel_worker/pipeline/fog/fog.py, US 5,535,374): the per-frame table of average
extinction (fog_params) and its per-sample lookup (fog_depths) against the exact integral of
the piecewise-linear strata (channel_worker/testing/fog_reference.py).

How the error is bounded. The table holds the average A(d) of sigma from the eye to axis
distances d = j dt and interpolates between them; tau = R A(d) = I(d) / c, d = R c, I(d) the
integral of sigma along the axis. An error e in I(d) is an error e / |c| in tau: at a fixed d a
grazing ray's error grows with its range without limit. A ray in clear air a few metres under
a fog base, rising at half a degree, has no fog in truth but reads the table cell holding the
base, times hundreds of metres: its transmission is off by 0.25 with the table at the sample
spacing (test_grazing_rays_...). So no bound on the transmission error holds for every ray;
what the table does bound is the error in the axis integral,

    |tau_table - tau_exact| |c| <= K sigma_max dt min(1, dt / spacing),

(dt the table spacing, sigma_max the densest sample): second order in dt while the table is
finer than the samples, first order (a cell's whole integral) when it is coarser. K and the
per-case bounds below were measured (the figure is in each comment) and set with a margin of
about a third; they are fog.py's at sha256 ba63094e (a cubic of the integral between entries)
and need measuring again if its interpolation changes. They fail if the interpolation or the
beyond-table closed form is broken: entries and the closed form are checked to 1e-11, an eye
on a plane (sigma linear across every cell) everywhere to rounding.

Three "reproducer" tests pin bugs found in an earlier version (a negative depth from
rounding, a division by zero next to a clear plane, a depth that fell with range in the eye's
cell), fixed since. The transmission errors of a realistic ground fog per
table spacing are bench/bench_fog.py's (bench/README.md "Fog").
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.contract import F_DT, F_INT_HI, F_J0, F_N, F_ON, F_SIG_EYE
from channel_worker.pipeline.fog.fog import MAX_TABLE, fog_depths, fog_params
from channel_worker.pipeline.scene.atmosphere import Fog
from channel_worker.testing.fog_reference import (
    axis_optical_depths,
    axis_position,
    layer_integral,
    optical_depths,
    sigma_at,
    strata,
)

COLOUR = np.array([0.7, 0.75, 0.8], np.float32)
#: Ground fog (as bench/bench_fog.py's): 0-300 m in 16 planes 20 m apart, light fog near the
#: ground, a dense layer (visibility ~50 m) one plane thick at 100 m, thinning to clear at
#: 300 m, clear above.
GROUND = np.array([0.010, 0.010, 0.012, 0.015, 0.010, 0.080, 0.010, 0.008, 0.006, 0.005,
                   0.004, 0.003, 0.002, 0.001, 0.0005, 0.0])
GROUND_DX = 20.0
#: A dense layer: visibility ~40 m between 40 and 80 m, light fog under it, clear above.
DENSE = np.array([0.005, 0.005, 0.100, 0.100, 0.100, 0.0, 0.0])
DENSE_DX = 20.0
#: Direction cosines with the axis every ray set uses: straight, oblique, grazing.
COSINES = np.array([1.0, 0.7, 0.3, 0.1, 0.03, 0.01, 1e-3, 1e-4])
RANGES = np.geomspace(1.0, 1e5, 61)

#: The axis-integral bound's K (module docstring) for tables 1/8 to 1 x the sample spacing.
#: Measured: 0.021 over 3000 of the property test's examples; 0.032 over 3000 random structures
#: x 256 rays (half of them grazing) at 1/16 to 1 x the spacing. (A table 2 or 4 x coarser than
#: the samples: 0.17, 0.25. US 5,535,374's linear interpolation of the average, fog.py's first
#: version: 0.23.)
K_AXIS = 0.045
#: The thin-layer test's bound in the eye's cells and the one holding the layer's edge:
#: measured 0.112 (a 40 m table, 4 x the layer's half-width).
THIN_EDGE = 0.15


def tables(spacing: float) -> tuple[float | None, float]:
    """The table spacings each hard case runs with: fog.py's default (None) and US
    5,535,374's, the sample spacing itself."""
    return (None, spacing)


def fog(extinction, spacing=20.0, *, axis=(0.0, 0.0, 1.0), origin=(0.0, 0.0, 0.0),
        table=None) -> Fog:
    return Fog(axis=np.asarray(axis, np.float64), origin=np.asarray(origin, np.float64),
               spacing_m=spacing, extinction=np.asarray(extinction, np.float64),
               colour=COLOUR, table_spacing_m=table)


def eye_at(fg: Fog, h: float, sideways: float = 0.0) -> np.ndarray:
    """A world eye h metres along the axis from plane 0 (and sideways along the strata)."""
    side = np.cross(fg.axis, [1.0, 0.0, 0.0] if abs(fg.axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    return fg.origin + h * fg.axis + sideways * side / np.linalg.norm(side)


def directions(axis: np.ndarray, cosines: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Unit world directions with the given cosines with the axis, random azimuths."""
    a = np.asarray(axis, np.float64)
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    phi = rng.uniform(0.0, 2.0 * math.pi, cosines.shape)
    s = np.sqrt(np.maximum(1.0 - cosines * cosines, 0.0))
    return (cosines[:, None] * a + s[:, None] * (np.cos(phi)[:, None] * e1
                                                 + np.sin(phi)[:, None] * e2))


def ray_grid(fg: Fog, signs=(1.0, -1.0), ranges=RANGES, seed=0):
    """Every cosine of COSINES with each sign against every range: (dirs, ranges)."""
    rng = np.random.default_rng(seed)
    cos = np.concatenate([s * COSINES for s in signs])
    c, r = np.meshgrid(cos, ranges, indexing="ij")
    return directions(fg.axis, c.ravel(), rng), r.ravel()


def depths(fg: Fog | None, eye, dirs, ranges):
    """(table tau, exact tau, cosines, FogTable) for rays from a world eye."""
    eye = np.asarray(eye, np.float64)
    tab = fog_params(fg, None, eye=eye)
    cos = np.ascontiguousarray(dirs @ fg.axis)
    ours = fog_depths(tab.params, np.ascontiguousarray(ranges, np.float64), cos)
    ref = optical_depths(strata(fg), eye, dirs, ranges)
    return ours, ref, cos, tab


def transmission_error(ours, ref) -> np.ndarray:
    return np.abs(np.exp(-ours) - np.exp(-ref))


def axis_error(ours, ref, cos) -> np.ndarray:
    """|tau_table - tau_exact| |c|: the error in the axis integral (0 where both are inf)."""
    both_inf = np.isinf(ours) & np.isinf(ref)
    with np.errstate(invalid="ignore"):
        e = np.abs(ours - ref) * np.abs(cos)
    return np.where(both_inf, 0.0, e)


def axis_bound(fg: Fog, tab, k: float = K_AXIS) -> float:
    dt = tab.params[F_DT]
    return k * float(fg.extinction.max()) * dt * min(1.0, dt / fg.spacing_m)


def relative(ours, ref) -> np.ndarray:
    return np.abs(ours - ref) / np.maximum(np.abs(ref), 1e-300)


def check_sane(ours, rounding: float = 0.0) -> None:
    assert not np.isnan(ours).any()
    assert (ours >= -rounding).all(), ours.min()


# --- exactness where the table is exact -------------------------------------------------------

def test_table_entries_and_beyond_the_table_are_exact():
    """At a table entry A is the exact integral's average and beyond the table the closed form
    is exact: both to rounding, however coarse the table."""
    for table in (None, 40.0, 5.0):
        fg = fog(GROUND, table=table)
        for h in (0.0, 37.0, 100.0, 100.0 + 1e-9, 299.0, 450.0, -30.0):
            tab = fog_params(fg, None, eye=eye_at(fg, h))
            dt, j0, n = tab.params[F_DT], tab.params[F_J0], tab.params[F_N]
            c = np.array([1.0, 0.5, 0.01, -1.0, -0.3, -0.01])
            for j in range(int(n)):
                k = j - j0
                if k == 0:
                    continue
                ok = np.sign(c) == np.sign(k)
                r = k * dt / c[ok]
                ours = fog_depths(tab.params, r, c[ok].copy())
                ref = axis_optical_depths(strata(fg), h, c[ok], r)
                assert relative(ours, ref).max() <= 1e-11, (table, h, j)
            # Beyond the table: d from just past its ends out to 100 km.
            lo = -j0 * dt
            hi = (n - 1 - j0) * dt
            for d in (lo * 1.0001, lo * 3.7, -1e5, hi * 1.0001, hi * 2.3, 1e5):
                cc = c[np.sign(c) == np.sign(d)]
                r = d / cc
                ours = fog_depths(tab.params, r, cc.copy())
                ref = axis_optical_depths(strata(fg), h, cc, r)
                assert relative(ours, ref).max() <= 1e-11, (table, h, d)


def test_no_fog_flag_is_zero():
    tab = fog_params(None, None, eye=np.array([1.0, 2.0, 3.0]))
    assert tab.params[F_ON] == 0.0
    assert not tab.params.any()
    assert not tab.coarsened


def test_homogeneous_fog_is_exp_minus_sigma_r():
    sigma = 0.0123
    for table in (None, 3.0, 700.0):
        for axis, origin in (((0, 0, 1), (0, 0, 0)), ((0.3, -0.2, 0.93), (1e6, -1e6, 50.0))):
            fg = fog([sigma], 10.0, axis=axis, origin=origin, table=table)
            for h in (0.0, 5.0, -123.4, 1e4):
                dirs, r = ray_grid(fg, ranges=np.concatenate([[0.0], RANGES]), seed=3)
                ours, ref, _, _ = depths(fg, eye_at(fg, h, 77.0), dirs, r)
                want = sigma * r
                assert relative(ours, want).max() <= 1e-12, (table, axis, h)
                assert relative(ref, want).max() <= 1e-12
                # Transmission: its relative error is the depth's absolute error (up to 2e-12
                # at depth 18: the table's entries are differences of integrals from plane 0,
                # which lose digits for an eye 10 km from it).
                assert np.abs(np.exp(-ours) - np.exp(-want)).max() <= 1e-12
            # The sky: infinite whichever way, and parallel too.
            tab = fog_params(fg, None, eye=eye_at(fg, 1.0))
            sky = fog_depths(tab.params, np.full(3, np.inf), np.array([0.5, -0.5, 0.0]))
            assert np.isinf(sky).all()


# --- the hard cases -------------------------------------------------------------------

def test_eye_exactly_on_a_sample_plane():
    """Resample planes through a sample plane, spaced a whole fraction of the sample spacing:
    sigma is linear across every cell, so the cubic of the integral (fog.py's docstring) is
    exact for every ray; the first cell either side is exact for any interpolation that keeps
    a linear average. An eye off the planes is the other tests' business."""
    rng = np.random.default_rng(1)
    for table in tables(GROUND_DX):
        fg = fog(GROUND, table=table)
        for k in (0, 4, 5, 6, 15):
            h = k * fg.spacing_m
            eye = eye_at(fg, h, 12.0)
            tab = fog_params(fg, None, eye=eye)
            assert tab.params[F_SIG_EYE] == GROUND[k]
            # Rays ending within one cell of the eye's plane along the axis.
            c = rng.uniform(-1.0, 1.0, 400)
            r = rng.uniform(0.0, tab.params[F_DT], 400) / np.abs(c)
            ours, ref, _, _ = depths(fg, eye, directions(fg.axis, c, rng), r)
            assert (np.abs(ours - ref) <= 1e-11 * ref + 1e-15).all(), (table, k)
            dirs, r = ray_grid(fg, seed=k)
            ours, ref, _, tab = depths(fg, eye, dirs, r)
            check_sane(ours)
            fin = np.isfinite(ref)
            # Measured: 1.6e-12 relative (depths of 1e-3 and below lose digits).
            assert (np.abs(ours - ref)[fin] <= 1e-11 * ref[fin] + 1e-15).all(), (table, k)


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["looking up", "looking down"])
def test_eye_inside_a_dense_layer(sign):
    """Eyes in a layer of visibility 40 m, on its planes and between them, looking up (into the
    clear sky above) and down (into light fog for ever)."""
    k_max = {None: 0.032, DENSE_DX: 0.032}  # measured 0.021, 0.023 of the axis bound's unit
    t_max = {None: 0.0055, DENSE_DX: 0.012}  # measured 0.0040, 0.0088
    for table in tables(DENSE_DX):
        fg = fog(DENSE, DENSE_DX, table=table)
        for h in (50.0, 60.0, 75.0, 79.0):
            dirs, r = ray_grid(fg, signs=(sign,), seed=int(h))
            ours, ref, cos, tab = depths(fg, eye_at(fg, h), dirs, r)
            check_sane(ours)
            assert axis_error(ours, ref, cos).max() <= axis_bound(fg, tab, k_max[table]), h
            assert transmission_error(ours, ref).max() <= t_max[table], (table, h)
            # Sky: clear above (finite, exact), the light fog below goes on for ever.
            sky = fog_depths(tab.params, np.full(cos.size, np.inf), cos)
            want = axis_optical_depths(strata(fg), h, cos, np.full(cos.size, np.inf))
            if sign > 0:
                assert np.isfinite(sky).all() and relative(sky, want).max() <= 1e-12
            else:
                assert np.isinf(sky).all() and np.isinf(want).all()


def test_thin_layer_one_plane_is_conserved():
    """One nonzero plane: a triangular layer of base 2 spacings holding sigma spacing. A ray
    that crosses it entirely sees that integral / |c|. The table keeps the layer however
    coarse it is (its entries are exact integrals, not point samples): exact at its entries,
    beyond it, and in every cell past the layer outside the eye's two. In the eye's cells and
    in the cell holding the layer's far edge, within the axis bound (THIN_EDGE)."""
    sigma, dx = 0.05, 10.0
    ext = np.zeros(9)
    ext[4] = sigma
    whole = sigma * dx
    for table in (None, 10.0, 5.0, 25.0, 40.0):
        fg = fog(ext, dx, table=table)
        assert layer_integral(strata(fg)) == pytest.approx(whole, rel=1e-15)
        for h in (0.0, 12.5, 29.0, 51.0, 80.0, 300.0, -1000.0):
            tab = fog_params(fg, None, eye=eye_at(fg, h))
            dt, j0, n = tab.params[F_DT], tab.params[F_J0], tab.params[F_N]
            sign = 1.0 if h < 40.0 else -1.0
            far = abs(40.0 - h) + dx  # the layer's far side, axis metres from the eye
            rng = np.random.default_rng(abs(int(h)) + 7)
            c = sign * np.concatenate([COSINES, rng.uniform(1e-3, 1.0, 400)])
            d = far + rng.uniform(0.0, 400.0, c.size)  # every ray crosses the whole layer
            d[:COSINES.size] = far + 0.37 * dx
            d[-20:] = (np.ceil(far / dt) + np.arange(20)) * dt  # on entries
            r = d / np.abs(c)
            ours = fog_depths(tab.params, r, c)
            want = whole / np.abs(c)
            ref = axis_optical_depths(strata(fg), h, c, r)
            assert relative(ref, want).max() <= 1e-12
            end = (n - 1 - j0) * dt if sign > 0 else j0 * dt  # the table's end
            d_j = np.floor(d / dt + 1e-12) * dt  # the entry before d
            on_entry = np.abs(d - np.round(d / dt) * dt) <= 1e-9 * d
            exact = on_entry | (d >= end) | ((d_j >= dt) & (d_j >= far))
            assert relative(ours[exact], want[exact]).max() <= 1e-12, (table, h)
            rest = ~exact
            err = axis_error(ours[rest], ref[rest], c[rest])
            assert err.max(initial=0.0) <= axis_bound(fg, tab, THIN_EDGE), (table, h)


def test_thin_layer_inside_the_eye_cell():
    """A known limit of the table: a layer wholly inside the eye's own cell (table spacing 25 m
    over a 20 m layer) is not conserved by rays ending past it inside that cell, since the
    cell's cubic cannot follow the layer's kinks; from the cell's end on it is exact."""
    ext = np.zeros(9)
    ext[4] = 0.05
    fg = fog(ext, 10.0, table=25.0)
    tab = fog_params(fg, None, eye=eye_at(fg, 29.0))
    # The layer (30..50 m) lies inside the eye's first table cell (29..54 m).
    r = np.array([22.0, 24.0, 30.0, 60.0])  # straight up: d = r, every one past the layer
    ours = fog_depths(tab.params, r, np.ones(r.size))
    # Measured: 0.480 and 0.498 (US 5,535,374's linear average: 0.387, 0.461), then 0.5 exactly.
    assert relative(ours[:2], np.full(2, 0.5)).max() <= 0.05, ours
    assert relative(ours[2:], np.full(2, 0.5)).max() <= 1e-9, ours


def test_tilted_axis_origin_away_from_zero():
    k_max = {None: 0.038, GROUND_DX: 0.038}  # measured 0.028, 0.014 of the axis bound's unit
    t_max = {None: 0.003, GROUND_DX: 0.03}  # measured 0.0022, 0.022
    axis = np.array([0.3, -0.2, 0.93])
    for table in tables(GROUND_DX):
        fg = fog(GROUND, axis=axis, origin=(1234.5, -678.9, 42.0), table=table)
        for h in (0.0, 50.0, 100.0, 111.1, 250.0, 813.7):
            dirs, r = ray_grid(fg, seed=int(h))
            ours, ref, cos, tab = depths(fg, eye_at(fg, h, 333.0), dirs, r)
            check_sane(ours)
            assert tab.eye_axis_m == pytest.approx(h, abs=1e-9)
            assert axis_error(ours, ref, cos).max() <= axis_bound(fg, tab, k_max[table]), h
            assert transmission_error(ours, ref).max() <= t_max[table], (table, h)


def test_ranges_of_100_km():
    """100 km rays: past the table (the closed form, exact) unless grazing; the grazing ones
    (d = 10 and 100 m) within the bound."""
    k_max = {None: 0.03, GROUND_DX: 0.03}  # measured 0 (exact), 0.022 of the bound's unit
    rng = np.random.default_rng(5)
    for table in tables(GROUND_DX):
        fg = fog(GROUND, table=table)
        for h in (5.0, 100.0, 107.3, 290.0, 1500.0, 1513.7):
            c = np.concatenate([COSINES, -COSINES, rng.uniform(-1.0, 1.0, 200), [0.0]])
            r = np.full(c.size, 1e5)
            ours, ref, cos, tab = depths(fg, eye_at(fg, h), directions(fg.axis, c, rng), r)
            check_sane(ours)
            far = np.abs(cos) * 1e5 > (GROUND.size + 2) * fg.spacing_m  # past the table
            assert relative(ours[far], ref[far]).max() <= 1e-12, h
            assert axis_error(ours, ref, cos).max() <= axis_bound(fg, tab, k_max[table]), h


def test_sky_above_and_below_the_layers():
    """R infinite: through clear air above, the finite integral / cos, exactly; into the fog
    that goes on for ever below, infinite."""
    fg = fog(GROUND)
    s = strata(fg)
    c = np.concatenate([COSINES, -COSINES, [0.0]])
    for h in (-50.0, 0.0, 60.0, 100.0, 300.0, 2000.0):
        tab = fog_params(fg, None, eye=eye_at(fg, h))
        ours = fog_depths(tab.params, np.full(c.size, np.inf), c)
        ref = axis_optical_depths(s, h, c, np.full(c.size, np.inf))
        up, down = c > 0.0, c < 0.0
        assert np.isfinite(ours[up]).all()
        assert relative(ours[up], ref[up]).max() <= 1e-12, h
        # I / cos: I the integral from the eye to the top of the fog (straight up).
        top = 15 * fg.spacing_m
        above = axis_optical_depths(s, h, np.ones(1), np.array([max(top - h, 0.0)]))[0]
        if h <= 0.0:
            assert above == pytest.approx(layer_integral(s) - GROUND[0] * h, rel=1e-14)
        if h >= top:
            assert above == 0.0
        assert ours[up] == pytest.approx(above / c[up], rel=1e-12), h
        assert np.isinf(ours[down]).all() and np.isinf(ref[down]).all()
        # Parallel: sigma at the eye for ever.
        assert ours[-1] == (np.inf if h < top else 0.0)
    # Clear below and foggy above: the other way round.
    fg2 = fog(GROUND[::-1])
    tab = fog_params(fg2, None, eye=eye_at(fg2, 150.0))
    ours = fog_depths(tab.params, np.full(c.size, np.inf), c)
    ref = axis_optical_depths(strata(fg2), 150.0, c, np.full(c.size, np.inf))
    assert np.isinf(ours[c > 0]).all() and np.isfinite(ours[c < 0]).all()
    assert relative(ours[c < 0], ref[c < 0]).max() <= 1e-12
    assert tab.params[F_INT_HI] > 0.0


def test_rays_parallel_to_the_strata():
    """cos 0: sigma at the eye times the range, no NaN or inf; tilting away converges to it."""
    s = strata(fog(DENSE))
    ranges = np.array([0.0, 1.0, 100.0, 1e4, 1e5])
    slope = np.abs(np.diff(DENSE)).max() / DENSE_DX  # the steepest sigma', 1/m^2
    for table in tables(DENSE_DX):
        fg = fog(DENSE, DENSE_DX, table=table)
        for h in (-10.0, 0.0, 20.0, 30.7, 40.0, 63.3, 80.0, 95.5, 1e4):
            tab = fog_params(fg, None, eye=eye_at(fg, h))
            flat = fog_depths(tab.params, ranges, np.zeros(ranges.size))
            ref = axis_optical_depths(s, h, np.zeros(ranges.size), ranges)
            assert np.isfinite(flat).all()
            assert np.array_equal(flat, tab.params[F_SIG_EYE] * ranges)
            assert relative(flat, ref)[ref > 0].max(initial=0.0) <= 1e-12
            if h % DENSE_DX == 0.0 and 0.0 <= h <= 120.0:
                assert tab.params[F_SIG_EYE] == DENSE[int(h / DENSE_DX)]
            prev = None
            for eps in (1e-6, 1e-9, 1e-12):
                gap = np.zeros(ranges.size)
                for sign in (1.0, -1.0):
                    c = np.full(ranges.size, sign * eps)
                    tilt = fog_depths(tab.params, ranges, c)
                    tilt_ref = axis_optical_depths(s, h, c, ranges)
                    assert np.isfinite(tilt).all()
                    # tau = R A(R c), A(d) = sigma_eye + sigma' d / 2 near d = 0 (d = R eps is
                    # 0.1 m at most here): within sigma'_max R^2 eps / 2 of the parallel value,
                    # to rounding of depths up to 1e4. The table's cubic in a cell holding a
                    # kink of sigma curves on its own: measured up to 1.30 x that (eye 4.5 m
                    # under a kink, 20 m cells).
                    near = slope * ranges * ranges * eps / 2.0 * (1 + 1e-6) + 1e-15 * (1 + flat)
                    assert (np.abs(tilt_ref - flat) <= near).all(), (h, eps)
                    assert (np.abs(tilt - flat) <= 1.75 * near).all(), (table, h, eps)
                    gap = np.maximum(gap, np.abs(tilt - flat))
                if prev is not None:  # smaller as eps shrinks, to rounding of the depths
                    assert (gap <= prev + 1e-15 * (1.0 + flat)).all(), (table, h, eps)
                prev = gap


def test_eye_1000_km_from_the_world_origin():
    """float64 world positions: the eye at (1e6, -1e6, h) over a structure there, and over a
    structure at the world origin with a tilted axis (the eye then lies 690 km along it)."""
    near = fog(GROUND, origin=(1e6, -1e6, 0.0))
    here = fog(GROUND)
    for h in (0.0, 37.5, 100.0, 140.0):
        eye = np.array([1e6, -1e6, h])
        dirs, r = ray_grid(near, seed=11)
        ours, ref, cos, tab = depths(near, eye, dirs, r)
        assert tab.eye_axis_m == h
        check_sane(ours)
        # The same as at the world origin, to rounding.
        ours0, _, _, _ = depths(here, np.array([0.0, 0.0, h]), dirs, r)
        assert relative(ours, ours0)[ours0 > 0].max() <= 1e-12
        # Measured: 0.0027 of the bound's unit.
        assert axis_error(ours, ref, cos).max() <= axis_bound(near, tab, 0.004)
    # Tilted axis, origin at 0: h = (1e6 * 0.3 + 1e6 * 0.2 + 0.93 * 500) / |axis| = 502 km
    # above plane 0; a 5 m table would take 100,000 entries: coarsened (to 15 m). Rays
    # ending in the fog (axis distance h - 320 .. h + 20 below the eye) and past it.
    tilted = fog(GROUND, axis=(0.3, -0.2, 0.93), table=5.0)
    eye = np.array([1e6, -1e6, 500.0])
    h = axis_position(strata(tilted), eye)
    rng = np.random.default_rng(12)
    c = -np.concatenate([COSINES[:4], rng.uniform(0.3, 1.0, 200)])
    r = (h - rng.uniform(-20.0, 320.0, c.size)) / -c
    ours, ref, cos, tab = depths(tilted, eye, directions(tilted.axis, c, rng), r)
    assert tab.coarsened
    assert tab.eye_axis_m == pytest.approx(h, rel=1e-15)
    check_sane(ours)
    assert ref.max() > 0.5  # the rays do reach the fog
    # Measured: 0.015 of the bound's unit.
    assert axis_error(ours, ref, cos).max() <= axis_bound(tilted, tab, 0.02)
    # And an axis that puts the eye inside the fog though 1414 km from the origin.
    inside = fog(GROUND, axis=(1.0, 1.0, 1e-4))
    eye = np.array([1e6, -1e6, 0.0]) + 120.0 * inside.axis
    dirs, r = ray_grid(inside, seed=13)
    ours, ref, cos, tab = depths(inside, eye, dirs, r)
    assert tab.eye_axis_m == pytest.approx(120.0, abs=1e-6)
    assert not tab.coarsened
    check_sane(ours)
    # Measured: 0.0024 of the bound's unit.
    assert axis_error(ours, ref, cos).max() <= axis_bound(inside, tab, 0.004)


def test_eye_far_outside_the_structure():
    """100 km above a 10 m structure: a 10 m table has 10,000 entries; the default (1.25 m) and
    a 1 m one would have more than MAX_TABLE and are coarsened (coarser entries, still within
    the bound)."""
    fg10 = fog(GROUND, 10.0)
    rng = np.random.default_rng(17)
    c = -np.concatenate([COSINES[:6], rng.uniform(1e-3, 1.0, 300)])
    for table, coarsened in ((10.0, False), (2.0, False), (None, True), (1.0, True)):
        fg = fog(GROUND, 10.0, table=table)
        h = 1e5
        tab = fog_params(fg, None, eye=eye_at(fg, h))
        assert tab.coarsened is coarsened, table
        assert tab.params[F_N] <= MAX_TABLE
        if coarsened:
            assert tab.params[F_DT] > 1.0
        # Rays ending in the fog (axis distance 1e5 - 160 .. 1e5 + 20) and past it.
        d = -(h - rng.uniform(-20.0, 160.0, c.size))
        r = d / c
        dirs = directions(fg.axis, c, rng)
        ours, ref, cos, tab = depths(fg, eye_at(fg, h), dirs, r)
        check_sane(ours)
        # Measured: up to 0.022 of the bound's unit (the coarsened tables: 1.53 m).
        assert axis_error(ours, ref, cos).max() <= axis_bound(fg, tab, 0.03), table
    # 1000 km up the coarsened table is coarser than the samples (15.3 m): still bounded.
    tab = fog_params(fg10, None, eye=eye_at(fg10, 1e6))
    assert tab.coarsened and tab.params[F_DT] > fg10.spacing_m
    d = -(1e6 - rng.uniform(-20.0, 160.0, c.size))
    ours = fog_depths(tab.params, d / c, c)
    ref = axis_optical_depths(strata(fg10), 1e6, c, d / c)
    # Measured: 0.050 of the bound's unit (dt = 15.3 m, so the unit is sigma_max dt).
    assert axis_error(ours, ref, c).max() <= axis_bound(fg10, tab, 0.07)


def test_grazing_rays_beside_a_layer_edge_are_bounded_only_in_the_axis_integral():
    """The table's limit: 7 m under a fog base, a ray rising at 0.01 rad (0.57 degrees) is
    still in clear air after 650 m, but reads the table cell holding the base, times 650 m.
    Its transmission error (measured 0.25 with the table at the sample spacing, 0.12, 0.012,
    0.0027, 1.0e-4 at 1/2 to 1/16 of it) is bounded only through the axis integral."""
    ext = np.array([0.0, 0.0, 0.0, 0.02, 0.02, 0.0])  # the base: plane 2 (40 m), 20 m apart
    h, c = 33.0, np.array([0.01])
    r = np.array([6.5 / 0.01])  # d = 6.5 m: ends 0.5 m below the base
    errs = []
    for table in (20.0, 10.0, 5.0, 2.5, 1.25):
        fg = fog(ext, 20.0, table=table)
        tab = fog_params(fg, None, eye=eye_at(fg, h))
        ours = fog_depths(tab.params, r, c)
        ref = axis_optical_depths(strata(fg), h, c, r)
        assert ref[0] == 0.0
        assert axis_error(ours, ref, c)[0] <= axis_bound(fg, tab)
        errs.append(transmission_error(ours, ref)[0])
    assert errs[0] > 0.15  # the limit is real
    assert all(b < a for a, b in itertools.pairwise(errs)), errs
    assert errs[-1] <= 1.5e-4, errs


def test_error_shrinks_as_the_table_spacing_halves():
    """Each halving of the table spacing divides the largest axis-integral error over a fixed
    set of rays by 3.6 to 7.5 (measured: 0.039, 0.011, 0.0015, 3.2e-4, 4.6e-5 of optical
    depth, 1 to 1/16 of the sample spacing); the transmission error falls with it (0.017,
    0.0043, 3.6e-4, 4.9e-5, 3.3e-5)."""
    rng = np.random.default_rng(23)
    c = np.concatenate([COSINES, -COSINES, rng.uniform(-1.0, 1.0, 300)])
    c = c[c != 0.0]
    errs, t_errs = [], []
    for factor in (1.0, 0.5, 0.25, 0.125, 0.0625):
        fg = fog(GROUND, table=GROUND_DX * factor)
        worst = worst_t = 0.0
        for h in (17.0, 100.0, 107.3, 260.0):
            # Axis distances spread over the whole structure either side, at most 100 km.
            rr = np.minimum(np.abs(np.linspace(-330.0, 330.0, c.size) / c), 1e5)
            dirs = directions(fg.axis, c, np.random.default_rng(1))
            ours, ref, cos, _ = depths(fg, eye_at(fg, h), dirs, rr)
            worst = max(worst, axis_error(ours, ref, cos).max())
            worst_t = max(worst_t, transmission_error(ours, ref).max())
        errs.append(worst)
        t_errs.append(worst_t)
    ratios = [a / b for a, b in itertools.pairwise(errs)]
    assert all(q >= 3.0 for q in ratios), (errs, ratios)
    assert all(b < a for a, b in itertools.pairwise(t_errs)), t_errs
    assert t_errs[0] / t_errs[-1] >= 200.0, t_errs  # measured 514


# --- monotonicity -----------------------------------------------------------------------------

def test_depth_never_falls_with_range():
    """Eye 5 m up a layer thinning from sigma 0.1 at plane 0 to 0 at plane 1 (10 m), and at
    its foot: straight up the depth grows to 0.125 (0.5) and stays. (US 5,535,374's linear
    interpolation of the average read 0.166 at 7 m, falling back to 0.125 at 10 m.)"""
    for h, table in ((5.0, 10.0), (5.0, None), (0.0, 10.0), (0.0, 40.0), (5.0, 40.0)):
        fg = fog([0.1, 0.0], 10.0, table=table)
        tab = fog_params(fg, None, eye=eye_at(fg, h))
        r = np.linspace(0.0, 60.0, 601)
        ours = fog_depths(tab.params, r, np.ones(r.size))
        assert (np.diff(ours) >= -1e-12).all(), (h, table, ours.max())


def test_depth_never_falls_in_the_eye_cell_reproducer():
    """Eye at 5 m, 1 m above a plane (4.5 m) where sigma falls from 0.25 at the eye to 0.042,
    and to 0 at 3 m; looking straight down, 1.5 m cells: the cubic's slope at the eye is 3.7
    times the cell's mean (Fritsch-Carlson's limit is 3), so it overshoots: the clamp holds it
    at the cell's end value 0.100694 from 1.0 m, and it dips to 0.100362 at 1.4 m before
    climbing back (the exact depth rises all the way)."""
    fg = fog([0.0, 0.0, 0.0, 0.04166667, 0.66666667], 1.5, table=1.5)
    tab = fog_params(fg, None, eye=eye_at(fg, 5.0))
    r = np.linspace(0.0, 3.0, 301)
    ours = fog_depths(tab.params, r, -np.ones(r.size))
    assert (np.diff(ours) >= -1e-12).all(), -np.diff(ours).max()


def test_depth_never_negative_reproducer():
    """Eye 1e-13 m under the top plane of a structure clear at the top, looking up into clear
    air: fog_params's integral from the eye up is (integral to the top plane) - (integral to
    the eye) = -2.2e-16, so the depths are negative: -2.5e-16 at 2 m, and for the sky that
    integral / cos, -0.022 at cos 1e-14 (T = 1.022) and -2e284 at cos 1e-300 (T = inf; fog_blend
    then gives NaN)."""
    fg = fog([0.0, 0.0, 0.0, 0.6781457, 0.0], 1.474609375)
    tab = fog_params(fg, None, eye=eye_at(fg, 4 * 1.474609375 - 1e-13))
    r = np.array([2.0, 10.0, 1e5, np.inf, np.inf, np.inf])
    ours = fog_depths(tab.params, r, np.array([1.0, 1.0, 1.0, 1.0, 1e-14, 1e-300]))
    assert (ours >= 0.0).all() and (np.exp(-ours) <= 1.0).all(), ours


def test_eye_cell_divides_by_zero_reproducer():
    """Eye 2e-15 m under the top plane (clear above), a ray of range 0 or parallel to the
    strata: u = J0 exactly, w = 0, the entry above is -2e-16 / dt < 0, so avg * w = 0 > a1
    and the clamp computes a1 / w. numba raises ZeroDivisionError (NaN with error_model
    numpy)."""
    fg = fog([0.0, 0.0, 0.14583333, 0.0], 3.0, table=3.0)
    tab = fog_params(fg, None, eye=eye_at(fg, 9.0 - 2e-15))
    ours = fog_depths(tab.params, np.array([0.0, 5.0]), np.array([0.0, 0.0]))
    # Parallel rays take sigma at the eye (1e-16 this close to the clear plane), finite.
    assert np.isfinite(ours).all() and (ours >= 0.0).all()
    assert np.array_equal(ours, tab.params[F_SIG_EYE] * np.array([0.0, 5.0]))


# --- property --------------------------------------------------------------------------------

def floats(lo, hi):
    return st.floats(lo, hi, allow_subnormal=False)


@st.composite
def scenes(draw):
    n = draw(st.integers(2, 20))
    spacing = draw(floats(0.5, 200.0))
    # Optical depth per spacing in [0, 1] (up to a visibility of about 4 spacings), and zeros.
    tau = draw(st.lists(st.one_of(st.just(0.0), floats(0.0, 1.0)), min_size=n, max_size=n))
    ext = np.array(tau) / spacing
    factor = draw(st.sampled_from([1.0, 0.5, 0.25, 0.125]))
    axis = np.array(draw(st.tuples(*[floats(-1.0, 1.0)] * 3)))
    if np.linalg.norm(axis) < 0.1:
        axis = np.array([0.0, 0.0, 1.0])
    origin = np.array(draw(st.tuples(*[floats(-2e6, 2e6)] * 3)))
    top = (n - 1) * spacing
    h = draw(st.one_of(floats(-top - 3 * spacing, 2 * top + 3 * spacing),
                       st.integers(0, n - 1).map(lambda k: k * spacing)))
    # Cosines below 1e-200 are 0 (the reference's cuts would lie beyond 1e308 m).
    cos = np.array(draw(st.lists(st.one_of(
        floats(-1.0, 1.0).map(lambda x: 0.0 if abs(x) < 1e-200 else x),
        st.sampled_from([0.0, 1e-12, -1e-12, 1e-4, -1e-4, 1.0, -1.0])), min_size=1, max_size=8)))
    ranges = np.array(draw(st.lists(st.one_of(floats(0.0, 1e5), floats(1e-2, 1e2),
                                              st.just(np.inf)), min_size=2, max_size=8)))
    return fog(ext, spacing, axis=axis, origin=origin, table=spacing * factor), h, cos, ranges


@settings(max_examples=1000, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_property_table_within_bound_of_the_reference(scene):
    """Random structures, eyes (on planes too), cosines (parallel and grazing too) and ranges
    (the sky too): never NaN, never negative, infinite exactly where the reference is, within
    the axis-integral bound, and never falling as the range grows along a ray."""
    fg, h, cos, ranges = scene
    eye = eye_at(fg, h, 250.0)
    tab = fog_params(fg, None, eye=eye)
    c = np.repeat(cos, ranges.size)
    r = np.tile(ranges, cos.size)
    ours = fog_depths(tab.params, r, c)
    # The same cosines for both (a world direction's cosine computed twice can differ in sign
    # near 0, and the sky's depth with it); the eye's axis position the reference's own.
    s = strata(fg)
    ref = axis_optical_depths(s, axis_position(s, eye), c, r)
    # Never NaN. Never negative, but for rounding: a clear-air axis integral of -2e-16, / |c|
    # in the depth (test_depth_never_negative_reproducer).
    check_sane(ours * np.where(c == 0.0, 1.0, np.abs(c)), rounding=1e-13)
    # Infinite where the reference is, but for parallel sky rays from an eye within rounding of
    # a plane where sigma reaches 0: the two sigmas at the eye are 0 and 1e-17 (both right).
    sig_eye = float(sigma_at(s, axis_position(s, eye)))
    knife = np.isinf(r) & (c == 0.0) & (sig_eye <= 1e-12 * float(fg.extinction.max()))
    assert np.array_equal(np.isinf(ours)[~knife], np.isinf(ref)[~knife])
    bound = axis_bound(fg, tab)
    # The two axis positions of the eye agree to rounding relative to the origin's 2e6 m.
    slack = 1e-9 * (1.0 + float(fg.extinction.max()) * np.where(np.isinf(r), 0.0, r))
    err = np.where(knife, 0.0, axis_error(ours, ref, c))
    assert (err <= bound + slack).all(), (err.max(), bound)
    # Parallel rays (no axis error to bound): sigma at the eye times the range, exactly.
    flat = (c == 0.0) & np.isfinite(r)  # (a ray stopping short is never on the knife edge)
    assert (np.abs(ours[flat] - ref[flat]) <= 1e-12 * ref[flat] + slack[flat]).all()
    # Along each ray the depth never falls as the range grows, but for rounding.
    rr = np.sort(np.concatenate([ranges[np.isfinite(ranges)], np.geomspace(1e-2, 1e5, 120)]))
    for ck in cos:
        t = fog_depths(tab.params, rr, np.full(rr.size, ck))
        fall = -np.diff(t)
        allowed = 1e-12 * (1.0 + t[1:])
        assert (fall <= allowed).all(), (ck, fall.max())
