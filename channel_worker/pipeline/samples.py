"""Named sample patterns: where inside a pixel the visibility is sampled.

Positions are in 1/16 pixel from the pixel centre (the D3D standard multisample patterns, which
are well studied for edge anti-aliasing), so every one lies exactly on the rasterizer's
1/256-pixel grid. A pattern is chosen by name, or by its sample count.
"""

from __future__ import annotations

import numpy as np

_SIXTEENTHS: dict[str, tuple[tuple[int, int], ...]] = {
    # One sample at the pixel centre: the classic point-sampled image.
    "centre": ((0, 0),),
    "d3d2": ((4, 4), (-4, -4)),
    # Rotated grid: four distinct x and four distinct y positions, so near-horizontal and
    # near-vertical edges get four coverage levels each.
    "rgss4": ((-2, -6), (6, -2), (-6, 2), (2, 6)),
    "d3d8": ((1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)),
    "d3d16": ((1, 1), (-1, -3), (-3, 2), (4, -1), (-5, -2), (2, 5), (5, 3), (3, -5),
              (-2, 6), (0, -7), (-4, -6), (-6, 4), (-8, 0), (7, -4), (6, 7), (-7, -8)),
}
_BY_COUNT = {len(v): k for k, v in _SIXTEENTHS.items()}


def pattern_names() -> list[str]:
    """Every registered pattern name."""
    return sorted(_SIXTEENTHS)


def sample_pattern(spec: int | str) -> np.ndarray:
    """Sample offsets (S, 2) float64, pixels from the pixel's top-left corner.

    Args:
        spec: a pattern name (see pattern_names) or a sample count (1, 2, 4, 8, 16).

    Raises:
        ValueError: unknown name or count.
    """
    if isinstance(spec, str) and spec.isdigit():
        spec = int(spec)
    if isinstance(spec, int):
        if spec not in _BY_COUNT:
            raise ValueError(f"samples: {spec} has no pattern; counts are {sorted(_BY_COUNT)}")
        spec = _BY_COUNT[spec]
    if spec not in _SIXTEENTHS:
        raise ValueError(f"samples: unknown pattern {spec!r}; known: {', '.join(pattern_names())}")
    return 0.5 + np.array(_SIXTEENTHS[spec], dtype=np.float64) / 16.0
