"""GeoTIFF (``.tif``/``.tiff``) and ESRI ASCII grid (``.asc``) elevation through rasterio (GDAL).

Band 1 holds the heights: band value x scale + offset, in the band's unit (metres unless the
file says feet; another unit is refused). The affine transform must be north-up or south-up
without rotation (a rotated grid is refused). The CRS comes from the file (an ESRI ASCII grid
takes it from the ``.prj`` beside it): WGS-84 geographic (EPSG:4326) is placed directly; any other
CRS, geographic or projected, is placed through rasterio.warp.transform; no CRS means local
metres. Nodata cells (the file's nodata value, or NaN) are filled from their valid surroundings
with GDAL's FillNodata (inverse-distance weighting from the edge of each hole, no smoothing) or,
with ``?nodata=refuse``, refused with their count.
"""

from __future__ import annotations

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
    try:
        with rasterio.open(path) as ds:
            band = ds.read(1, masked=True)
            transform, crs, height, width = ds.transform, ds.crs, ds.height, ds.width
            declared_nodata = ds.nodata
            scale, offset, unit = ds.scales[0], ds.offsets[0], (ds.units[0] or "").strip().lower()
    except RasterioError as exc:
        raise TerrainError(f"source: {where!r} cannot be read: {exc}") from None
    if transform.b != 0.0 or transform.d != 0.0:
        raise TerrainError(f"{where}: transform: {tuple(transform)[:6]!r} is rotated; warp it north-up first")
    if unit not in _METRES_PER_UNIT:
        raise TerrainError(f"{where}: units: {unit!r} is not a height unit this reader knows "
                           f"({', '.join(repr(u) for u in _METRES_PER_UNIT)})")
    # Heights are band values times the band's scale plus its offset, in its unit (metres
    # when the file does not say).
    values = np.ma.filled(band.astype(np.float64), np.nan) * scale + offset
    values *= _METRES_PER_UNIT[unit]
    invalid = ~np.isfinite(values)
    count = int(invalid.sum())
    if count == values.size:
        raise TerrainError(f"{where}: nodata: every one of the {count} cells is nodata ({declared_nodata!r})")
    if count and nodata == "refuse":
        raise TerrainError(f"{where}: nodata: {count} of {values.size} cells are nodata ({declared_nodata!r}); "
                           f"use {where}?nodata=fill to fill them")
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


def _is_wgs84_lonlat(crs) -> bool:
    """EPSG:4326 or the same datum in longitude/latitude order (OGC:CRS84, which GDAL reads from
    an ESRI .prj of WGS 84): both are placed directly, without a PROJ transform."""
    return crs.to_epsg() == 4326 or crs.to_string() == "OGC:CRS84"
