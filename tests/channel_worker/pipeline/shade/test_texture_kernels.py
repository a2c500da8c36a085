"""Texture samplers and the fade: exact at texel centres, wrapping for any coordinate, trilinear
between levels, the fade monotone in the sample spacing; checked against a numpy reference."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit, typeof

from channel_worker.pipeline.jit import borrowing
from channel_worker.pipeline.scene.surfaces import (
    LOOK_AMPLITUDE,
    LOOK_DETAIL,
    LOOK_INTENSITY,
    LOOK_PER_COLOUR,
    LOOK_PRIMARY,
    LOOK_SLOTS,
    LOOK_TEXTURE,
)
from channel_worker.pipeline.scene.texture_sampling import (
    FADE,
    TextureArrays,
    fade_amplitude,
    texel_bilinear,
    texel_trilinear,
    texture_lod,
    texture_modulation,
)
from channel_worker.pipeline.scene.textures import build_store, empty_store


def make_store():
    rng = np.random.default_rng(7)
    images = [rng.random((16, 16, 3)) + 0.1, rng.random((8, 32, 3)) + 0.1, rng.random((4, 1, 3)) + 0.1]
    return build_store(images, ["square", "wide", "thin"])


STORE = make_store()


# Bounds-checked compiles: an index outside texels raises IndexError instead of reading whatever
# lies there. texel_bilinear is a function of its own (not inlined into its callers), so it is
# compiled anew from its source with the check; texel_trilinear's wrapper checks what it
# inlines and calls the kernels' texel_bilinear.
bilinear = njit(boundscheck=True)(texel_bilinear.py_func)


@njit(boundscheck=True)
def trilinear(store, t, x, y, lod):
    return texel_trilinear(store, t, x, y, lod)


def level_signal(store, t, lv):
    offset, wl, hl = store.level[t, lv]
    return store.texels[offset : offset + (1 << wl) * (1 << hl), :3].reshape(1 << hl, 1 << wl, 3).astype(np.float64)


def reference_bilinear(store, t, level, x, y):
    """numpy wrap-bilinear with Python's exact integer floor and modulo."""
    lv = min(max(level, 0), int(store.levels[t]) - 1)
    sig = level_signal(store, t, lv)
    height, width = sig.shape[:2]
    u = x * width / (1 << int(store.level[t, 0, 1])) - 0.5
    v = y * height / (1 << int(store.level[t, 0, 2])) - 0.5
    i, j = math.floor(u), math.floor(v)
    fx, fy = u - i, v - j
    c0, c1, r0, r1 = i % width, (i + 1) % width, j % height, (j + 1) % height
    return ((1 - fx) * (1 - fy) * sig[r0, c0] + fx * (1 - fy) * sig[r0, c1]
            + (1 - fx) * fy * sig[r1, c0] + fx * fy * sig[r1, c1])


def test_bounds_checking_is_on_in_the_wrappers():
    bad = STORE._replace(level=STORE.level.copy())
    bad.level[0, 0, 0] = STORE.texels.shape[0]  # level 0 of texture 0 past the end of texels
    with pytest.raises(IndexError):
        bilinear(bad, 0, 0, 0.5, 0.5)


@pytest.mark.parametrize("t", [0, 1, 2])
def test_bilinear_exact_at_texel_centres(t):
    w0, h0 = 1 << int(STORE.level[t, 0, 1]), 1 << int(STORE.level[t, 0, 2])
    for lv in range(int(STORE.levels[t])):
        sig = level_signal(STORE, t, lv)
        height, width = sig.shape[:2]
        for j in range(height):
            for i in range(width):
                x, y = (i + 0.5) * w0 / width, (j + 0.5) * h0 / height
                assert bilinear(STORE, t, lv, x, y) == tuple(sig[j, i]), (t, lv, i, j)


def test_bilinear_wraps_continuously():
    sig = level_signal(STORE, 0, 0)
    # On the seam (x = 0): halfway between the last column and the first.
    np.testing.assert_allclose(bilinear(STORE, 0, 0, 0.0, 0.5), 0.5 * (sig[0, 0] + sig[0, -1]), rtol=1e-12)
    np.testing.assert_array_equal(bilinear(STORE, 0, 0, 0.0, 3.25), bilinear(STORE, 0, 0, 16.0, 3.25))
    np.testing.assert_array_equal(bilinear(STORE, 0, 0, 2.75, -16.0), bilinear(STORE, 0, 0, 2.75, 0.0))
    for eps in (1e-3, 1e-6):
        below = np.array(bilinear(STORE, 0, 0, 16.0 - eps, 7.3))
        above = np.array(bilinear(STORE, 0, 0, 16.0 + eps, 7.3))
        assert np.abs(below - above).max() < 2 * eps * 2 * np.abs(sig).max() + 1e-12


def test_bilinear_clamps_the_level_and_guards_non_finite():
    last = int(STORE.levels[1]) - 1
    assert bilinear(STORE, 1, 99, 3.3, 1.1) == bilinear(STORE, 1, last, 3.3, 1.1)
    assert bilinear(STORE, 1, -3, 3.3, 1.1) == bilinear(STORE, 1, 0, 3.3, 1.1)
    for bad in (math.nan, math.inf, -math.inf):
        assert bilinear(STORE, 0, 0, bad, 1.0) == (0.0, 0.0, 0.0)
        assert bilinear(STORE, 0, 0, 1.0, bad) == (0.0, 0.0, 0.0)


def test_bilinear_keeps_precision_far_from_the_origin():
    # 1e9 + 0.25 texels is exact in float64; the sample must be that of 0.25 + a multiple of 16.
    far = bilinear(STORE, 0, 0, 1e9 + 0.25, -1e9 + 3.75)
    near = bilinear(STORE, 0, 0, 0.25, 3.75)  # 1e9 is a multiple of 16
    np.testing.assert_allclose(far, near, rtol=0, atol=1e-12)


def test_empty_store_samples_zero():
    empty = empty_store()
    assert bilinear(empty, 0, 0, 12.3, -4.5) == (0.0, 0.0, 0.0)
    assert trilinear(empty, 0, 12.3, -4.5, 3.0) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("t", [0, 1, 2])
def test_trilinear_equals_bilinear_at_integer_lods(t):
    last = int(STORE.levels[t]) - 1
    for x, y in [(0.3, 0.7), (5.5, 2.25), (-7.1, 40.2)]:
        for lv in range(last + 1):
            assert trilinear(STORE, t, x, y, float(lv)) == bilinear(STORE, t, lv, x, y)
        assert trilinear(STORE, t, x, y, -2.0) == bilinear(STORE, t, 0, x, y)
        assert trilinear(STORE, t, x, y, math.nan) == bilinear(STORE, t, 0, x, y)
        assert trilinear(STORE, t, x, y, last + 3.5) == bilinear(STORE, t, last, x, y)
        assert trilinear(STORE, t, x, y, math.inf) == bilinear(STORE, t, last, x, y)


def test_trilinear_blends_linearly_between_levels():
    a, b = np.array(bilinear(STORE, 0, 1, 3.3, 9.1)), np.array(bilinear(STORE, 0, 2, 3.3, 9.1))
    np.testing.assert_allclose(trilinear(STORE, 0, 3.3, 9.1, 1.25), a + 0.25 * (b - a), rtol=1e-12)


def test_texture_lod():
    assert texture_lod(4.0) == 2.0
    for rho in (1.0, 0.5, 0.0, -3.0, math.nan, math.inf):
        assert texture_lod(rho) == 0.0


def test_fade_amplitude():
    finest = 0.25
    assert fade_amplitude(finest, 0.0) == 1.0
    assert fade_amplitude(finest, 1.0) == 1.0  # q = 0.5
    assert fade_amplitude(finest, 1.5) == pytest.approx(0.5)  # halfway, smoothstep's midpoint
    assert fade_amplitude(finest, 2.0) == 0.0  # q = 1: at Nyquist
    assert fade_amplitude(finest, 50.0) == 0.0
    assert fade_amplitude(finest, -1.5) == fade_amplitude(finest, 1.5)
    for bad in (math.nan, math.inf):
        assert fade_amplitude(finest, bad) == 0.0
    assert fade_amplitude(0.0, 1e6) == 1.0  # no contrast: nothing to alias
    rhos = np.linspace(0.0, 5.0, 2001)
    amp = np.array([fade_amplitude(finest, r) for r in rhos])
    assert np.all(np.diff(amp) <= 0.0) and np.all((amp >= 0.0) & (amp <= 1.0))
    assert np.abs(np.diff(amp)).max() < 0.01  # continuous on this grid


def test_kernels_compile_once_for_every_store():
    """The kernels get a store's arrays (FrameConstants), one numba type whatever the store."""
    fields = ("texels", "level", "levels", "finest")
    three = build_store([np.ones((2, 2, 3))] * 3, ["a", "b", "c"])
    types = {tuple(typeof(getattr(store, f)) for f in fields) for store in (three, empty_store(), STORE)}
    assert len(types) == 1


@borrowing
def _borrowing_sample(store, x):
    r, g, b = texel_trilinear(store, 1, x, 2.0 * x, 1.5)
    return r + g + b


def test_samplers_inline_into_kernels_without_reference_counting():
    # The pipeline's hot kernels compile without numba's reference counting (jit.borrowing).
    assert math.isfinite(_borrowing_sample(STORE, 3.7))


coordinates = st.one_of(
    st.floats(-1e9, 1e9, allow_nan=False),
    st.floats(-40.0, 40.0, allow_nan=False),
    st.integers(-10**9, 10**9).map(lambda i: i + 0.5),
)


@settings(max_examples=300, deadline=None)
@given(t=st.integers(0, 2), level=st.integers(-2, 12), x=coordinates, y=coordinates)
def test_bilinear_matches_reference(t, level, x, y):
    got = np.array(bilinear(STORE, t, level, x, y))
    np.testing.assert_allclose(got, reference_bilinear(STORE, t, level, x, y), rtol=0, atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(t=st.integers(0, 2), x=coordinates, y=coordinates, lod=st.floats(-3.0, 15.0, allow_nan=False))
def test_trilinear_stays_in_bounds_and_in_range(t, x, y, lod):
    got = np.array(trilinear(STORE, t, x, y, lod))
    lo = STORE.texels.min() - 1e-6
    hi = STORE.texels.max() + 1e-6
    assert np.all((got >= lo) & (got <= hi))


@njit(boundscheck=True)
def modulation(store, row, u, v, side):
    return texture_modulation(store, row, FADE, u, v, side, 0.0, 0.0, side)


@pytest.mark.parametrize("side", [0.01, 0.2, 0.45])
def test_a_mono_code_reads_the_mean_channel_as_the_mean_of_the_three(side):
    # A mono code (one signal for every colour) reads the texels' fourth channel alone: it must
    # give the mean of what the per-colour code reads from the other three, at any footprint
    # (side: metres a pixel, one texel a metre), as far as nothing is clamped at 0.
    store = TextureArrays(STORE.texels, STORE.level, STORE.levels, STORE.finest)
    row = np.zeros(LOOK_SLOTS)
    row[LOOK_TEXTURE:LOOK_TEXTURE + 3] = (0, 1, -1)
    row[LOOK_INTENSITY] = 0.3
    row[LOOK_PRIMARY:LOOK_PRIMARY + 2] = 1.0 / 16.0  # a 16-texel repeat 16 m long
    row[LOOK_DETAIL:LOOK_DETAIL + 2] = 1.0 / 32.0
    row[LOOK_AMPLITUDE] = 0.5
    rng = np.random.default_rng(3)
    for u, v in rng.uniform(-1e4, 1e4, (50, 2)):
        colour = row.copy()
        colour[LOOK_PER_COLOUR] = 1.0
        r, g, b = modulation(store, colour, u, v, side)
        grey = modulation(store, row, u, v, side)
        assert grey[0] == grey[1] == grey[2]
        assert abs(grey[0] - (r + g + b) / 3.0) < 1e-6, (u, v, grey, (r, g, b))
