"""Texture stores: image loading, the signal, the pyramid, the finest frequency, the bundled
textures, and errors that name the field and the value."""

import numpy as np
import OpenImageIO as oiio
import pytest

from channel_worker.pipeline.scene.textures import (
    BUNDLED_TEXTURES,
    MAX_LEVELS,
    MAX_TEXTURES,
    PROCEDURAL_KINDS,
    build_store,
    bundled_texture_path,
    empty_store,
    load_image,
    procedural,
)


def write_raw(path, pixels: np.ndarray, fmt=oiio.UINT8) -> None:
    """pixels (H, W, C) written as they are (no colour conversion), in fmt."""
    height, width, channels = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out is not None
    assert out.open(str(path), oiio.ImageSpec(width, height, channels, fmt))
    assert out.write_image(pixels)
    out.close()


def sinusoid(size: int, k: float, axis: int = 1) -> np.ndarray:
    """A grey (size, size, 3) image 0.5 (1 + 0.5 cos(2 pi k x)) along axis, k cycles/texel."""
    x = np.arange(size) + 0.5
    wave = 0.5 * (1.0 + 0.5 * np.cos(2 * np.pi * k * x))
    grey = np.broadcast_to(wave[None, :] if axis == 1 else wave[:, None], (size, size))
    return np.repeat(grey[..., None], 3, axis=2).copy()


def level_signal(store, t: int, lv: int) -> np.ndarray:
    offset, wl, hl = store.level[t, lv]
    return store.texels[offset : offset + (1 << wl) * (1 << hl), :3].reshape(1 << hl, 1 << wl, 3)


# --- load_image ---------------------------------------------------------------------------


def test_load_round_trip_decodes_srgb(tmp_path):
    rng = np.random.default_rng(0)
    encoded = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    write_raw(tmp_path / "a.png", encoded)
    rgb = load_image(tmp_path / "a.png")
    assert rgb.shape == (5, 7, 3) and rgb.dtype == np.float32
    c = encoded / 255.0
    expected = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)  # IEC 61966-2-1
    np.testing.assert_allclose(rgb, expected, atol=1e-6)
    assert load_image(tmp_path / "a.png")[0, 0, 0] == pytest.approx(expected[0, 0, 0], abs=1e-6)


def test_load_grey_is_replicated_and_alpha_dropped(tmp_path):
    grey = np.full((3, 4, 1), 188, np.uint8)
    write_raw(tmp_path / "g.png", grey)
    rgb = load_image(tmp_path / "g.png")
    assert rgb.shape == (3, 4, 3)
    assert np.all(rgb == rgb[0, 0, 0]) and rgb[0, 0, 0] == pytest.approx(0.5, abs=0.01)  # sRGB 188 ~ linear 0.5
    rgba = np.zeros((2, 2, 4), np.uint8)
    rgba[..., 3] = 255
    write_raw(tmp_path / "rgba.png", rgba)
    assert load_image(tmp_path / "rgba.png").shape == (2, 2, 3)


def test_load_float_exr_is_linear(tmp_path):
    pixels = np.full((2, 3, 3), 0.25, np.float32)
    write_raw(tmp_path / "f.exr", pixels, oiio.FLOAT)
    np.testing.assert_allclose(load_image(tmp_path / "f.exr"), 0.25)


def test_load_errors_name_the_path(tmp_path):
    with pytest.raises(ValueError, match=r"missing\.png: no such image file"):
        load_image(tmp_path / "missing.png")
    write_raw(tmp_path / "ok.png", np.zeros((8, 8, 3), np.uint8))
    data = (tmp_path / "ok.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    (tmp_path / "junk.png").write_bytes(b"not an image at all" * 10)
    for name in ("cut.png", "junk.png"):
        with pytest.raises(ValueError, match=rf"{name}: unreadable image"):
            load_image(tmp_path / name)


def test_load_rejects_nan(tmp_path):
    pixels = np.full((2, 2, 3), 0.5, np.float32)
    pixels[1, 1, 2] = np.nan
    write_raw(tmp_path / "nan.exr", pixels, oiio.FLOAT)
    with pytest.raises(ValueError, match=r"nan\.exr: NaN or infinite"):
        load_image(tmp_path / "nan.exr")


def test_load_rejects_huge_image_before_reading(tmp_path):
    write_raw(tmp_path / "wide.png", np.zeros((1, 4097, 1), np.uint8))
    with pytest.raises(ValueError, match=r"wide\.png: 4097 x 1 has a side over 4096"):
        load_image(tmp_path / "wide.png")


# --- bundled textures ---------------------------------------------------------------------


@pytest.mark.parametrize("name", BUNDLED_TEXTURES)
def test_bundled_texture_loads_and_tiles(name):
    rgb = load_image(bundled_texture_path(name)).astype(np.float64)
    assert rgb.shape[0] == rgb.shape[1] and rgb.shape[0] & (rgb.shape[0] - 1) == 0
    assert 0.01 < rgb.mean() < 0.9
    for axis in (0, 1):
        a = np.moveaxis(rgb, axis, 1)
        interior = np.abs(np.diff(a, axis=1)).mean(axis=(0, 2))  # per neighbouring column pair
        seam = np.abs(a[:, 0] - a[:, -1]).mean()
        # The wrap is a seam like any other: within the spread of the interior's.
        assert seam <= np.percentile(interior, 95) * 1.1, (name, axis, seam, np.median(interior))


def test_bundled_texture_path_rejects_unknown_name():
    with pytest.raises(ValueError, match=r"name: 'marble' is not a bundled texture"):
        bundled_texture_path("marble")


def test_bundled_textures_are_package_data():
    import tomllib
    from pathlib import Path

    pyproject = Path(__file__).resolve().parents[4] / "pyproject.toml"
    patterns = tomllib.loads(pyproject.read_text())["tool"]["setuptools"]["package-data"]["channel_worker"]
    assert "data/textures/*.png" in patterns
    for name in BUNDLED_TEXTURES:
        assert bundled_texture_path(name).is_file()


# --- procedural ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", PROCEDURAL_KINDS)
def test_procedural_is_periodic_linear_and_repeatable(kind):
    image = procedural(kind, 64, seed=3)
    assert image.shape == (64, 64, 3) and image.dtype == np.float32
    assert image.min() >= 0.0 and image.max() <= 1.0
    np.testing.assert_array_equal(image, procedural(kind, 64, seed=3))
    for axis in (0, 1):
        a = np.moveaxis(image.astype(np.float64), axis, 1)
        interior = np.abs(np.diff(a, axis=1)).mean(axis=(0, 2))
        assert np.abs(a[:, 0] - a[:, -1]).mean() <= interior.max() * 1.01


def test_procedural_asphalt_is_greyish_and_dark():
    image = procedural("asphalt", 256, seed=1)
    mean = image.mean(axis=(0, 1))
    assert 0.04 < mean.mean() < 0.2
    assert mean.max() - mean.min() < 0.1 * mean.mean()  # a tint, not a colour


@pytest.mark.parametrize("args,pattern", [
    (("marble", 64, 0), r"kind: 'marble' is not one of"),
    (("noise", 100, 0), r"size: 100 is not a power of two"),
    (("noise", 2048, 0), r"size: 2048 is not a power of two from 8 to 1024"),
    (("noise", 64, -1), r"seed: -1 is not an integer >= 0"),
])
def test_procedural_errors(args, pattern):
    with pytest.raises(ValueError, match=pattern):
        procedural(*args)


# --- build_store --------------------------------------------------------------------------


def test_store_layout_and_signal():
    images = [procedural("noise", 64, 1), procedural("checker", 32, 0), np.random.default_rng(2).random((40, 9, 3))]
    store = build_store(images, ["n", "c", "odd"])
    assert store.names == ("n", "c", "odd")
    assert store.level.shape == (3, MAX_LEVELS, 3) and store.level.dtype == np.int64
    assert store.texels.dtype == np.float32 and store.texels.shape[1] == 4
    # Channel 3 is the mean of the signal's three: what a mono code reads.
    np.testing.assert_allclose(store.texels[:, 3], store.texels[:, :3].mean(axis=1), atol=1e-7)
    # 40 x 9 -> 32 x 8 (nearest powers of two): 6 levels, the last (1 x 1) repeated.
    assert list(store.levels) == [7, 6, 6]
    assert tuple(store.level[2, 0, 1:]) == (3, 5)
    assert tuple(store.level[2, 3, 1:]) == (0, 2)  # width stays 1 while height halves on
    assert all(tuple(store.level[2, lv]) == tuple(store.level[2, 5]) for lv in range(5, MAX_LEVELS))
    np.testing.assert_allclose(store.mean_rgb[0], images[0].mean(axis=(0, 1)), rtol=1e-6)
    for t in range(3):
        base = level_signal(store, t, 0)
        np.testing.assert_allclose(base.mean(axis=(0, 1)), 0.0, atol=1e-6)
        for lv in range(1, store.levels[t]):
            np.testing.assert_allclose(level_signal(store, t, lv).mean(axis=(0, 1)), base.mean(axis=(0, 1)),
                                       atol=1e-6)
    # The signal reproduces the image: mean * (1 + signal) == image when nothing was resampled.
    np.testing.assert_allclose(images[0].mean(axis=(0, 1)) * (1 + level_signal(store, 0, 0)), images[0], atol=1e-5)


def test_store_black_channel_has_no_signal():
    image = np.zeros((8, 8, 3))
    image[..., 1] = np.arange(64).reshape(8, 8) / 64.0
    store = build_store([image], ["green"])
    signal = level_signal(store, 0, 0)
    assert np.all(signal[..., [0, 2]] == 0.0) and signal[..., 1].std() > 0.1


def test_store_resamples_to_powers_of_two_and_keeps_periodicity():
    # One period of a sinusoid on 48 texels, stored on 64: still one period, continuous at the wrap.
    x = (np.arange(48) + 0.5) / 48
    row = 0.5 + 0.25 * np.sin(2 * np.pi * x)
    image = np.repeat(np.broadcast_to(row, (48, 48))[..., None], 3, axis=2)
    store = build_store([image], ["s"])
    assert tuple(store.level[0, 0, 1:]) == (6, 6)
    signal = level_signal(store, 0, 0)[0, :, 0].astype(np.float64)
    expected = 0.5 * np.sin(2 * np.pi * (np.arange(64) + 0.5) / 64)
    np.testing.assert_allclose(signal, expected, atol=0.01)


@pytest.mark.parametrize("k", [1 / 32, 3 / 32, 0.125, 0.25, 0.4375])
@pytest.mark.parametrize("axis", [0, 1])
def test_finest_of_a_sinusoid_is_its_frequency(k, axis):
    store = build_store([sinusoid(64, k, axis)], ["wave"])
    assert store.finest[0] == pytest.approx(k, abs=1e-9)


def test_finest_of_a_flat_texture_is_zero():
    store = build_store([np.full((16, 16, 3), 0.3)], ["flat"])
    assert store.finest[0] == 0.0
    assert np.abs(store.texels).max() < 1e-12  # 0 but for the rounding of the mean


def test_finest_is_capped_at_half():
    # Power in the spectrum's corner (0.5, 0.5): radius 0.71, counted as at Nyquist.
    image = np.repeat(np.where(np.indices((16, 16)).sum(axis=0) % 2 == 0, 0.2, 0.8)[..., None], 3, axis=2)
    assert build_store([image], ["fine"]).finest[0] == 0.5


def test_empty_store():
    empty = empty_store()
    assert empty.names == () and empty.texels.shape == (1, 4) and empty.level.shape == (1, MAX_LEVELS, 3)
    assert build_store([], []).texels.shape == empty.texels.shape


@pytest.mark.parametrize("images,names,pattern", [
    ([np.zeros((4, 4))], ["a"], r"images\[0\] \('a'\): shape \(4, 4\) is not \(H, W, 3\)"),
    ([np.zeros((4, 4, 4))], ["a"], r"images\[0\] \('a'\): shape \(4, 4, 4\)"),
    ([np.zeros((0, 4, 3))], ["a"], r"images\[0\] \('a'\): 4 x 0 is not 1 to 4096 on a side"),
    ([np.zeros((4, 4, 3)), np.full((4, 4, 3), np.nan)], ["a", "b"], r"images\[1\] \('b'\): NaN or infinite"),
    ([np.full((4, 4, 3), np.inf)], ["a"], r"images\[0\] \('a'\): NaN or infinite"),
    ([np.full((4, 4, 3), -0.5)], ["a"], r"images\[0\] \('a'\): negative value -0.5"),
    ([np.zeros((4, 4, 3))], ["a", "b"], r"names: 2 names for 1 images"),
    ([np.zeros((4, 4, 3))] * 2, ["a", "a"], r"names\[1\]: 'a' is given twice"),
    ([np.zeros((4, 4, 3))], [""], r"names\[0\]: '' is not a non-empty string"),
    ([np.zeros((2, 2, 3))] * (MAX_TEXTURES + 1), [f"t{i}" for i in range(MAX_TEXTURES + 1)],
     r"images: 65 textures, more than MAX_TEXTURES = 64"),
])
def test_store_errors_name_the_field(images, names, pattern):
    with pytest.raises(ValueError, match=pattern):
        build_store(images, names)
