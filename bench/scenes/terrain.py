"""A large, fine procedural terrain for bench/bench_terrain.py, and terrain-only scenes.

    python bench/scenes/terrain.py            # build (or find) the cached database, print it
    python bench/scenes/terrain.py --preview preview.png   # also write a map of level 3

`fractal_terrain()` is a 4096 x 4096-voxel database at 3 m (12.3 x 12.3 km, 6 levels of
128 x 128-voxel pages, no pruning, no patterns) generated from FRACTAL_RECIPE, deterministic
for a seed:

- heights: fractal hills (spectral synthesis, power spectrum k^-4.4) plus ridged mountains
  (1 - |fBm|, crests slightly rounded, squared) plus fine roughness (k^-3, from 400 m
  wavelength down to one voxel), 0 .. about 900 m, median slope about 22 degrees;
- colours (linear RGB): a palette by height (meadow, forest, scrub, rock, snow) jittered by
  noise so no contour line shows, hill-shaded by the slope (sun from the north-west), times a
  pink-noise texture (k^-1: every octave as strong as the next, so there is detail at every
  scale from the whole map down to one voxel), and a patchwork of fields on the low, gentle
  ground (120 m plots with their own tint: sharp edges);

so every level of the database has something to resolve and level switching shows in the
error. Building takes about a minute and a peak of about 4 GB; the result (about 630 MB) is
cached in the bundled terrain's cache directory ($IG_CACHE_DIR, else ~/.cache/ig-rig) under a
name keyed by the recipe, this file's and the builder's source, and loaded memory-mapped.

`terrain_scene(terrain, haze=..., clouds=...)` is a Database with no polygons, that terrain,
and optionally haze and a cloud layer; `eyepoint_above(terrain, x, y, agl, heading, pitch)` an
eyepoint a given height above the terrain surface at a ground point.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

# Runnable from a plain checkout too.
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from channel_worker.pipeline.background.terrain import surface_height
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.load import parse_scene
from channel_worker.pipeline.scene.terrain.build import build_terrain
from channel_worker.pipeline.scene.terrain.bundled import cache_dir, recipe_key
from channel_worker.pipeline.scene.terrain.database import TerrainDatabase
from channel_worker.pipeline.scene.terrain.store import build_cached, load_terrain
from services.rig.frame import Eyepoint

FRACTAL_RECIPE: dict[str, Any] = {
    "generator": "bench/scenes/terrain.py ridged fBm/1",
    "voxels": 4096,            # per side (level 0)
    "spacing_m": 3.0,
    "page_size": 128,
    "seed": 20020,
    "hills_m": 120.0,          # std of the smooth hills
    "ridges_m": 280.0,         # height of a full ridge
    "roughness_m": 1.5,        # std of the fine roughness
    "field_voxels": 40,        # side of a field plot (120 m)
}

#: Linear-RGB palette by normalised height: meadow, forest, scrub, rock, snow.
PALETTE = (
    (0.00, (0.090, 0.180, 0.040)),
    (0.30, (0.035, 0.090, 0.020)),
    (0.55, (0.120, 0.110, 0.050)),
    (0.75, (0.230, 0.220, 0.200)),
    (0.86, (0.330, 0.320, 0.310)),
    (0.93, (0.700, 0.720, 0.760)),
    (1.00, (0.800, 0.820, 0.860)),
)


def fbm(n: int, beta: float, rng: np.random.Generator, *, k_min: float = 1.0) -> np.ndarray:
    """(n, n) float64 periodic fractal noise of power spectrum k^-beta (k in cycles per tile,
    below k_min nothing), mean 0, standard deviation 1."""
    ky = np.fft.fftfreq(n) * n
    kx = np.fft.rfftfreq(n) * n
    k = np.hypot(ky[:, None], kx[None, :])
    amp = np.where(k >= k_min, np.maximum(k, 1e-9) ** (-0.5 * beta), 0.0)
    spec = amp * (rng.standard_normal(k.shape) + 1j * rng.standard_normal(k.shape))
    del k, amp
    field = np.fft.irfft2(spec, s=(n, n))
    del spec
    field -= field.mean()
    field /= field.std()
    return field


def _nodes(a: np.ndarray) -> np.ndarray:
    """(n, n) periodic voxel-lattice field -> (n + 1, n + 1) nodes (the tile wraps)."""
    return np.pad(a, ((0, 1), (0, 1)), mode="wrap")


def fractal_nodes(recipe: dict[str, Any] = FRACTAL_RECIPE) -> tuple[np.ndarray, np.ndarray]:
    """(heights (n + 1, n + 1) float64 metres, colours (n + 1, n + 1, 3) float64 linear RGB)."""
    n = int(recipe["voxels"])
    spacing = float(recipe["spacing_m"])
    rng = np.random.default_rng(int(recipe["seed"]))
    # Heights: hills + ridges + roughness.
    h = recipe["hills_m"] * fbm(n, 4.4, rng, k_min=1.5)
    m = fbm(n, 4.4, rng, k_min=3.0)
    ridge = np.clip(1.0 - np.sqrt(m * m + 0.04), 0.0, None)  # crests rounded over |m| < 0.2
    del m
    h += recipe["ridges_m"] * ridge * ridge
    del ridge
    h += recipe["roughness_m"] * fbm(n, 3.0, rng, k_min=32.0)
    h = _nodes(h)
    h -= h.min()
    t = h / h.max()

    # Slope and hill-shade from the node gradient (sun from the north-west, 45 degrees up).
    gy, gx = np.gradient(h, spacing)
    slope = np.hypot(gx, gy)
    sun = np.array([-math.sqrt(0.5), math.sqrt(0.5), 1.0]) / math.sqrt(2.0)
    shade = np.clip((-gx * sun[0] - gy * sun[1] + sun[2]) / np.sqrt(1.0 + slope * slope), 0.0, 1.0)
    del gx, gy

    # Palette by height, the height jittered by noise so that no contour line shows.
    jitter = _nodes(fbm(n, 1.6, rng, k_min=4.0))
    tj = np.clip(t + 0.05 * jitter, 0.0, 1.0)
    del jitter
    stops = np.array([s for s, _ in PALETTE])
    colours = np.empty(h.shape + (3,), np.float64)
    for ch in range(3):
        colours[..., ch] = np.interp(tj, stops, [c[ch] for _, c in PALETTE])
    # Steep ground shows rock.
    rock = np.clip((slope - 1.0) / 0.7, 0.0, 1.0)[..., None]
    colours = colours * (1.0 - rock) + np.array(PALETTE[3][1]) * rock
    del rock

    # Fields: plots of field_voxels on low, gentle ground, each with its own tint.
    f = int(recipe["field_voxels"])
    plots = -(-(n + 1) // f)
    tint = 0.65 + 0.7 * rng.random((plots, plots, 3))
    tint[..., 2] = 0.8 + 0.4 * tint[..., 2] / 1.35
    idx = np.arange(n + 1) // f
    field_tint = tint[idx[:, None], idx[None, :]]
    low = ((tj < 0.3) & (slope < 0.25))[..., None]
    colours = np.where(low, colours * field_tint, colours)
    del field_tint, low, tj, slope

    # Texture at every scale: pink noise (every octave equally strong), multiplicative.
    tex = _nodes(fbm(n, 1.0, rng, k_min=1.0))
    colours *= np.exp(0.3 * tex)[..., None]
    del tex
    colours *= (0.35 + 0.9 * shade)[..., None]
    np.clip(colours, 0.0, 1.0, out=colours)
    return h, colours


def fractal_terrain_path(recipe: dict[str, Any] = FRACTAL_RECIPE, *, verbose: bool = True) -> Path:
    """The database's cached directory, built on first use (about a minute)."""
    digest = hashlib.sha256(recipe_key(recipe).encode())
    digest.update(Path(__file__).read_bytes())  # a changed generator rebuilds
    target = cache_dir() / f"bench-fractal-{digest.hexdigest()[:16]}.igt"
    if verbose and not (target / "terrain.json").is_file():
        print(f"building the bench terrain ({recipe['voxels']}^2 voxels at "
              f"{recipe['spacing_m']:g} m) into {target} ...", file=sys.stderr, flush=True)
    return build_cached(target, lambda: _build_fractal(recipe))


def _build_fractal(recipe: dict[str, Any]) -> TerrainDatabase:
    # The node grids go out of scope before the database is saved (memory peak).
    heights, colours = fractal_nodes(recipe)
    n = int(recipe["voxels"])
    half = 0.5 * n * float(recipe["spacing_m"])
    return build_terrain(heights, colours, spacing_m=float(recipe["spacing_m"]),
                         origin=(-half, -half, 0.0), page_size=int(recipe["page_size"]),
                         info={"source": "procedural (bench/scenes/terrain.py)",
                               "licence": "generated", "recipe": recipe})


def fractal_terrain(recipe: dict[str, Any] = FRACTAL_RECIPE) -> TerrainDatabase:
    """The bench database, memory-mapped (built and cached first if needed)."""
    return load_terrain(fractal_terrain_path(recipe), mmap=True)


def terrain_scene(terrain: TerrainDatabase | None, *, sky: str = "#a4c8ea",
                  earth: str = "#5f8a3e", haze: dict | None = None,
                  clouds: dict | None = None) -> Database:
    """A scene without polygons: the terrain, optional haze and clouds (scene-format dicts),
    flat lighting (ambient 1)."""
    doc: dict[str, Any] = {"format": "ig-scene/1", "name": "bench terrain",
                           "sky": {"colour": sky}, "earth": {"colour": earth},
                           "lighting": {"ambient": 1.0}, "models": {}, "instances": []}
    if haze is not None:
        doc["haze"] = haze
    if clouds is not None:
        doc["clouds"] = clouds
    db = parse_scene(doc, source="bench terrain scene")
    return dataclasses.replace(db, terrain=terrain) if terrain is not None else db


def ground_z(terrain: TerrainDatabase, x: float, y: float) -> float:
    """World z of the terrain surface at world (x, y) (finest level present)."""
    z = surface_height(terrain, x - float(terrain.origin[0]), y - float(terrain.origin[1]))
    if z is None:
        raise ValueError(f"({x}, {y}) is outside the terrain")
    return z + float(terrain.origin[2])


def eyepoint_above(terrain: TerrainDatabase, x: float, y: float, agl_m: float, *,
                   heading_deg: float, pitch_deg: float, roll_deg: float = 0.0) -> Eyepoint:
    """An eyepoint agl_m metres above the terrain surface at world (x, y)."""
    return Eyepoint(position=np.array([x, y, ground_z(terrain, x, y) + agl_m], np.float64),
                    heading_deg=heading_deg, pitch_deg=pitch_deg, roll_deg=roll_deg)


def describe(terrain: TerrainDatabase) -> dict[str, Any]:
    """Size, levels and pages of a database, for the records."""
    ex, ey = terrain.extent_m
    return {"voxels": [int(terrain.nx), int(terrain.ny)], "spacing_m": float(terrain.spacing_m),
            "extent_m": [float(ex), float(ey)], "levels": int(terrain.levels),
            "page_size": int(terrain.page_size), "pages": int(terrain.z.shape[0]),
            "z_range_m": [float(terrain.z_min), float(terrain.z_max)],
            "bytes": int(terrain.z.nbytes + terrain.rgb.nbytes + terrain.pattern.nbytes)}


def main(argv: list[str] | None = None) -> int:
    """Build or find the cached database and print what it is."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--preview", type=Path, help="write a PNG map of one level's colours")
    parser.add_argument("--level", type=int, default=3, help="level of the preview (default 3)")
    args = parser.parse_args(argv)
    path = fractal_terrain_path()
    terrain = load_terrain(path)
    print(path)
    print(json.dumps(describe(terrain), indent=1))
    if args.preview:
        from services.rig.image_io import write_image

        lv, p = args.level, terrain.page_size
        nx, ny = terrain.level_size(lv)
        px, py = int(terrain.pages_x[lv]), int(terrain.pages_y[lv])
        lut = (np.arange(256) / 255.0)
        lut = np.where(lut <= 0.04045, lut / 12.92, ((lut + 0.055) / 1.055) ** 2.4)
        img = np.zeros((py * p, px * p, 3), np.float32)
        for j in range(py):
            for i in range(px):
                page = terrain.page_index(lv, i, j)
                img[j * p:(j + 1) * p, i * p:(i + 1) * p] = lut[terrain.rgb[page, :, :, 0]]
        write_image(args.preview, img[:ny, :nx][::-1].copy())  # north up
        print(f"wrote {args.preview}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
