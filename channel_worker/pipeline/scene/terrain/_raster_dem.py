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
refused. A height (in metres, after scale, offset and unit) outside HEIGHT_RANGE_M, -12000 ..
9000 m, is refused with the count and the first one's row, column and value, whatever
``nodata`` says: no place on Earth is there, so the file is damaged or its nodata value is not
declared.

An ESRI ASCII grid is read through GDAL, which takes ``nan`` or any cell that is not a number
(``abc``) as 0 in a grid of whole numbers, wraps a whole number past int32, clamps ``inf`` and
``1e39`` to the largest float32, and pads a short grid with 0. The text is therefore read first:
a cell that is not a decimal number, ``nan`` or ``inf`` is refused (it is damage, not nodata),
as is a cell count other than ``ncols`` x ``nrows``; the cells' own float64 values then replace
GDAL's (except where GDAL found the nodata value), so non-finite cells are the nodata they are
and out-of-range ones are refused as they are written.
"""

from __future__ import annotations

import contextlib
import math
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .database import TerrainError
from .grid import ElevationGrid

#: Band units (GDAL's unit type, lower case) -> metres; "" (not given) is taken as metres.
_METRES_PER_UNIT = {"": 1.0, "m": 1.0, "metre": 1.0, "meter": 1.0, "metres": 1.0, "meters": 1.0,
                    "ft": 0.3048, "foot": 0.3048, "feet": 0.3048, "us-ft": 1200.0 / 3937.0,
                    "us survey foot": 1200.0 / 3937.0}

#: Plausible heights, metres: from below the Challenger Deep (-10935 m) to above Everest
#: (8849 m). A height outside is a damaged file, an undeclared nodata value (SRTM's -32768) or
#: a wrapped integer, never terrain.
HEIGHT_RANGE_M = (-12000.0, 9000.0)


def open_raster_dem(path: str, *, nodata: str = "fill") -> ElevationGrid:
    """Read band 1 of a GeoTIFF or ESRI ASCII grid as an ElevationGrid (row 0 south).

    Args:
        path: the file.
        nodata: "fill" or "refuse" (module docstring).

    Raises:
        TerrainError: unreadable file, rotated grid, bad cell size, an ESRI ASCII cell that is not a
            number or a cell count other than ncols x nrows, a height outside HEIGHT_RANGE_M,
            every cell nodata, or nodata with "refuse".
    """
    import rasterio
    from rasterio.errors import RasterioError

    where = str(path)
    if not Path(path).is_file():
        raise TerrainError(f"source: {where!r} is not a file")
    ascii_grid = _read_ascii_grid(path, where) if str(path).lower().endswith(".asc") else None
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
    raw = np.ma.filled(band.astype(np.float64), np.nan)
    # An ESRI ASCII grid's cells as its text has them; None for a GeoTIFF.
    text = ascii_grid if ascii_grid is not None and ascii_grid.values.size == raw.size else None
    if text is not None:
        # GDAL's integers wrap and its float32 clamps: the text's own float64 values are the
        # heights, except where GDAL found the declared nodata value.
        raw = np.where(np.ma.getmaskarray(band), np.nan, text.values.reshape(raw.shape))
    # Heights are band values times the band's scale plus its offset, in its unit (metres
    # when the file does not say).
    values = raw * scale + offset
    values *= _METRES_PER_UNIT[unit]
    low, high = HEIGHT_RANGE_M
    with np.errstate(invalid="ignore"):  # NaN compares False: nodata is not out of range
        implausible = (values < low) | (values > high)
    implausible &= np.isfinite(values)
    if implausible.any():
        row, col = (int(v) for v in np.argwhere(implausible)[0])
        value = text.text(row * width + col) if text is not None else repr(band.data[row, col].item())
        raise TerrainError(f"{where}: heights: {int(implausible.sum())} of {values.size} cells are outside "
                           f"{low:g} .. {high:g} m (the Challenger Deep to above Everest), the first at row "
                           f"{row}, column {col} (from 0, the file's first row and column): {value} "
                           f"({values[row, col]:g} m)")
    invalid = ~np.isfinite(values)
    count = int(invalid.sum())
    if count == values.size:
        raise TerrainError(f"{where}: nodata: every one of the {count} cells is nodata ({declared_nodata!r})")
    if count and nodata == "refuse":
        row, col = (int(v) for v in np.argwhere(invalid)[0])
        value = text.text(row * width + col) if text is not None else repr(band.data[row, col].item())
        declared = "" if declared_nodata is None else f" ({declared_nodata!r})"
        raise TerrainError(f"{where}: nodata: {count} of {values.size} cells are nodata{declared} or not "
                           f"finite, the first at row {row}, column {col} (from 0, the file's first row and "
                           f"column): {value}; use {where}?nodata=fill to fill them")
    if count:
        from rasterio.fill import fillnodata
        # max_search_distance spans the whole grid, so every hole is reached from some edge.
        filled = fillnodata(np.where(invalid, 0.0, values), mask=(~invalid).astype(np.uint8),
                            max_search_distance=float(height + width), smoothing_iterations=0)
        # GDAL fills in float32: only the holes take its values, the valid cells keep float64.
        values = np.where(invalid, filled, values)
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


#: One line of an ESRI ASCII grid header: one of GDAL's keywords and its value. Only these, so
#: that a damaged first row (``abc 2``) is read as cells, not as more header.
_ASCII_HEADER_LINE = re.compile(rb"[ \t]*(ncols|nrows|xllcorner|yllcorner|xllcenter|yllcenter|cellsize|dx|dy|"
                                rb"nodata_value)[ \t]+(\S+)[ \t]*\r?\n", re.IGNORECASE)
#: A cell that is not a decimal number, NaN or infinity. Python's float() and numpy would also
#: take ``1_000``; GDAL reads it as 1.
_NOT_A_NUMBER = re.compile(rb"(?<!\S)(?![+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:e[+-]?[0-9]+)?|nan|inf(?:inity)?)"
                           rb"(?!\S))\S+", re.IGNORECASE)


class _AsciiGrid(NamedTuple):
    """The cells of an ESRI ASCII grid as its text has them."""

    values: np.ndarray  #: float64, in file order (row 0 north), ncols x nrows of them
    tokens: list[bytes]  #: the cells' text, in the same order

    def text(self, index: int) -> str:
        """Cell ``index``'s text as written (only decimal numbers, NaN and infinity get here)."""
        return self.tokens[index].decode("ascii")


def _read_ascii_grid(path: str, where: str) -> _AsciiGrid | None:
    """The cells of an ESRI ASCII grid, or None when its header has no whole ncols and nrows > 0
    (GDAL then says what is wrong).

    Raises:
        TerrainError: cellsize, dx or dy is not a finite number > 0; a cell is not a number; the
            cell count is not ncols x nrows.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise TerrainError(f"source: {where!r} cannot be read: {exc}") from None
    header: dict[str, str] = {}
    pos = 0
    while (line := _ASCII_HEADER_LINE.match(data, pos)) is not None:
        header[line.group(1).decode().lower()] = line.group(2).decode("ascii", "backslashreplace")
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
        columns, rows = int(header.get("ncols", "")), int(header.get("nrows", ""))
    except ValueError:
        return None
    if columns <= 0 or rows <= 0:
        return None
    tokens = data[pos:].split()
    values: np.ndarray | None = None
    # The usual grid holds only digits, signs, points and exponents: numpy's float parsing then
    # accepts exactly the decimal numbers, and the slower cell-by-cell search is not needed.
    if not data[pos:].translate(None, b"0123456789+-.eE \t\r\n\v\f"):
        with contextlib.suppress(ValueError):  # 1e, 1..2: the search below names the cell
            values = np.array(tokens, dtype=np.float64)
    if values is None:
        bad = list(_NOT_A_NUMBER.finditer(data, pos))
        if bad:
            row, col = divmod(len(data[pos:bad[0].start()].split()), columns)
            # repr of the bytes without its b: 'abc', '\xff\xfe', as the file has them.
            raise TerrainError(f"{where}: cells: row {row}, column {col} (from 0, the file's first row and "
                               f"column): {repr(bad[0].group())[1:]} is not a number (cells that are not: "
                               f"{len(bad)}); the file is damaged")
    if len(tokens) != columns * rows:
        raise TerrainError(f"{where}: cells: the file has {len(tokens)} cells, not ncols x nrows = {columns} x "
                           f"{rows} = {columns * rows}")
    if values is None:  # the search found every cell a number, NaN or infinity
        values = np.array(tokens, dtype=np.float64)
    return _AsciiGrid(values, tokens)


def _is_wgs84_lonlat(crs) -> bool:
    """EPSG:4326 or the same datum in longitude/latitude order (OGC:CRS84, which GDAL reads from
    an ESRI .prj of WGS 84): both are placed directly, without a PROJ transform."""
    return crs.to_epsg() == 4326 or crs.to_string() == "OGC:CRS84"
