"""The scene's atmosphere: haze, layered fog and a coarse cloud layer, as the scene file gives
them (docs/scene-format.md "haze", "fog", "clouds"). The stages that draw them are
background/ (haze, clouds) and fog/.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Haze:
    """Scene haze (docs/scene-format.md "haze").

    Attributes:
        visibility_m: half-haze distance of a horizontal path at base_height_m, metres (> 0).
        scale_height_m: height over which the haze thins by e, metres (> 0; inf = homogeneous).
        base_height_m: world z where visibility_m holds.
        colour: (3,) float32 linear RGB of the haze.
    """

    visibility_m: float
    scale_height_m: float
    base_height_m: float
    colour: np.ndarray


#: Extinction coefficient times meteorological visibility (Koschmieder: the distance at which
#: a black object keeps 2 % contrast), for scenes that give the strata as visibilities.
KOSCHMIEDER = -math.log(0.02)

#: Most sample planes a scene may declare (the structure is a coarse, smooth function).
MAX_FOG_PLANES = 100_000


@dataclass(frozen=True)
class Fog:
    """Scene fog (docs/scene-format.md "fog").

    Attributes:
        axis: (3,) float64 unit vector perpendicular to the strata (world).
        origin: (3,) float64 world point on sample plane 0.
        spacing_m: distance between sample planes along the axis, metres (> 0).
        extinction: (N,) float64 extinction coefficient at each sample plane, 1/metres (>= 0).
        colour: (3,) float32 linear RGB of the fog.
        table_spacing_m: spacing of the per-frame resample planes, metres (None: spacing_m /
            TABLE_SUBDIVISION).
    """

    axis: np.ndarray
    origin: np.ndarray
    spacing_m: float
    extinction: np.ndarray
    colour: np.ndarray
    table_spacing_m: float | None = None

    def __post_init__(self) -> None:
        axis = np.asarray(self.axis, np.float64)
        norm = float(np.linalg.norm(axis))
        if not (np.isfinite(axis).all() and norm > 0.0):
            raise ValueError(f"fog.axis: expected a nonzero finite vector, got {axis.tolist()}")
        object.__setattr__(self, "axis", axis / norm)
        object.__setattr__(self, "origin", np.asarray(self.origin, np.float64))
        ext = np.atleast_1d(np.asarray(self.extinction, np.float64))
        if ext.ndim != 1 or not (np.isfinite(ext).all() and (ext >= 0.0).all()):
            raise ValueError(f"fog.extinction_per_m: expected finite values >= 0, got {ext.tolist()}")
        object.__setattr__(self, "extinction", ext)
        if not (math.isfinite(self.spacing_m) and self.spacing_m > 0.0):
            raise ValueError(f"fog.spacing_m: expected a finite value > 0, got {self.spacing_m}")
        t = self.table_spacing_m
        if t is not None and not (math.isfinite(t) and t > 0.0):
            raise ValueError(f"fog.table_spacing_m: expected a finite value > 0, got {t}")


@dataclass(frozen=True)
class Clouds:
    """A coarse cloud database: node grids, interpolated bilinearly inside each cell like the
    terrain's corners, so cloud edges thin out and shapes round off instead of showing cells.

    Attributes:
        origin: (2,) float64 world x, y of node (0, 0), metres.
        cell_m: node spacing, metres.
        base_m, top_m: (ny + 1, nx + 1) float32 world heights of the cloud slab at each node.
        density: (ny + 1, nx + 1) float32 extinction inside the cloud at each node, 1/metres
            (0: clear sky).
        colour: (3,) float32 linear RGB of the cloud's sunlit top; its base is darker
            (BASE_SHADE of it).
    """

    origin: np.ndarray
    cell_m: float
    base_m: np.ndarray
    top_m: np.ndarray
    density: np.ndarray
    colour: np.ndarray


def cloud_layer(*, extent_m: tuple[float, float, float, float], cell_m: float, base_m: float,
                thickness_m: float, cover: float, extinction_per_m: float, colour: np.ndarray,
                seed: int) -> Clouds:
    """A procedural cumulus layer: smooth value noise over the nodes, thresholded to `cover`.

    Args:
        extent_m: (x0, y0, x1, y1) world metres covered.
        cell_m: node spacing, metres.
        base_m: cloud base, world z metres.
        thickness_m: thickness of the thickest cloud, metres.
        cover: share of the nodes holding cloud, 0..1.
        extinction_per_m: extinction inside the thickest part of a cloud, 1/metres.
        colour: (3,) linear RGB of a sunlit cloud top.
        seed: the noise seed (the same seed gives the same clouds on every machine).
    """
    x0, y0, x1, y1 = extent_m
    nx = max(1, int(np.ceil((x1 - x0) / cell_m)))
    ny = max(1, int(np.ceil((y1 - y0) / cell_m)))
    rng = np.random.default_rng(seed)
    # Value noise: random lattices every 6 and 2 nodes, smoothstep-interpolated.
    noise = np.zeros((ny + 1, nx + 1))
    for period, weight in ((6, 0.7), (2, 0.3)):
        lat = rng.random(((ny + 1) // period + 3, (nx + 1) // period + 3))
        yy, xx = np.mgrid[0:ny + 1, 0:nx + 1] / period
        iy, ix = yy.astype(int), xx.astype(int)
        fy, fx = yy - iy, xx - ix
        fy, fx = fy * fy * (3 - 2 * fy), fx * fx * (3 - 2 * fx)
        noise += weight * ((1 - fy) * ((1 - fx) * lat[iy, ix] + fx * lat[iy, ix + 1])
                           + fy * ((1 - fx) * lat[iy + 1, ix] + fx * lat[iy + 1, ix + 1]))
    # The cover-quantile of the noise is the threshold: that share of nodes holds cloud.
    cover = float(np.clip(cover, 0.0, 1.0))
    if cover <= 0.0:
        amount = np.zeros_like(noise)
    else:
        threshold = np.quantile(noise, 1.0 - cover)
        span = max(float(noise.max() - threshold), 1e-9)  # guard: a flat field
        amount = np.clip((noise - threshold) / span, 0.0, 1.0)
    # Cumulus: flat-ish bases, domed tops; thin edges are thin in height and in density.
    thick = thickness_m * np.sqrt(amount)
    base = base_m + 0.2 * thickness_m * (1.0 - np.sqrt(amount)) * (amount > 0)
    return Clouds(origin=np.array([x0, y0], np.float64), cell_m=float(cell_m),
                  base_m=base.astype(np.float32), top_m=(base + thick).astype(np.float32),
                  density=(extinction_per_m * np.sqrt(amount)).astype(np.float32),
                  colour=np.asarray(colour, np.float32))
