"""Procedural textures: images made in code rather than photographed, periodic by construction.

They live here, below the pipeline, because the bundled asphalt (build_textures.py) is made
from them and this package may not import the pipeline; the pipeline's texture store offers
them as ``channel_worker.pipeline.scene.textures.procedural``.

Every kind is synthesised on the torus: noise is shaped in the Fourier domain (whose basis is
periodic in the image's side), and every drawn feature (crack, patch, square) is placed with
wrapped coordinates, so a texture repeats across its borders without a seam.
"""

from __future__ import annotations

import math

import numpy as np

#: The kinds procedural() makes. "asphalt": fine aggregate with a few cracks and repair
#: patches, dark grey; "noise": band-limited fractional Brownian motion, mid grey; "checker":
#: 8 x 8 squares of two greys, for tests.
PROCEDURAL_KINDS = ("asphalt", "noise", "checker")

#: Largest side procedural() makes: the texture store's own largest side (it would only be
#: resampled down).
MAX_PROCEDURAL_SIDE = 1024


def procedural(kind: str, size: int, seed: int) -> np.ndarray:
    """A procedural texture.

    Args:
        kind: one of PROCEDURAL_KINDS.
        size: side in texels, a power of two from 8 to MAX_PROCEDURAL_SIDE (the texture
            store's sides are powers of two, so it is stored without resampling).
        seed: seed of the random generator (>= 0): the same seed gives the same image.

    Returns:
        (size, size, 3) float32 linear RGB in [0, 1], periodic in both axes.

    Raises:
        ValueError: an unknown kind, a bad size or seed (naming the argument and value).
    """
    if kind not in PROCEDURAL_KINDS:
        raise ValueError(f"kind: {kind!r} is not one of {', '.join(PROCEDURAL_KINDS)}")
    if not isinstance(size, int) or size < 8 or size > MAX_PROCEDURAL_SIDE or size & (size - 1):
        raise ValueError(f"size: {size!r} is not a power of two from 8 to {MAX_PROCEDURAL_SIDE}")
    if not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: {seed!r} is not an integer >= 0")
    rng = np.random.default_rng(seed)
    if kind == "checker":
        image = _checker(size)
    elif kind == "noise":
        grey = 0.18 * (1.0 + 0.35 * _unit(fbm(size, rng, lowest=2.0, highest=0.25 * size, slope=1.0)))
        image = np.repeat(grey[..., None], 3, axis=2)
    else:
        image = _asphalt(size, rng)
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def fbm(size: int, rng: np.random.Generator, *, lowest: float, highest: float, slope: float) -> np.ndarray:
    """Periodic band-limited fractional Brownian motion: white noise whose amplitude spectrum
    falls as f**-slope between lowest and highest cycles per image, nothing outside.

    Band-limiting the top keeps the texture's finest frequency (and so where the pipeline
    fades it) a property of the recipe rather than of the random draw; the bottom limit keeps a
    few huge blobs from setting the whole tile's tone. Returns (size, size) float64, mean 0.
    """
    white = rng.standard_normal((size, size))
    f = np.hypot(*np.meshgrid(np.fft.fftfreq(size) * size, np.fft.fftfreq(size) * size, indexing="ij"))
    # f == 0 (the mean) is outside every band (lowest > 0), so the power law never sees it.
    band = (f >= lowest) & (f <= highest)
    gain = np.zeros_like(f)
    gain[band] = f[band] ** -slope
    return np.fft.ifft2(np.fft.fft2(white) * gain).real


def _unit(field: np.ndarray) -> np.ndarray:
    """field scaled to standard deviation 1 (a zero field stays zero)."""
    std = float(field.std())
    # Guard: a field without variance (every value equal) has nothing to scale.
    return field / std if std > 0.0 else field


def _checker(size: int) -> np.ndarray:
    """8 x 8 squares of linear 0.2 and 0.6, size / 8 texels each: an even count per side, so
    the pattern repeats across the borders."""
    cell = size // 8
    i = np.arange(size) // cell
    grey = np.where((i[:, None] + i[None, :]) % 2 == 0, 0.2, 0.6)
    return np.repeat(grey[..., None], 3, axis=2)


def _wrapped_offset(coord: np.ndarray, centre: float, size: int) -> np.ndarray:
    """coord - centre on a circle of circumference size, in [-size/2, size/2): distances that
    see the tile's copies, so shapes crossing a border reappear on the other side."""
    return (coord - centre + 0.5 * size) % size - 0.5 * size


def _asphalt(size: int, rng: np.random.Generator) -> np.ndarray:
    """Dark grey aggregate (fine noise over a gentle fBm), a few repair patches of another tone,
    and a few dark cracks; linear RGB."""
    # Aggregate: stones a texel or two across (a band up to 0.35 cycles per texel, under the
    # texel grid's 0.5) over a slow variation of the binder.
    aggregate = _unit(fbm(size, rng, lowest=0.12 * size, highest=0.35 * size, slope=0.0))
    binder = _unit(fbm(size, rng, lowest=1.0, highest=0.06 * size, slope=1.5))
    tone = 1.0 + 0.22 * aggregate + 0.10 * binder
    yy, xx = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5, indexing="ij")
    for _ in range(3):
        cx, cy = rng.uniform(0, size, 2)
        rx, ry = rng.uniform(0.08, 0.2, 2) * size
        dx, dy = _wrapped_offset(xx, cx, size) / rx, _wrapped_offset(yy, cy, size) / ry
        # A soft-edged rounded rectangle (a superellipse), a newer, darker or older, lighter mix.
        inside = np.clip((1.0 - (dx**4 + dy**4)) * 4.0, 0.0, 1.0)
        tone *= 1.0 + inside * rng.choice([-0.18, 0.15])
    cracks = np.zeros((size, size))
    for _ in range(4):
        _crack(cracks, rng, size)
    tone *= 1.0 - 0.55 * np.clip(cracks, 0.0, 1.0)
    # Asphalt reflects about a tenth of the light; a slightly warm grey.
    return 0.10 * tone[..., None] * np.array([1.0, 0.98, 0.94])


def _crack(mask: np.ndarray, rng: np.random.Generator, size: int) -> None:
    """Add one crack to mask: a random walk of unit steps whose heading wanders, each point
    splatted bilinearly at wrapped coordinates (so the crack is about two texels wide and
    continues across the borders)."""
    x, y = rng.uniform(0, size, 2)
    heading = rng.uniform(0, 2 * math.pi)
    for _ in range(int(rng.uniform(0.3, 0.7) * size)):
        heading += rng.normal(0.0, 0.25)
        x += math.cos(heading)
        y += math.sin(heading)
        fx, fy = x - 0.5, y - 0.5
        ix, iy = math.floor(fx), math.floor(fy)
        ax, ay = fx - ix, fy - iy
        for ddx, wx in ((0, 1 - ax), (1, ax)):
            for ddy, wy in ((0, 1 - ay), (1, ay)):
                mask[(iy + ddy) % size, (ix + ddx) % size] += wx * wy


def cross_fade_tileable(image: np.ndarray, margin: int) -> np.ndarray:
    """A periodic image from a non-periodic one, without mirroring: its last `margin` rows and
    columns are cross-faded into its first ones, and cut off.

    Output texel x < margin is a blend of source x (weight a rising from 0 to 1) and source
    x + n (n = width - margin), so output column n - 1 (= source n - 1) is followed across the
    wrap by a column close to source n: the seam is a seam the photograph already had. The
    blend mixes deviations from the mean with weights normalised to keep their variance
    (a / sqrt(a^2 + b^2)): a plain linear blend of two unrelated patches halves their contrast
    in the middle of the band, a visible stripe when the texture repeats.

    Args:
        image: (H, W, C) float, linear.
        margin: band width in texels, 1 <= margin < min(H, W) / 2.

    Returns:
        (H - margin, W - margin, C) float64.
    """
    if margin < 1 or 2 * margin >= min(image.shape[0], image.shape[1]):
        raise ValueError(f"margin: {margin} is not from 1 to under half the side {min(image.shape[:2])}")
    out = np.asarray(image, np.float64)
    for axis in (0, 1):
        out = _fade_axis(out, margin, axis)
    return out


def _fade_axis(image: np.ndarray, margin: int, axis: int) -> np.ndarray:
    moved = np.moveaxis(image, axis, 0)
    n = moved.shape[0] - margin
    mean = moved.mean(axis=(0, 1), keepdims=True)
    out = moved[:n].copy()
    a = ((np.arange(margin) + 0.5) / margin).reshape((margin,) + (1,) * (moved.ndim - 1))
    b = 1.0 - a
    # a and b are never both 0 (a + b = 1), so the norm is at least sqrt(1/2).
    norm = np.sqrt(a * a + b * b)
    out[:margin] = mean + (a * (moved[:margin] - mean) + b * (moved[n:] - mean)) / norm
    return np.moveaxis(out, 0, axis)
