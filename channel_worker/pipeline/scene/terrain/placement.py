"""Placing an elevation grid in the world frame: a regular east-north-up node grid, float64.

With a CRS, the world frame is the local east-north-up frame of a geodetic origin (lat, lon, h)
(WGS-84 -> ECEF -> ENU, host_sim/replay/geodetic.py; docs/conventions.md): world (0, 0, 0) is
the origin, x east, y north, z up along the origin's ellipsoid normal. A node at (x, y) gets
the z at which the vertical line through (x, y) meets the terrain, so the terrain's height is
reduced by the drop of the ellipsoid below the tangent plane there (d^2 / 2R: 7.8 m at 10 km) and
distant terrain sits lower, as seen from the origin. Heights between the source's cell centres
are interpolated bilinearly in the source's own coordinates (longitude/latitude or easting/
northing): the sources are 30-100 m grids and the database is usually as fine or finer, where
bilinear interpolation neither overshoots nor shifts features.

Without a CRS (an ESRI grid with no .prj) the file's coordinates are taken as local metres and
only shifted so that world (0, 0) is the node nearest the grid's centre.

The node grid is the largest rectangle of whole spacings that lies inside the source's cell
centres, with world (0, 0) on the lattice (x0 and y0 are whole multiples of the spacing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from services.rig.geodetic import enu, geodetic_of_enu

from .database import TerrainError
from .grid import ElevationGrid, bilinear, fractional_index

#: Refuse node grids above this many nodes (a 5000 x 5000 grid holds ~10 float64 temporaries of
#: 200 MB each while it is placed): a mistyped --spacing should fail at once, not swap.
MAX_NODES = 25_000_000
#: Fixed-point steps putting a node's sample point on its own vertical line (below).
_VERTICAL_STEPS = 3


@dataclass(frozen=True)
class PlacedGrid:
    """Heights on a regular world-frame node grid.

    Attributes:
        heights: (ny + 1, nx + 1) float64 world z of the nodes, metres; row 0 is the southern
            row, node (j, i) is at world (x0 + i spacing_m, y0 + j spacing_m).
        x0, y0: world x, y of node (0, 0), metres.
        spacing_m: node spacing, metres.
        geodetic_origin: (lat deg, lon deg, h m) of world (0, 0, 0), or None for local metres.
        info: placement notes (and the source's info).
    """

    heights: np.ndarray
    x0: float
    y0: float
    spacing_m: float
    geodetic_origin: tuple[float, float, float] | None
    info: dict = field(default_factory=dict)

    @property
    def nx(self) -> int:
        return self.heights.shape[1] - 1

    @property
    def ny(self) -> int:
        return self.heights.shape[0] - 1

    def node_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) world metres of the nodes: (nx + 1,) and (ny + 1,)."""
        return (self.x0 + np.arange(self.nx + 1) * self.spacing_m,
                self.y0 + np.arange(self.ny + 1) * self.spacing_m)

    def with_heights(self, heights: np.ndarray) -> PlacedGrid:
        """The same grid with other heights (same shape)."""
        if heights.shape != self.heights.shape:
            raise TerrainError(f"heights: shape {heights.shape} is not {self.heights.shape}")
        return PlacedGrid(heights, self.x0, self.y0, self.spacing_m, self.geodetic_origin, self.info)


def place(grid: ElevationGrid, *, spacing_m: float | None = None,
          origin: tuple[float, float, float] | None = None) -> PlacedGrid:
    """Resample a source grid onto a regular world node grid.

    Args:
        grid: the source heights.
        spacing_m: node spacing, metres; default: the source's finer cell size (native_spacing_m).
        origin: geodetic origin (latitude deg, longitude deg, height m above the source's height
            datum) of world (0, 0, 0); default: the grid's centre at height 0, so world z is the
            height above the datum less the earth's curvature. Only for grids with a CRS.

    Raises:
        TerrainError: origin given for a grid without CRS, bad spacing, a grid smaller than one
            voxel at that spacing or larger than MAX_NODES.
    """
    if origin is not None:
        if not grid.crs:
            raise TerrainError(f"origin: {origin!r} needs a source with a CRS; {grid.where} has none")
        lat, lon, h = (float(v) for v in origin)
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 360.0 and math.isfinite(h)):
            raise TerrainError(f"origin: {origin!r} is not (latitude -90..90, longitude, finite height)")
        origin = (lat, lon, h)
    elif grid.crs:
        origin = default_origin(grid)
    if spacing_m is None:
        spacing_m = native_spacing_m(grid, origin)
    if not (isinstance(spacing_m, (int, float, np.integer, np.floating)) and math.isfinite(spacing_m)
            and spacing_m > 0):
        raise TerrainError(f"spacing_m: {spacing_m!r} is not a finite number > 0")
    if origin is None:
        return _place_local(grid, spacing_m)
    return _place_geodetic(grid, spacing_m, origin)


def default_origin(grid: ElevationGrid) -> tuple[float, float, float]:
    """(lat, lon, 0) of the grid's centre (rounded to 1e-6 degree, ~0.1 m; longitude in -180..180)."""
    lat, lon = _geodetic_of_grid_xy(grid, np.array([0.5 * (grid.x[0] + grid.x[-1])]),
                                    np.array([0.5 * (grid.y[0] + grid.y[-1])]))
    return round(float(lat[0]), 6), round((float(lon[0]) + 180.0) % 360.0 - 180.0, 6), 0.0


def native_spacing_m(grid: ElevationGrid, origin: tuple[float, float, float] | None = None) -> float:
    """The finer of the source's two cell sizes near its centre, metres (rounded to 0.1 m)."""
    ci, cj = grid.x.size // 2, grid.y.size // 2
    # x.size, y.size >= 2, so ci >= 1 and cj >= 1: the backward steps below exist.
    xs = np.array([grid.x[ci], grid.x[ci - 1], grid.x[ci]])
    ys = np.array([grid.y[cj], grid.y[cj], grid.y[cj - 1]])
    if not grid.crs:
        return round(float(min(xs[0] - xs[1], ys[0] - ys[2])), 1)
    lat, lon = _geodetic_of_grid_xy(grid, xs, ys)
    origin = origin or (float(lat[0]), float(lon[0]), 0.0)
    p = enu(lat, lon, np.full(3, origin[2]), origin)
    return round(float(min(np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[0]))), 1)


def _place_local(grid: ElevationGrid, spacing_m: float) -> PlacedGrid:
    cx = round(0.5 * (grid.x[0] + grid.x[-1]) / spacing_m) * spacing_m
    cy = round(0.5 * (grid.y[0] + grid.y[-1]) / spacing_m) * spacing_m
    i0, nx = _lattice(grid.x[0] - cx, grid.x[-1] - cx, spacing_m, "x")
    j0, ny = _lattice(grid.y[0] - cy, grid.y[-1] - cy, spacing_m, "y")
    _check_size(nx, ny, spacing_m)
    xs = cx + (i0 + np.arange(nx + 1)) * spacing_m
    ys = cy + (j0 + np.arange(ny + 1)) * spacing_m
    heights = bilinear(grid.values, fractional_index(grid.y, ys)[:, None], fractional_index(grid.x, xs)[None, :])
    info = dict(grid.info, frame="local metres (no CRS)", local_offset=[cx, cy], spacing_m=spacing_m,
                interpolation="bilinear")
    return PlacedGrid(heights, i0 * spacing_m, j0 * spacing_m, spacing_m, None, info)


def _place_geodetic(grid: ElevationGrid, spacing_m: float, origin: tuple[float, float, float]) -> PlacedGrid:
    # The source's outer ring of cell centres, in ENU: the node rectangle lies inside it.
    rows, cols = grid.values.shape
    ring = [(np.full(rows, grid.x[0]), grid.y), (np.full(rows, grid.x[-1]), grid.y),
            (grid.x, np.full(cols, grid.y[0])), (grid.x, np.full(cols, grid.y[-1]))]
    edges = []
    for gx, gy in ring:
        lat, lon = _geodetic_of_grid_xy(grid, gx, gy)
        edges.append(enu(lat, lon, np.full(lat.shape, origin[2]), origin))
    west, east, south, north = edges[0][:, 0].max(), edges[1][:, 0].min(), edges[2][:, 1].max(), edges[3][:, 1].min()
    i0, nx = _lattice(west, east, spacing_m, "x")
    j0, ny = _lattice(south, north, spacing_m, "y")
    _check_size(nx, ny, spacing_m)
    east_m, north_m = np.meshgrid((i0 + np.arange(nx + 1)) * spacing_m, (j0 + np.arange(ny + 1)) * spacing_m)
    # Find up so that (east, north, up) lies on the terrain: the geodetic point of (e, n, u) has
    # height h, the terrain there H, and h grows one for one with u, so u += H - h. The first step
    # (from u = 0) gets u to the tangent-plane drop; the next ones follow the vertical line,
    # which leans from the origin's up by d / R (a node 500 m above the plane, 20 km out, samples
    # 1.6 m further out): three steps leave well under a millimetre.
    up = np.zeros_like(east_m)
    for _ in range(_VERTICAL_STEPS):
        lat, lon, h = geodetic_of_enu(east_m, north_m, up, origin)
        up += _sample_geodetic(grid, lat, lon) - h
    info = dict(grid.info, frame="east-north-up of the geodetic origin (WGS-84)",
                geodetic_origin=list(origin), spacing_m=spacing_m, interpolation="bilinear",
                curvature="z is the height less the drop of the ellipsoid below the origin's tangent plane")
    return PlacedGrid(up, i0 * spacing_m, j0 * spacing_m, spacing_m, origin, info)


def _lattice(lo: float, hi: float, spacing_m: float, axis: str) -> tuple[int, int]:
    """(first index, voxel count) of the lattice multiples of spacing inside [lo, hi]."""
    # spacing_m > 0 was checked by place(); the 1e-9 forgives float rounding of a bound that
    # sits on a lattice point.
    first = math.ceil(lo / spacing_m - 1e-9)
    last = math.floor(hi / spacing_m + 1e-9)
    if last - first < 1:
        raise TerrainError(f"spacing_m: {spacing_m!r} leaves no whole voxel across the source "
                           f"({axis} {lo:.1f} .. {hi:.1f} m)")
    return first, last - first


def _check_size(nx: int, ny: int, spacing_m: float) -> None:
    if (nx + 1) * (ny + 1) > MAX_NODES:
        raise TerrainError(f"spacing_m: {spacing_m!r} makes {nx} x {ny} voxels, more than "
                           f"{MAX_NODES} nodes")


def _geodetic_of_grid_xy(grid: ElevationGrid, gx: np.ndarray, gy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lat, lon) degrees of grid coordinates."""
    if grid.geographic:
        return np.asarray(gy, np.float64), np.asarray(gx, np.float64)
    from rasterio.warp import transform
    lon, lat = transform(grid.crs, "EPSG:4326", np.ravel(gx), np.ravel(gy))
    return np.reshape(lat, np.shape(gx)), np.reshape(lon, np.shape(gx))


def _sample_geodetic(grid: ElevationGrid, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """Bilinear source height at geodetic positions, metres."""
    if grid.geographic:
        # Bring the longitude within 180 degrees of the grid's west edge (topobathy runs 0..360).
        gx = (lon - grid.x[0] + 180.0) % 360.0 + grid.x[0] - 180.0
        gy = lat
    else:
        from rasterio.warp import transform
        xs, ys = transform("EPSG:4326", grid.crs, lon.ravel(), lat.ravel())
        gx, gy = np.reshape(xs, lon.shape), np.reshape(ys, lon.shape)
    return bilinear(grid.values, fractional_index(grid.y, gy), fractional_index(grid.x, gx))
