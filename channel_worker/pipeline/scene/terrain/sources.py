"""Elevation and colour sources of the terrain build, chosen by URL (like pyserial's serial_for_url).

Elevation (open_elevation):

- ``mpl:jacksboro``: matplotlib's bundled USGS sample DEM (3 arc-seconds, Tennessee/Kentucky).
- ``mpl:topobathy``: matplotlib's bundled topography/bathymetry sample (1/30 degree).
- ``PATH.tif`` / ``PATH.tiff`` (GeoTIFF) or ``PATH.asc`` (ESRI ASCII grid), read with rasterio;
  ``?nodata=fill`` (default: holes filled from their valid surroundings) or ``?nodata=refuse``.

Colour (colour_nodes), evaluated on the placed east-north-up node grid:

- ``relief:CMAP`` (default ``relief:gist_earth``): hypsometric tint with a matplotlib colour map,
  hill-shaded by matplotlib's LightSource; options ``azimuth`` (degrees clockwise from north,
  default 315), ``altitude`` (degrees, 45), ``exaggeration`` (1), ``span`` (the part of the colour
  map used for lowest..highest, default 0.3,0.9 so that gist_earth starts at green lowland rather
  than the blue it keeps for water).
- an image path, read with OpenImageIO and stretched over the database extent, its top row north;
  8/16-bit images are taken as sRGB-encoded, float images as linear.

Backends (matplotlib, rasterio) are imported only when a URL needs them (the ``gis`` extra).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .database import TerrainError
from .grid import ElevationGrid, bilinear

DEFAULT_COLOUR = "relief:gist_earth"
RASTER_SUFFIXES = (".tif", ".tiff", ".asc")


def split_url(url: str) -> tuple[str, dict[str, str]]:
    """(body, options) of ``body?key=value&key=value``."""
    body, _, query = url.partition("?")
    options: dict[str, str] = {}
    for part in filter(None, query.split("&")):
        key, eq, value = part.partition("=")
        if not eq:
            raise TerrainError(f"{url}: option {part!r} is not key=value")
        options[key] = value
    return body, options


def take_option(url: str, options: dict[str, str], name: str, convert: Callable[[str], Any], default: Any) -> Any:
    """Pop one option of a URL, converted; a TerrainError names the URL, option and value."""
    if name not in options:
        return default
    text = options.pop(name)
    try:
        return convert(text)
    except (TypeError, ValueError) as exc:
        raise TerrainError(f"{url}: {name}: {text!r} is not valid ({exc})") from None


def reject_unused(url: str, options: dict[str, str]) -> None:
    """An option nobody took is a typo: refuse it (like pbrt's factories)."""
    if options:
        raise TerrainError(f"{url}: unknown option(s) {', '.join(sorted(options))}")


def require(module: str, url: str) -> None:
    """Import an optional backend, or say which extra installs it (a TerrainError, so that a
    scene naming the bundled terrain fails with a message, not an ImportError)."""
    import importlib
    try:
        importlib.import_module(module)
    except ImportError:
        raise TerrainError(f"{url}: needs {module}, which is not installed: "
                           f"pip install 'ig-rig[gis]'") from None


def open_elevation(url: str) -> ElevationGrid:
    """Read an elevation source (module docstring lists the URLs).

    Raises:
        TerrainError: unknown scheme or suffix, unreadable file, unusable georeferencing or
            nodata, naming the source, field and value.
    """
    body, options = split_url(url)
    if body.startswith("mpl:"):
        require("matplotlib", url)
        from ._mpl_dem import open_mpl_dem
        reject_unused(url, options)
        return open_mpl_dem(body[4:])
    if body.lower().endswith(RASTER_SUFFIXES):
        require("rasterio", url)
        from ._raster_dem import open_raster_dem
        nodata = take_option(url, options, "nodata", _one_of("fill", "refuse"), "fill")
        reject_unused(url, options)
        return open_raster_dem(body, nodata=nodata)
    raise TerrainError(f"source: {url!r} is not mpl:jacksboro, mpl:topobathy or a "
                       f"{'/'.join(RASTER_SUFFIXES)} file")


def colour_nodes(url: str, heights: np.ndarray, *, spacing_m: float) -> np.ndarray:
    """Linear RGB of every node of a placed grid.

    Args:
        url: ``relief:CMAP[?options]`` or an image path (module docstring).
        heights: (ny + 1, nx + 1) node heights, metres, row 0 south (the placed ENU grid).
        spacing_m: node spacing, metres (slopes of the hill-shading).

    Returns:
        (ny + 1, nx + 1, 3) float64 linear RGB in [0, 1].
    """
    body, options = split_url(url)
    if body.startswith("relief:"):
        require("matplotlib", url)
        from ._relief import relief_colours
        cmap = body[len("relief:"):] or "gist_earth"
        kwargs = {
            "azimuth_deg": take_option(url, options, "azimuth", _finite, 315.0),
            "altitude_deg": take_option(url, options, "altitude", _finite, 45.0),
            "exaggeration": take_option(url, options, "exaggeration", _finite, 1.0),
            "span": take_option(url, options, "span", _span, (0.3, 0.9)),
        }
        reject_unused(url, options)
        return relief_colours(heights, cmap, spacing_m=spacing_m, where=url, **kwargs)
    reject_unused(url, options)
    return image_colours(Path(body), heights.shape)


def image_colours(path: Path, node_shape: tuple[int, int]) -> np.ndarray:
    """An image (top row north) stretched over the node grid, bilinear, as linear RGB.

    The image spans the database extent edge to edge: node (0, 0) (south-west corner) samples
    the bottom-left corner of the image's bottom-left pixel, the last node the top-right corner.
    """
    import OpenImageIO as oiio

    from services.rig.colour import srgb8_to_linear

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise TerrainError(f"colour: {str(path)!r} cannot be read: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if pixels is None:
            raise TerrainError(f"colour: {str(path)!r} cannot be read: {inp.geterror()}")
        is_float = spec.format.basetype in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    finally:
        inp.close()
    img = np.asarray(pixels, np.float64).reshape(spec.height, spec.width, spec.nchannels)
    img = np.repeat(img[..., :1], 3, axis=2) if spec.nchannels < 3 else img[..., :3]
    img = img[::-1]  # row 0 south, like the node grid
    rows, cols = node_shape
    # rows, cols >= 2 (a database is at least one voxel), so the divisions by rows - 1 and
    # cols - 1 are safe; the image is at least 1 x 1.
    py = np.clip(np.arange(rows) / (rows - 1) * spec.height - 0.5, 0, spec.height - 1)
    px = np.clip(np.arange(cols) / (cols - 1) * spec.width - 0.5, 0, spec.width - 1)
    out = bilinear(img, py[:, None], px[None, :])
    out = np.clip(out, 0.0, 1.0)
    if not is_float:
        # Integer images are sRGB-encoded; OpenImageIO scaled them to [0, 1].
        out = srgb8_to_linear(np.round(out * 255.0)).astype(np.float64)
    return out


def _finite(text: str) -> float:
    value = float(text)
    if not np.isfinite(value):
        raise ValueError("not finite")
    return value


def _span(text: str) -> tuple[float, float]:
    lo, hi = (float(v) for v in text.split(","))
    if not 0.0 <= lo < hi <= 1.0:
        raise ValueError("need 0 <= LO < HI <= 1")
    return lo, hi


def _one_of(*choices: str) -> Callable[[str], str]:
    def convert(text: str) -> str:
        if text not in choices:
            raise ValueError(f"not one of {', '.join(choices)}")
        return text
    return convert
