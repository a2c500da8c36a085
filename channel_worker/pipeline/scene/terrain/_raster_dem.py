"""GeoTIFF (``.tif``/``.tiff``) and ESRI ASCII grid (``.asc``) elevation through rasterio (GDAL).

Band 1 holds the heights: band value x scale + offset, in the band's unit (metres unless the
file says feet; another unit is refused). The affine transform must be north-up or south-up
without rotation (a rotated grid is refused). The CRS comes from the file (an ESRI ASCII grid
takes it from the ``.prj`` beside it): WGS-84 geographic (EPSG:4326) is placed directly; any other
CRS, geographic or projected, is placed through rasterio.warp.transform; no CRS means local
metres. Nodata cells (the file's nodata value, NaN or infinity) are filled from their valid
surroundings with GDAL's FillNodata (inverse-distance weighting from the edge of each hole, no
smoothing) or, with ``?nodata=refuse``, refused with their count and the first one's row, column
and value. A cell size that is not a finite number > 0 (an ESRI grid's ``cellsize``, ``dx`` or
``dy``; a GeoTIFF transform's pixel width or height, which may be negative, must not be 0) is
refused.

An ESRI ASCII grid is read through GDAL, which takes ``nan`` as 0 in a grid of whole numbers
and clamps ``inf`` to the largest float32; its header and non-finite cells are therefore read
from the text first, so that they are treated as the nodata they are.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from .database import TerrainError
from .grid import ElevationGrid

#: Band units (GDAL's unit type, lower case) -> metres; "" (not given) is taken as metres.
_METRES_PER_UNIT = {"": 1.0, "m": 1.0, "metre": 1.0, "meter": 1.0, "metres": 1.0, "meters": 1.0,
                    "ft": 0.3048, "foot": 0.3048, "feet": 0.3048, "us-ft": 1200.0 / 3937.0,
                    "us survey foot": 1200.0 / 3937.0}


def open_raster_dem(path: str, *, nodata: str = "fill") -> ElevationGrid:
    """Read band 1 of a GeoTIFF or ESRI ASCII grid as an ElevationGrid (row 0 south).

    Args:
        path: the file.
        nodata: "fill" or "refuse" (module docstring).

    Raises:
        TerrainError: unreadable file, rotated grid, every cell nodata, or nodata with "refuse".
    """
    import rasterio
    from rasterio.errors import RasterioError

    where = str(path)
    if not Path(path).is_file():
        raise TerrainError(f"source: {where!r} is not a file")
    ascii_cells = _ascii_non_finite(path, where) if str(path).lower().endswith(".asc") else None
    try:
        with rasterio.open(path) as ds:
            band = ds.read(1, masked=True)
            transform, crs, height, width = ds.transform, ds.crs, ds.height, ds.width
            declared_nodata = ds.nodata
            scale, offset, unit = ds.scales[0], ds.offsets[0], (ds.units[0] or "").strip().lower()
    except RasterioError as exc:
        raise TerrainError(f"source: {where!r} cannot be read: {exc}") from None
    if not all(math.isfinite(v) for v in tuple(transform)[:6]) or transform.a == 0.0 or transform.e == 0.0:
        raise TerrainError(f"{where}: cell size: {transform.a!r} x {transform.e!r} (the transform's pixel width "
                           f"and height) is not finite and non-zero")
    if transform.b != 0.0 or transform.d != 0.0:
        raise TerrainError(f"{where}: transform: {tuple(transform)[:6]!r} is rotated; warp it north-up first")
    if unit not in _METRES_PER_UNIT:
        raise TerrainError(f"{where}: units: {unit!r} is not a height unit this reader knows "
                           f"({', '.join(repr(u) for u in _METRES_PER_UNIT)})")
    # Heights are band values times the band's scale plus its offset, in its unit (metres
    # when the file does not say).
    values = np.ma.filled(band.astype(np.float64), np.nan) * scale + offset
    values *= _METRES_PER_UNIT[unit]
    tokens: dict[tuple[int, int], str] = {}
    if ascii_cells is not None:
        columns, cells = ascii_cells
        for index, token in cells:
            cell = divmod(index, columns)
            if cell[0] < height:
                values[cell] = np.nan
                tokens[cell] = token
    invalid = ~np.isfinite(values)
    count = int(invalid.sum())
    if count == values.size:
        raise TerrainError(f"{where}: nodata: every one of the {count} cells is nodata ({declared_nodata!r})")
    if count and nodata == "refuse":
        row, col = (int(v) for v in np.argwhere(invalid)[0])
        value = tokens.get((row, col), repr(band.data[row, col].item()))
        declared = "" if declared_nodata is None else f" ({declared_nodata!r})"
        raise TerrainError(f"{where}: nodata: {count} of {values.size} cells are nodata{declared} or not "
                           f"finite, the first at row {row}, column {col} (from 0, the file's first row and "
                           f"column): {value}; use {where}?nodata=fill to fill them")
    if count:
        from rasterio.fill import fillnodata
        # max_search_distance spans the whole grid, so every hole is reached from some edge.
        values = fillnodata(np.where(invalid, 0.0, values), mask=(~invalid).astype(np.uint8),
                            max_search_distance=float(height + width), smoothing_iterations=0)
    # Cell centres from the affine transform: x = c + (col + 0.5) a, y = f + (row + 0.5) e.
    x = transform.c + (np.arange(width) + 0.5) * transform.a
    y = transform.f + (np.arange(height) + 0.5) * transform.e
    if transform.a < 0:
        x, values = x[::-1], values[:, ::-1]
    if transform.e < 0:  # the usual north-up file: row 0 is north
        y, values = y[::-1], values[::-1]
    crs_text = "" if crs is None else ("EPSG:4326" if _is_wgs84_lonlat(crs) else crs.to_string())
    info = {"source": where, "licence": "not recorded in the file: see its provider",
            "crs": crs_text or "none (local metres)", "nodata_filled": count,
            "cell": [abs(transform.a), abs(transform.e)]}
    return ElevationGrid(values=np.ascontiguousarray(values), x=x, y=y, crs=crs_text, info=info)


#: One line of an ESRI ASCII grid header: a keyword and its value.
_ASCII_HEADER_LINE = re.compile(r"[ \t]*([A-Za-z_]+)[ \t]+(\S+)[ \t]*\r?\n")
#: Cell values that may not be finite: NaN, infinity, or a decimal exponent of 100 or more
#: (checked with float(): only those past float64 are infinite).
_MAYBE_NOT_FINITE = re.compile(r"(?<!\S)[+-]?(?:nan|inf(?:inity)?|[0-9.]*e\+?0*[0-9]{3,})(?!\S)", re.IGNORECASE)


def _ascii_non_finite(path: str, where: str) -> tuple[int, list[tuple[int, str]]] | None:
    """(columns, [(cell index in file order, text)] of the non-finite cells) of an ESRI ASCII grid,
    or None when its header has no whole ncols (GDAL then says what is wrong).

    Raises:
        TerrainError: cellsize, dx or dy is not a finite number > 0.
    """
    try:
        text = Path(path).read_text(errors="replace")
    except OSError as exc:
        raise TerrainError(f"source: {where!r} cannot be read: {exc}") from None
    header: dict[str, str] = {}
    pos = 0
    while (line := _ASCII_HEADER_LINE.match(text, pos)) is not None:
        header[line.group(1).lower()] = line.group(2)
        pos = line.end()
    for key in ("cellsize", "dx", "dy"):
        if key in header:
            try:
                size = float(header[key])
            except ValueError:
                size = math.nan
            if not (math.isfinite(size) and size > 0):
                raise TerrainError(f"{where}: {key}: {header[key]!r} is not a finite cell size > 0")
    try:
        columns = int(header.get("ncols", ""))
    except ValueError:
        return None
    if columns <= 0:
        return None
    cells = []
    index, last = 0, pos
    for match in _MAYBE_NOT_FINITE.finditer(text, pos):
        index += len(text[last:match.start()].split())
        last = match.end()
        if not math.isfinite(float(match.group())):
            cells.append((index, match.group()))
        index += 1
    return columns, cells


def _is_wgs84_lonlat(crs) -> bool:
    """EPSG:4326 or the same datum in longitude/latitude order (OGC:CRS84, which GDAL reads from
    an ESRI .prj of WGS 84): both are placed directly, without a PROJ transform."""
    return crs.to_epsg() == 4326 or crs.to_string() == "OGC:CRS84"
