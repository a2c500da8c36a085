"""Elevation grids as the sources read them, and sampling them at fractional indices."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .database import TerrainError


@dataclass(frozen=True)
class ElevationGrid:
    """Heights on a rectilinear grid of cells, as read from a source.

    The axes need not be evenly spaced (topobathy's latitudes are not); sampling finds the
    fractional index of a coordinate by interpolating the axis (see fractional_index).

    Attributes:
        values: (rows, cols) float64 heights, metres; row 0 is the southern row, column 0 the
            western column; every value finite.
        x: (cols,) strictly increasing cell-centre x: longitude, degrees, when crs is "EPSG:4326";
            otherwise easting in the units of crs (metres for the usual projections).
        y: (rows,) strictly increasing cell-centre y: latitude, degrees, or northing.
        crs: "EPSG:4326" (WGS-84 longitude/latitude), another CRS as rasterio prints it
            (placed through rasterio.warp.transform), or "" for local metres without a CRS.
        info: source, licence, attribution and reading notes.
    """

    values: np.ndarray
    x: np.ndarray
    y: np.ndarray
    crs: str
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        values = self.values
        if values.ndim != 2 or values.shape[0] < 2 or values.shape[1] < 2:
            raise TerrainError(f"{self.where}: values: shape {values.shape} is not (rows >= 2, cols >= 2)")
        if values.shape != (self.y.size, self.x.size):
            raise TerrainError(f"{self.where}: values: shape {values.shape} does not match "
                               f"{self.y.size} y and {self.x.size} x coordinates")
        if not np.isfinite(values).all():
            raise TerrainError(f"{self.where}: values: {int((~np.isfinite(values)).sum())} heights are not finite")
        for name, axis in (("x", self.x), ("y", self.y)):
            if not (np.all(np.isfinite(axis)) and np.all(np.diff(axis) > 0)):
                raise TerrainError(f"{self.where}: {name}: cell centres are not finite and strictly increasing")

    @property
    def where(self) -> str:
        return str(self.info.get("source", "<elevation grid>"))

    @property
    def geographic(self) -> bool:
        """True when x, y are WGS-84 longitude and latitude in degrees."""
        return self.crs == "EPSG:4326"


def bilinear(values: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of values (rows, cols[, ...]) at fractional indices (clamped)."""
    rows, cols = values.shape[:2]
    row = np.clip(row, 0.0, rows - 1.0)
    col = np.clip(col, 0.0, cols - 1.0)
    r0 = np.minimum(row.astype(np.int64), max(rows - 2, 0))
    c0 = np.minimum(col.astype(np.int64), max(cols - 2, 0))
    r1 = np.minimum(r0 + 1, rows - 1)
    c1 = np.minimum(c0 + 1, cols - 1)
    fr, fc = row - r0, col - c0
    r0, c0, r1, c1 = np.broadcast_arrays(r0, c0, r1, c1)
    fr, fc = np.broadcast_arrays(fr, fc)
    if values.ndim == 3:
        fr, fc = fr[..., None], fc[..., None]
    return ((values[r0, c0] * (1 - fc) + values[r0, c1] * fc) * (1 - fr)
            + (values[r1, c0] * (1 - fc) + values[r1, c1] * fc) * fr)


def fractional_index(axis: np.ndarray, coord: np.ndarray) -> np.ndarray:
    """Fractional index of coordinates along a strictly increasing axis (clamped to its ends)."""
    return np.interp(coord, axis, np.arange(axis.size, dtype=np.float64))
