"""``relief:CMAP`` colours: hypsometric tint plus hill-shading with matplotlib's LightSource."""

from __future__ import annotations

import numpy as np

from services.rig.colour import srgb_to_linear

from .database import TerrainError


def relief_colours(heights: np.ndarray, cmap_name: str, *, spacing_m: float, where: str,
                   azimuth_deg: float = 315.0, altitude_deg: float = 45.0, exaggeration: float = 1.0,
                   span: tuple[float, float] = (0.3, 0.9)) -> np.ndarray:
    """Linear RGB (ny + 1, nx + 1, 3) of a placed node grid (row 0 south), metres.

    The lowest node takes colour-map position span[0], the highest span[1]; the tint is then
    blended with the hill-shade (LightSource "soft" blend, as matplotlib's hillshading example
    recommends for complex surfaces) of a sun at azimuth_deg (clockwise from north) and
    altitude_deg above the horizon, slopes exaggerated by exaggeration. matplotlib's colour maps
    are sRGB; the result is decoded to linear.
    """
    import matplotlib
    from matplotlib.colors import LightSource, ListedColormap

    try:
        base = matplotlib.colormaps[cmap_name]
    except KeyError:
        raise TerrainError(f"colour: {where!r}: {cmap_name!r} is not a matplotlib colour map") from None
    cmap = ListedColormap(base(np.linspace(span[0], span[1], 256)))
    lo, hi = float(heights.min()), float(heights.max())
    light = LightSource(azdeg=azimuth_deg, altdeg=altitude_deg)
    # LightSource takes row 0 as the top of a north-up image (it negates dy); ours is south.
    north_up = heights[::-1]
    rgba = light.shade(north_up, cmap=cmap, blend_mode="soft", vert_exag=exaggeration,
                       dx=spacing_m, dy=spacing_m, vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    return srgb_to_linear(np.clip(np.asarray(rgba[::-1, :, :3], np.float64), 0.0, 1.0))
