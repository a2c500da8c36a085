"""Build the bundled textures, channel_worker/data/textures/*.png (LICENSE.md there).

    pip install scikit-image                        # a development tool, not a dependency
    python -m channel_worker.data.build_textures    # rewrite the PNGs

grass, gravel and brick are scikit-image's CC0 sample photographs (skimage.data); asphalt is
procedural (texture_synthesis.procedural). scikit-image's brick wall was photographed at an
angle (its long mortar lines converge on a vanishing point): it is rectified first, so that
they are parallel and can repeat, and turned back to horizontal courses (scikit-image turned
it by 90 degrees). Every texture repeats across a face, so each photograph is made tileable:
a period is cut from it where the photograph nearly repeats
(for the bricks, a whole number of courses), the band beyond the cut is cross-faded into the
start (cross_fade_tileable: no mirroring, no visible symmetry), and the result resampled
periodically to SIDE x SIDE. Written as 8-bit sRGB PNGs through the rig's image writer.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from channel_worker.data.texture_synthesis import cross_fade_tileable, procedural
from services.rig.colour import srgb_to_linear
from services.rig.image_io import write_image

#: Where the bundled textures live (channel_worker.pipeline.scene.textures.bundled_texture_path()).
OUTPUT = Path(__file__).resolve().with_name("textures")

#: Side of every bundled texture (texels): a quarter megapixel each keeps the PNGs in the
#: hundreds of KB, and is detail enough for a few metres of ground per repeat.
SIDE = 256

#: Width of the cross-faded band (source pixels of the 512 x 512 photographs).
MARGIN = 48

#: Shortest period cut from a photograph (source pixels): what is left of 512 after the
#: margin leaves a choice of 512 - MARGIN - MIN_PERIOD + 1 cuts per axis.
MIN_PERIOD = 320

#: How far the two cut periods may differ (ratio): they are resampled to one square side, so
#: this bounds the stretch of the picture.
MAX_STRETCH = 1.08

#: Seed of the bundled asphalt.
ASPHALT_SEED = 1

PHOTOGRAPHS = ("brick", "grass", "gravel")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUTPUT, help="directory to write the PNGs to")
    args = parser.parse_args(argv)
    for name in PHOTOGRAPHS:
        rgb = tileable_photograph(name)
        write_image(args.out / f"{name}.png", rgb)
        print(f"{name}: {rgb.shape[1]} x {rgb.shape[0]}")
    write_image(args.out / "asphalt.png", procedural("asphalt", SIDE, ASPHALT_SEED))
    print(f"asphalt: {SIDE} x {SIDE}")
    return 0


def tileable_photograph(name: str) -> np.ndarray:
    """scikit-image's sample photograph `name`, tileable, (SIDE, SIDE, 3) linear RGB."""
    import skimage.data
    import skimage.transform

    encoded = np.asarray(getattr(skimage.data, name)(), np.float64) / 255.0
    if encoded.ndim == 2:
        encoded = encoded[..., None]
    linear = srgb_to_linear(encoded)
    if name == "brick":
        linear = np.rot90(_rectified(linear), -1)
    ny, nx = _periods(linear)
    tile = cross_fade_tileable(linear[: ny + MARGIN, : nx + MARGIN], MARGIN)
    # mode="wrap" makes both the anti-aliasing blur and the interpolation periodic: the tile's
    # first and last texels are neighbours.
    side = skimage.transform.resize(tile, (SIDE, SIDE), order=1, mode="wrap", anti_aliasing=True)
    side = np.clip(side, 0.0, 1.0)
    return np.repeat(side, 3, axis=2) if side.shape[2] == 1 else side


def _rectified(image: np.ndarray) -> np.ndarray:
    """image with the vanishing point of its near-vertical lines moved to infinity: row y is
    scaled about the vanishing point's column so every line through the point becomes
    vertical, and the bottom row is kept as it is.

    The vanishing point (vx, vy), above the image, is found by search: the one that makes the
    column means most contrasted (vertical lines add up down a column; slanted ones smear).
    """
    from scipy import ndimage

    height, width = image.shape[:2]
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)

    def warp(vx: float, vy: float) -> np.ndarray:
        # vy < 0 (the point is above the image), so the bottom row's height - 1 - vy > 0.
        source = vx + (cols - vx) * (rows - vy) / (height - 1 - vy)
        planes = [ndimage.map_coordinates(image[..., c], [rows, source], order=1, mode="nearest")
                  for c in range(image.shape[2])]
        return np.stack(planes, axis=2)

    candidates = [(vx, vy) for vx in np.linspace(0.2 * width, 0.9 * width, 36)
                  for vy in -np.geomspace(0.5 * height, 40 * height, 30)]
    vx, vy = max(candidates, key=lambda v: float(warp(*v).mean(axis=(0, 2)).var()))
    return warp(vx, vy)


def _periods(image: np.ndarray) -> tuple[int, int]:
    """(rows, columns) to cut: where the band after the cut best matches the image's first
    band (least mean square difference), so the cross-fade blends like with like; the two
    within MAX_STRETCH of each other."""
    scores = [_seam_scores(np.moveaxis(image, axis, 0)) for axis in (0, 1)]
    best: tuple[float, int, int] = (np.inf, 0, 0)
    for ny, sy in scores[0].items():
        for nx, sx in scores[1].items():
            # ny, nx >= MIN_PERIOD > 0: the ratio is defined.
            if max(ny, nx) / min(ny, nx) <= MAX_STRETCH and sy + sx < best[0]:
                best = (sy + sx, ny, nx)
    return best[1], best[2]


def _seam_scores(image: np.ndarray) -> dict[int, float]:
    """For each cut n along axis 0: mean square difference of image[n : n + MARGIN] and
    image[:MARGIN]."""
    first = image[:MARGIN]
    return {n: float(np.mean((image[n : n + MARGIN] - first) ** 2))
            for n in range(MIN_PERIOD, image.shape[0] - MARGIN + 1)}


if __name__ == "__main__":
    sys.exit(main())
