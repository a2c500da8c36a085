"""Shaping a placed grid for the image generator: flattened pads (airfields) and forests.

- flatten(): a pad (x0, y0, x1, y1, z, blend_m) in world metres sets every node inside the
  rectangle to z and blends linearly back to the original height over blend_m outside it
  (weight 1 - distance / blend_m, distance to the rectangle).
- tree_mask(): a deterministic pattern mask: clustered forests covering a given fraction of the
  voxels that are gentle enough (slope below a limit) and outside every pad and its blend,
  preferring the higher ground (the bundled region is forested ridges).
- TREE_PATTERN and BUILDING_PATTERN: the vertical patterns of JP H07-76990's pattern memory.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from .database import Pattern, TerrainError

#: Trunk band 0-3 m brown, crown 3-14 m dark green (a forest block seen at voxel scale).
TREE_PATTERN = Pattern("tree", np.array([3.0, 14.0], np.float32),
                       np.array([[0x5a, 0x43, 0x2c], [0x2c, 0x48, 0x22]], np.uint8))
#: Walls 0-8 m light grey, roof 8-10 m dark red.
BUILDING_PATTERN = Pattern("building", np.array([8.0, 10.0], np.float32),
                           np.array([[0xb4, 0xae, 0xa2], [0x7a, 0x3b, 0x2e]], np.uint8))

Pad = tuple[float, float, float, float, float, float]


def check_pad(pad: Sequence[float], where: str = "flatten") -> Pad:
    """A validated pad (x0, y0, x1, y1, z, blend_m): finite, x0 < x1, y0 < y1, blend_m >= 0."""
    if len(pad) != 6:
        raise TerrainError(f"{where}: {list(pad)!r} is not X0,Y0,X1,Y1,Z,BLEND")
    x0, y0, x1, y1, z, blend = (float(v) for v in pad)
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1, z, blend)) or not (x0 < x1 and y0 < y1 and blend >= 0):
        raise TerrainError(f"{where}: {list(pad)!r} is not finite with X0 < X1, Y0 < Y1 and BLEND >= 0")
    return x0, y0, x1, y1, z, blend


def pad_distance(pad: Pad, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distance, metres, from world points (broadcast x, y) to the pad's rectangle (0 inside)."""
    x0, y0, x1, y1 = pad[:4]
    dx = np.maximum(np.maximum(x0 - x, x - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - y, y - y1), 0.0)
    return np.hypot(dx, dy)


def flatten(heights: np.ndarray, x: np.ndarray, y: np.ndarray, pads: Iterable[Sequence[float]]) -> np.ndarray:
    """Heights with every pad applied in turn.

    Args:
        heights: (ny + 1, nx + 1) node heights, world z metres, row 0 south.
        x, y: (nx + 1,) and (ny + 1,) world x, y of the node columns and rows, metres.
        pads: (x0, y0, x1, y1, z, blend_m) world metres each.
    """
    out = np.array(heights, np.float64)
    for raw in pads:
        pad = check_pad(raw)
        d = pad_distance(pad, x[None, :], y[:, None])
        if pad[5] > 0:
            w = np.clip(1.0 - d / pad[5], 0.0, 1.0)
        else:  # no blend (guards the division): a step at the rectangle's edge
            w = (d == 0).astype(np.float64)
        out = w * pad[4] + (1.0 - w) * out
    return out


def voxel_slope_deg(heights: np.ndarray, spacing_m: float) -> np.ndarray:
    """(ny, nx) slope of every voxel from its four corner heights, degrees."""
    sw, se, nw, ne = heights[:-1, :-1], heights[:-1, 1:], heights[1:, :-1], heights[1:, 1:]
    # spacing_m > 0 (every placed grid has one).
    dzdx = ((se - sw) + (ne - nw)) / (2.0 * spacing_m)
    dzdy = ((nw - sw) + (ne - se)) / (2.0 * spacing_m)
    return np.degrees(np.arctan(np.hypot(dzdx, dzdy)))


def tree_mask(heights: np.ndarray, x: np.ndarray, y: np.ndarray, *, spacing_m: float, density: float,
              seed: int = 0, max_slope_deg: float = 35.0, cluster_m: float = 250.0,
              ridge_weight: float = 1.0, pads: Iterable[Sequence[float]] = (), pattern: int = 1) -> np.ndarray:
    """A deterministic forest mask over the voxels of a placed grid.

    Voxels are eligible when their slope is below max_slope_deg and they lie outside every pad
    and its blend. Each eligible voxel gets a score: smoothed seeded noise (blobs about
    cluster_m across, so forests come in stands, not speckle) plus ridge_weight times the voxel's
    height rank in [0, 1] (forests on the ridges, fields in the valleys); the density fraction
    with the highest scores get the pattern.

    Args:
        heights: (ny + 1, nx + 1) node heights, world z metres.
        x, y: world x, y of the node columns and rows, metres.
        spacing_m: node spacing, metres.
        density: fraction of the eligible voxels to mark, 0..1.
        seed: noise seed (same inputs and seed -> same mask).
        pattern: the value written into marked voxels (1 + index into the patterns).

    Returns:
        (ny, nx) uint8: pattern where a tree stands, else 0.
    """
    if not 0.0 <= density <= 1.0:
        raise TerrainError(f"trees: density {density!r} is not in [0, 1]")
    ny, nx = heights.shape[0] - 1, heights.shape[1] - 1
    mask = np.zeros((ny, nx), np.uint8)
    cx, cy = 0.5 * (x[:-1] + x[1:]), 0.5 * (y[:-1] + y[1:])
    eligible = voxel_slope_deg(heights, spacing_m) < max_slope_deg
    for raw in pads:
        pad = check_pad(raw)
        eligible &= pad_distance(pad, cx[None, :], cy[:, None]) > pad[5]
    count = round(density * int(eligible.sum()))
    if count == 0:
        return mask
    rng = np.random.default_rng(seed)
    # spacing_m > 0; at least one voxel of smoothing.
    noise = _box_blur(rng.standard_normal((ny, nx)), max(1, round(cluster_m / spacing_m / 2)), passes=3)
    noise /= max(float(noise.std()), 1e-12)  # unit spread; the floor guards a constant field
    centre = 0.25 * (heights[:-1, :-1] + heights[:-1, 1:] + heights[1:, :-1] + heights[1:, 1:])
    rank = np.argsort(np.argsort(centre, axis=None)).reshape(centre.shape) / max(centre.size - 1, 1)
    score = np.where(eligible, noise + ridge_weight * 3.0 * rank, -np.inf)
    chosen = np.argpartition(score, score.size - count, axis=None)[score.size - count:]
    mask.reshape(-1)[chosen] = pattern
    return mask


def _box_blur(a: np.ndarray, radius: int, *, passes: int) -> np.ndarray:
    """Repeated (2 radius + 1)-wide box filter along both axes (edges replicated): ~Gaussian."""
    for _ in range(passes):
        for axis in (0, 1):
            pad = [(0, 0), (0, 0)]
            pad[axis] = (radius + 1, radius)
            c = np.cumsum(np.pad(a, pad, mode="edge"), axis=axis)
            n = a.shape[axis]
            hi = np.take(c, np.arange(2 * radius + 1, 2 * radius + 1 + n), axis=axis)
            lo = np.take(c, np.arange(0, n), axis=axis)
            a = (hi - lo) / (2 * radius + 1)
    return a
