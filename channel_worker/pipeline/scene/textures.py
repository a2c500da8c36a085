"""Texture stores: the images a face's texture code refers to, as the kernels sample them.

After *An image generator* (docs/references.md): every texture lives in one store; a face
carries a texture code naming up to three textures in priority order; a fine texture fades
out as its finest spatial frequency approaches the sampling rate, so it never aliases. This
module builds the store; texture_sampling.py samples it and computes the fade.

What is stored is a modulation *signal*, not a colour: ``signal = rgb / mean_rgb - 1`` per
channel, so a face of colour c shows ``c * (1 + signal)``: the image's relative contrast on
the face's own colour (a face coloured like ``mean_rgb`` looks like the image). Each texture
is stored with its mip pyramid (L. Williams, *Pyramidal parametrics*) for the trilinear
sampler. docs/textures.md describes the signal, the pyramid, the finest frequency and the
fade.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
import OpenImageIO as oiio

from channel_worker.data.texture_synthesis import PROCEDURAL_KINDS, procedural
from services.rig.colour import srgb_to_linear

__all__ = [
    "BUNDLED_TEXTURES",
    "MAX_LEVELS",
    "MAX_TEXTURES",
    "PROCEDURAL_KINDS",
    "TextureStore",
    "build_store",
    "bundled_texture_path",
    "empty_store",
    "load_image",
    "procedural",
]

#: Most textures one store holds. A texture code names three of them, and 64 fit six bits
#: each; the bound also caps the store's memory: 64 textures of 1024 x 1024 with their
#: pyramids are 1.43 GB of float32 texels (four channels), held by every worker process.
MAX_TEXTURES = 64

#: Channels of a stored texel: the signal's r, g, b and their mean (TextureStore.texels).
TEXEL_CHANNELS = 4

#: Largest side of a stored texture (texels); larger images are resampled down to it.
MAX_STORE_SIDE = 1024

#: Mip levels per texture in TextureStore.level: 1024 -> 512 -> ... -> 1 is 11 levels.
MAX_LEVELS = int(math.log2(MAX_STORE_SIDE)) + 1

#: Largest side load_image and build_store accept (pixels): four times the stored side, which
#: area resampling still uses fully; anything larger is a mistake (a whole orthophoto as a
#: repeating texture) that would cost seconds and hundreds of MB at every start.
MAX_IMAGE_SIDE = 4096

#: Fraction of a texture's non-DC power below its finest significant frequency.
FINEST_POWER_FRACTION = 0.99

#: A channel whose mean is at most this (linear) has no contrast to speak of relative to its
#: mean (a black channel): its signal is 0 rather than a division by ~0.
MEAN_FLOOR = 1e-6

#: Textures shipped in channel_worker/data/textures (LICENSE.md there names their sources).
BUNDLED_TEXTURES = ("asphalt", "brick", "grass", "gravel")


class TextureStore(NamedTuple):
    """Every texture of a scene, as the kernels take it (whole, as one argument).

    Attributes:
        texels: (M, 4) float32: every mip level of every texture, each level row-major (texel
            (x, y) of a level at offset + y * width + x), concatenated. The modulation signal
            ``rgb / mean_rgb - 1``, not colour, and in channel 3 its mean over r, g and b:
            a mono code (one signal for all three colours) reads one channel, not three (the
            terrain's detail reads a texel for nearly every pixel).
        level: (T, MAX_LEVELS, 3) int64: per texture t, per level l: (offset of texel (0, 0) in
            texels, log2 width, log2 height). Level 0 is full size; levels past the texture's
            last repeat its last (1 x 1) level.
        levels: (T,) int64 how many levels texture t has.
        finest: (T,) float64 finest significant spatial frequency of level 0 (cycles per texel,
            0 to 0.5): the radial frequency below which FINEST_POWER_FRACTION of the signal's
            non-DC power lies; 0 for a texture without contrast.
        mean_rgb: (T, 3) float32 mean linear RGB of the source image: a face coloured like this
            looks like the image.
        names: the textures' names, index = texture number.

    The kernels never take the store itself (numba would type its names by their number):
    FrameConstants carries texels, level, levels and finest (geometry/view.frame_constants).
    """

    texels: np.ndarray
    level: np.ndarray
    levels: np.ndarray
    finest: np.ndarray
    mean_rgb: np.ndarray
    names: tuple[str, ...]


def empty_store() -> TextureStore:
    """The store of a scene without textures (T = 0): 1-element arrays (one 1 x 1 texture of
    signal 0, no contrast) so that kernels take one type whether or not a scene has textures."""
    return TextureStore(
        texels=np.zeros((1, TEXEL_CHANNELS), np.float32),
        level=np.zeros((1, MAX_LEVELS, 3), np.int64),
        levels=np.ones(1, np.int64),
        finest=np.zeros(1, np.float64),
        mean_rgb=np.ones((1, 3), np.float32),
        names=(),
    )


def bundled_texture_path(name: str) -> Path:
    """The PNG of a bundled texture (one of BUNDLED_TEXTURES)."""
    if name not in BUNDLED_TEXTURES:
        raise ValueError(f"name: {name!r} is not a bundled texture ({', '.join(BUNDLED_TEXTURES)})")
    return Path(__file__).resolve().parents[2] / "data" / "textures" / f"{name}.png"


def load_image(path: str | Path) -> np.ndarray:
    """Read an image file as linear RGB, through OpenImageIO.

    Integer files (8- and 16-bit PNG, JPEG, TIFF) are taken as sRGB-encoded and decoded
    (IEC 61966-2-1); float files (EXR, float TIFF) as linear already. A grey image is
    replicated to three channels (grey + alpha: the grey), alpha is dropped.

    Args:
        path: the image file.

    Returns:
        (H, W, 3) float32 linear RGB.

    Raises:
        ValueError: naming the path: missing, unreadable, zero size, a side over
            MAX_IMAGE_SIDE, NaN or infinite values.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such image file")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise ValueError(f"{path}: unreadable image: {oiio.geterror()}")
    try:
        spec = inp.spec()
        width, height, channels = spec.width, spec.height, spec.nchannels
        if width <= 0 or height <= 0 or channels <= 0:
            raise ValueError(f"{path}: zero size ({width} x {height}, {channels} channels)")
        if max(width, height) > MAX_IMAGE_SIDE:
            raise ValueError(f"{path}: {width} x {height} has a side over {MAX_IMAGE_SIDE}")
        # The size is checked before reading: a huge image is refused without decoding it.
        pixels = inp.read_image(0, 0, 0, channels, oiio.FLOAT)
        if pixels is None:
            raise ValueError(f"{path}: unreadable image: {inp.geterror()}")
        encoded = spec.format.basetype not in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    finally:
        inp.close()
    data = np.asarray(pixels, np.float32).reshape(height, width, channels)
    if not np.isfinite(data).all():
        raise ValueError(f"{path}: NaN or infinite values in the image")
    rgb = data[..., :3] if channels >= 3 else np.repeat(data[..., :1], 3, axis=2)
    if encoded:
        rgb = srgb_to_linear(rgb)
    return np.ascontiguousarray(rgb, dtype=np.float32)


def build_store(images: Sequence[np.ndarray], names: Sequence[str]) -> TextureStore:
    """The store of images, texture number = index.

    Each image is taken as one period of a repeating texture (the samplers wrap): it is
    resampled periodically to power-of-two sides (the nearest power of two in ratio, at most
    MAX_STORE_SIDE: area-weighted down, linear up), turned into the signal
    ``rgb / mean - 1`` (a channel whose mean is at most MEAN_FLOOR gets signal 0), and
    reduced by 2 x 2 boxes down to 1 x 1 (a side that reaches 1 stays 1 while the other
    halves on), every level keeping the signal's mean of 0.

    Args:
        images: (H, W, 3) linear RGB images, finite, >= 0, sides 1 to MAX_IMAGE_SIDE.
        names: one distinct non-empty name per image.

    Raises:
        ValueError: naming the field and value (and the image by index and name): more than
            MAX_TEXTURES images, names not matching images, wrong shape, NaN/inf, negative.
    """
    if len(images) != len(names):
        raise ValueError(f"names: {len(names)} names for {len(images)} images")
    if len(images) > MAX_TEXTURES:
        raise ValueError(f"images: {len(images)} textures, more than MAX_TEXTURES = {MAX_TEXTURES}")
    for i, name in enumerate(names):
        if not isinstance(name, str) or not name:
            raise ValueError(f"names[{i}]: {name!r} is not a non-empty string")
        if name in names[:i]:
            raise ValueError(f"names[{i}]: {name!r} is given twice")
    if not images:
        return empty_store()
    chunks: list[np.ndarray] = []
    level = np.zeros((len(images), MAX_LEVELS, 3), np.int64)
    levels = np.zeros(len(images), np.int64)
    finest = np.zeros(len(images), np.float64)
    mean_rgb = np.zeros((len(images), 3), np.float32)
    offset = 0
    for t, (image, name) in enumerate(zip(images, names, strict=True)):
        rgb = _checked(image, f"images[{t}] ({name!r})")
        mean_rgb[t] = rgb.mean(axis=(0, 1))
        base = _resample(rgb, _store_side(rgb.shape[0]), _store_side(rgb.shape[1]))
        signal = _signal(base)
        finest[t] = finest_frequency(signal)
        pyramid = _pyramid(signal)
        levels[t] = len(pyramid)
        for lv in range(MAX_LEVELS):
            sig = pyramid[min(lv, len(pyramid) - 1)]
            if lv < len(pyramid):
                level[t, lv] = (offset, int(math.log2(sig.shape[1])), int(math.log2(sig.shape[0])))
                flat = sig.reshape(-1, 3)
                chunks.append(np.concatenate([flat, flat.mean(axis=1, keepdims=True)], axis=1))
                offset += sig.shape[0] * sig.shape[1]
            else:
                level[t, lv] = level[t, lv - 1]
    texels = np.concatenate(chunks).astype(np.float32)
    return TextureStore(texels, level, levels, finest, mean_rgb, tuple(names))


def finest_frequency(signal: np.ndarray) -> float:
    """The finest significant spatial frequency of a periodic (H, W, 3) signal, cycles per
    texel: the radial frequency |(fx, fy)| below which FINEST_POWER_FRACTION of the non-DC
    power (summed over channels) lies, at most 0.5.

    The fade compares it with the sampling rate: the last percent of power is left out so
    that a texture is not faded for a trace of fine noise its eye-visible pattern does not
    have. Radial, because a face may be seen along any direction of its texture; capped at
    0.5, the texel grid's Nyquist frequency along an axis, so power in the corners of the
    spectrum (up to 0.71 diagonally) counts as at Nyquist. 0 for a signal with no contrast.
    """
    height, width = signal.shape[:2]
    power = np.zeros((height, width))
    for c in range(signal.shape[2]):
        power += np.abs(np.fft.fft2(signal[..., c])) ** 2
    power[0, 0] = 0.0
    total = float(power.sum())
    # By Parseval, total / (H W)^2 is the signal's mean square; below 1e-12 (an rms of 1e-6,
    # under any 8-bit or half-float step) the texture has no contrast, and what is left is
    # rounding noise with no meaningful spectrum.
    if total <= 1e-12 * float(height * width) ** 2:
        return 0.0
    radius = np.hypot(np.fft.fftfreq(height)[:, None], np.fft.fftfreq(width)[None, :]).ravel()
    order = np.argsort(radius, kind="stable")
    cumulative = np.cumsum(power.ravel()[order])
    k = min(int(np.searchsorted(cumulative, FINEST_POWER_FRACTION * total)), order.size - 1)
    return min(float(radius[order[k]]), 0.5)


def _checked(image: np.ndarray, field: str) -> np.ndarray:
    """image as float64 (H, W, 3), or ValueError naming field."""
    array = np.asarray(image)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError(f"{field}: shape {array.shape} is not (H, W, 3)")
    if min(array.shape[:2]) < 1 or max(array.shape[:2]) > MAX_IMAGE_SIDE:
        raise ValueError(f"{field}: {array.shape[1]} x {array.shape[0]} is not 1 to {MAX_IMAGE_SIDE} on a side")
    if not np.issubdtype(array.dtype, np.number) or np.issubdtype(array.dtype, np.complexfloating):
        raise ValueError(f"{field}: dtype {array.dtype} is not a real number type")
    rgb = array.astype(np.float64)
    if not np.isfinite(rgb).all():
        raise ValueError(f"{field}: NaN or infinite values")
    if rgb.min() < 0.0:
        raise ValueError(f"{field}: negative value {rgb.min():g} (linear RGB is >= 0)")
    return rgb


def _store_side(side: int) -> int:
    """The stored side for an image side: the nearest power of two in ratio (768 -> 1024,
    700 -> 512), at most MAX_STORE_SIDE; side >= 1, so log2 is defined."""
    return min(1 << round(math.log2(side)), MAX_STORE_SIDE)


def _resample(rgb: np.ndarray, height: int, width: int) -> np.ndarray:
    """rgb resampled to height x width, periodically (the image is one period of a tiling)."""
    return _resample_axis(_resample_axis(rgb, height, 0), width, 1)


def _resample_axis(a: np.ndarray, n: int, axis: int) -> np.ndarray:
    """a resampled to n texels along axis, periodically. Down: each output texel averages the
    source interval it covers, partial texels by their overlap (area resampling: the mean is
    kept exactly, nothing above the new Nyquist folds back at full strength). Up: linear
    interpolation between source texel centres, wrapping at the ends."""
    m = a.shape[axis]
    if n == m:
        return a
    index, weight = _periodic_weights(m, n)
    moved = np.moveaxis(a, axis, 0)
    out = np.zeros((n,) + moved.shape[1:])
    for k in range(index.shape[1]):
        out += weight[:, k].reshape((n,) + (1,) * (moved.ndim - 1)) * moved[index[:, k]]
    return np.moveaxis(out, 0, axis)


def _periodic_weights(m: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, k) source indices (mod m) and weights resampling m texels to n; m, n >= 1."""
    scale = m / n  # n >= 1: a side of the store is a power of two
    i = np.arange(n, dtype=np.float64)
    if n < m:
        start, end = i * scale, (i + 1) * scale
        first = np.floor(start).astype(np.int64)
        source = first[:, None] + np.arange(math.ceil(scale) + 1)[None, :]
        overlap = np.minimum(end[:, None], source + 1) - np.maximum(start[:, None], source)
        # scale > 1 here: the weights of one output texel sum to its width, scale.
        return source % m, np.clip(overlap, 0.0, None) / scale
    centre = (i + 0.5) * scale - 0.5
    left = np.floor(centre)
    frac = centre - left
    left_index = left.astype(np.int64)
    return np.stack([left_index % m, (left_index + 1) % m], 1), np.stack([1.0 - frac, frac], 1)


def _signal(rgb: np.ndarray) -> np.ndarray:
    """rgb / mean - 1 per channel: mean 0, the image's contrast relative to its mean."""
    mean = rgb.mean(axis=(0, 1))
    signal = np.zeros_like(rgb)
    for c in range(3):
        # Guard: a channel at most MEAN_FLOOR on average is black; no contrast relative to it.
        if mean[c] > MEAN_FLOOR:
            signal[..., c] = rgb[..., c] / mean[c] - 1.0
    return signal


def _pyramid(signal: np.ndarray) -> list[np.ndarray]:
    """signal and its 2 x 2 box reductions down to 1 x 1; a side that reaches 1 stays 1."""
    pyramid = [signal]
    while pyramid[-1].shape[:2] != (1, 1):
        cur = pyramid[-1]
        if cur.shape[0] > 1:
            cur = 0.5 * (cur[0::2] + cur[1::2])
        if cur.shape[1] > 1:
            cur = 0.5 * (cur[:, 0::2] + cur[:, 1::2])
        pyramid.append(cur)
    return pyramid
