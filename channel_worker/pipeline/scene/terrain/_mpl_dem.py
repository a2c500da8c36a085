"""``mpl:NAME`` elevation sources: the sample DEMs bundled with matplotlib.

``mpl:jacksboro`` is ``jacksboro_fault_dem.npz``: ``elevation`` (344, 403) int16 metres on a
3 arc-second grid (``dx`` = ``dy`` = 1/1200 degree) with ``xmin``/``xmax`` the western/eastern
longitudes and ``ymin``/``ymax`` the latitudes of the FIRST and LAST rows: 'ymin' (36.733) is the
north edge, 'ymax' (36.446) the south. How that was determined: matplotlib's own
topographic_hillshading example shows the array with imshow's default origin='upper' (row 0 at
the top of a north-up map) and lights it with LightSource(azdeg=315), "from the northwest";
LightSource.hillshade itself negates dy because "the first row in the array [is] the top of the
image"; and its 3-D surface example spreads the rows over linspace(ymin, ymax, nrows), putting
row 0 at ymin = 36.733. All three say row 0 is the northern row. The terrain agrees: read so,
the long straight ridge in the north-east quadrant trends north-east, as Pine Mountain does from
near Jellico into Kentucky, and the lineament cutting the block on its south-west side trends
north-west, as the Jacksboro fault does; flipped north-south both would trend the wrong way
(tests/channel_worker/terrain/test_sources.py checks the ridge's trend). The bounds are the outer cell
edges: (xmax - xmin) / dx = 403.0 and (ymin - ymax) / dy = 344.0 cells exactly, and the cell
centres then fall on whole multiples of 3 arc-seconds, as USGS 3" data do.

``mpl:topobathy`` is ``topobathy.npz``: ``topo`` (91, 120) float32 metres (negative below sea
level), with 1-D ``longitude`` (degrees east, 0..360) and ``latitude`` (increasing with the row:
row 0 is south) of the cell centres; the latitude steps shrink northwards by 4 % (Mercator-like),
so the grid is rectilinear, not regular.
"""

from __future__ import annotations

import numpy as np

from .database import TerrainError
from .grid import ElevationGrid

JACKSBORO_INFO = {
    "source": "mpl:jacksboro (matplotlib sample data jacksboro_fault_dem.npz)",
    "licence": "USGS elevation data, public domain (U.S. Government work); redistributed with "
               "matplotlib's sample data under the matplotlib licence",
    "attribution": "Elevation: U.S. Geological Survey, via matplotlib's sample data "
                   "(jacksboro_fault_dem.npz)",
}
TOPOBATHY_INFO = {
    "source": "mpl:topobathy (matplotlib sample data topobathy.npz)",
    "licence": "matplotlib licence (shipped with matplotlib's sample data; matplotlib does not "
               "document the original survey)",
    "attribution": "Topography/bathymetry: matplotlib sample data (topobathy.npz)",
}


def open_mpl_dem(name: str) -> ElevationGrid:
    """Read one of matplotlib's sample DEMs as an ElevationGrid (row 0 south, WGS-84 lon/lat)."""
    if name == "jacksboro":
        return _jacksboro()
    if name == "topobathy":
        return _topobathy()
    raise TerrainError(f"source: 'mpl:{name}' is not mpl:jacksboro or mpl:topobathy")


def _sample_path(filename: str) -> str:
    from matplotlib import cbook
    return str(cbook.get_sample_data(filename, asfileobj=False))


def _jacksboro() -> ElevationGrid:
    with np.load(_sample_path("jacksboro_fault_dem.npz")) as dem:
        elevation = np.asarray(dem["elevation"], np.float64)
        dx, dy = float(dem["dx"]), float(dem["dy"])
        west, north, south = float(dem["xmin"]), float(dem["ymin"]), float(dem["ymax"])
    rows, cols = elevation.shape
    lon = west + (np.arange(cols) + 0.5) * dx
    lat = south + (np.arange(rows) + 0.5) * dy
    if abs(lat[-1] + 0.5 * dy - north) > 1e-3 * dy:
        raise TerrainError(f"mpl:jacksboro: ymin: {north!r} is not the north edge {lat[-1] + 0.5 * dy!r}")
    info = dict(JACKSBORO_INFO, cell_deg=[dx, dy],
                bounds_deg={"west": west, "east": west + cols * dx, "south": south, "north": north})
    return ElevationGrid(values=elevation[::-1].copy(), x=lon, y=lat, crs="EPSG:4326", info=info)


def _topobathy() -> ElevationGrid:
    with np.load(_sample_path("topobathy.npz")) as dem:
        topo = np.asarray(dem["topo"], np.float64)
        lon = np.asarray(dem["longitude"], np.float64)
        lat = np.asarray(dem["latitude"], np.float64)
    return ElevationGrid(values=topo, x=lon, y=lat, crs="EPSG:4326", info=dict(TOPOBATHY_INFO))
