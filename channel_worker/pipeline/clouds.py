"""Clouds of seed 002: a coarse cloud database scanned like the ground, blended by range.

Seed 002: "Clouds are inserted by scanning another database ... by the same mechanism. This
separate database describes cloud patterns in three dimensions, similar to the way ground is
described. The cloud pattern is intentionally made very rough to produce a blurry cloud with
translucent edges ... the linear resolution of clouds is one-eighth the resolution of the
earth. ... an interpolation stage smooths the cloud scene between coarse pixels ... Pixel range
comparisons are used to determine what is visible."

Here the cloud database is a coarse 2-D grid of cells, each holding a cloud slab (base and top
heights, metres) of uniform extinction; the terrain stage scans it along the same azimuth
columns as the terrain at one eighth of the pre-image's resolution (CLOUD_FACTOR), integrating
each coarse row's ray through the slabs front to back (_cloud_kernels.scan_clouds_kernel), and
the warp interpolates that coarse image bilinearly and lays it over whatever lies beyond the
cloud's entry range (terrain, sky, earth plane, polygons).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Pre-image texels per cloud texel along each axis (seed 002: one eighth).
CLOUD_FACTOR = 8


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


#: Brightness of a cloud's base relative to its top: light through a cloud dims downwards.
BASE_SHADE = 0.62


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
