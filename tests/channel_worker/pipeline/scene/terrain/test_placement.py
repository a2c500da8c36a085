"""Placement of source grids on the world east-north-up node grid."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain.database import TerrainError
from channel_worker.pipeline.scene.terrain.grid import ElevationGrid
from channel_worker.pipeline.scene.terrain.placement import MAX_NODES, native_spacing_m, place
from channel_worker.pipeline.scene.terrain.sources import open_elevation
from services.rig import geodetic

LAT0, LON0 = 36.6, -84.2


def geographic_grid(values_of, *, half_deg=0.15, step_deg=0.002):
    lon = LON0 + np.arange(-half_deg, half_deg + 1e-9, step_deg)
    lat = LAT0 + np.arange(-half_deg, half_deg + 1e-9, step_deg)
    return ElevationGrid(values=values_of(lat[:, None], lon[None, :]) + 0 * lat[:, None] * lon[None, :],
                         x=lon, y=lat, crs="EPSG:4326", info={"source": "test"})


def test_the_origin_node_maps_to_its_height_and_10_km_north_is_lower_by_the_earth_s_curvature():
    h = 120.0
    grid = geographic_grid(lambda lat, lon: np.full(np.broadcast(lat, lon).shape, h))
    placed = place(grid, spacing_m=100.0, origin=(LAT0, LON0, 0.0))
    x, y = placed.node_xy()
    i0, j0 = int(np.flatnonzero(x == 0.0)[0]), int(np.flatnonzero(y == 0.0)[0])
    assert placed.heights[j0, i0] == pytest.approx(h, abs=1e-6)  # world (0, 0, h)
    j10 = int(np.flatnonzero(y == 10_000.0)[0])
    # 10 km out the ellipsoid has dropped d^2 / 2R below the tangent plane: ~7.85 m
    assert placed.heights[j10, i0] - h == pytest.approx(-7.85, abs=0.1)
    assert placed.geodetic_origin == (LAT0, LON0, 0.0)
    assert placed.x0 % 100.0 == 0.0 and placed.y0 % 100.0 == 0.0  # world (0, 0) is a node


def test_a_feature_10_km_north_lands_10_km_north():
    lat_f, lon_f, _ = geodetic.geodetic_of_enu(0.0, 10_000.0, 0.0, (LAT0, LON0, 0.0))
    lat_g, lon_g, _ = geodetic.geodetic_of_enu(-6_000.0, -3_000.0, 0.0, (LAT0, LON0, 0.0))

    def hills(lat, lon):
        d2f = ((lat - lat_f) * 111e3) ** 2 + ((lon - lon_f) * 89e3) ** 2
        d2g = ((lat - lat_g) * 111e3) ** 2 + ((lon - lon_g) * 89e3) ** 2
        return 300.0 + 200.0 * np.exp(-d2f / (2 * 400.0 ** 2)) + 100.0 * np.exp(-d2g / (2 * 400.0 ** 2))

    placed = place(geographic_grid(hills, step_deg=0.001), spacing_m=50.0, origin=(LAT0, LON0, 300.0))
    x, y = placed.node_xy()
    for east, north, rise in ((0.0, 10_000.0, 200.0), (-6_000.0, -3_000.0, 100.0)):
        near = (np.abs(x - east) < 2000)[None, :] & (np.abs(y - north) < 2000)[:, None]
        j, i = np.unravel_index(np.argmax(np.where(near, placed.heights, -np.inf)), placed.heights.shape)
        assert abs(x[i] - east) <= 50.0 and abs(y[j] - north) <= 50.0
        drop = (east ** 2 + north ** 2) / (2 * 6.37e6)
        assert placed.heights[j, i] == pytest.approx(rise - drop, abs=2.0)


def test_the_node_grid_lies_inside_the_source_and_covers_most_of_it():
    grid = geographic_grid(lambda lat, lon: lat * 0 + lon * 0 + 5.0)
    placed = place(grid, spacing_m=200.0, origin=(LAT0, LON0, 0.0))
    x, y = placed.node_xy()
    corners_lat, corners_lon, _ = geodetic.geodetic_of_enu(x[[0, -1, 0, -1]], y[[0, 0, -1, -1]], 0.0,
                                                           (LAT0, LON0, 0.0))
    assert np.all((corners_lat >= grid.y[0]) & (corners_lat <= grid.y[-1]))
    assert np.all((corners_lon >= grid.x[0]) & (corners_lon <= grid.x[-1]))
    assert (x[-1] - x[0]) > 0.9 * 0.3 * 89e3 and (y[-1] - y[0]) > 0.9 * 0.3 * 111e3
    np.testing.assert_allclose(placed.heights + (x[None, :] ** 2 + y[:, None] ** 2) / (2 * 6.37e6), 5.0, atol=1.0)


def test_a_projected_grid_is_placed_through_its_crs(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    from affine import Affine
    from rasterio.warp import transform

    # A UTM 17N grid (30 m) whose height is its northing in km: the node at the origin samples it.
    (e0,), (n0,) = transform("EPSG:4326", "EPSG:32617", [LON0], [LAT0])
    west, north = e0 - 3000.0, n0 + 3000.0
    rows = cols = 201
    northing = north - (np.arange(rows) + 0.5) * 30.0
    values = np.repeat((northing / 1000.0)[:, None], cols, axis=1).astype(np.float32)
    path = tmp_path / "utm.tif"
    with rasterio.open(path, "w", driver="GTiff", height=rows, width=cols, count=1, dtype="float32",
                       crs="EPSG:32617", transform=Affine(30.0, 0, west, 0, -30.0, north)) as ds:
        ds.write(values, 1)
    placed = place(open_elevation(str(path)), spacing_m=25.0, origin=(LAT0, LON0, 0.0))
    x, y = placed.node_xy()
    i0, j0 = int(np.flatnonzero(x == 0.0)[0]), int(np.flatnonzero(y == 0.0)[0])
    assert placed.heights[j0, i0] == pytest.approx(n0 / 1000.0, abs=1e-3)
    # 1 km north the UTM northing has grown by ~1 km (scale factor and grid convergence: 0.1 %),
    # so the height by 1 m, less the 7.85 cm the ellipsoid drops below the tangent plane there
    j1 = int(np.flatnonzero(y == 1000.0)[0])
    assert placed.heights[j1, i0] - placed.heights[j0, i0] == pytest.approx(1.0 - 0.0785, abs=0.003)
    assert 5500 < x[-1] - x[0] < 6000  # the 6 km grid, less the 1.9 degree grid convergence


def test_a_grid_without_crs_is_placed_in_its_own_metres():
    grid = ElevationGrid(values=np.add.outer(np.arange(11.0), np.arange(21.0)),
                         x=5000.0 + 10.0 * np.arange(21), y=7000.0 + 10.0 * np.arange(11), crs="",
                         info={"source": "local.asc"})
    placed = place(grid, spacing_m=5.0)
    assert placed.geodetic_origin is None and placed.info["local_offset"] == [5100.0, 7050.0]
    x, y = placed.node_xy()
    assert (x[0], x[-1], y[0], y[-1]) == (-100.0, 100.0, -50.0, 50.0)
    # node (2, 3) is at file (x 5015, y 7010): between cells (row 1, columns 1 and 2), bilinear
    assert placed.heights[2, 3] == pytest.approx(1.0 + 1.5)
    with pytest.raises(TerrainError, match=r"origin: .* needs a source with a CRS; local.asc has none"):
        place(grid, spacing_m=5.0, origin=(LAT0, LON0, 0.0))
    assert native_spacing_m(grid) == 10.0


def test_bad_spacings_are_refused():
    grid = geographic_grid(lambda lat, lon: lat * 0 + lon * 0)
    with pytest.raises(TerrainError, match=r"spacing_m: 100000.0 leaves no whole voxel"):
        place(grid, spacing_m=1e5)
    with pytest.raises(TerrainError, match=f"spacing_m: 1.0 makes .* more than {MAX_NODES} nodes"):
        place(grid, spacing_m=1.0)
    with pytest.raises(TerrainError, match="spacing_m: -5"):
        place(grid, spacing_m=-5.0)
    with pytest.raises(TerrainError, match="origin"):
        place(grid, spacing_m=100.0, origin=(95.0, 0.0, 0.0))


def test_default_origin_and_spacing():
    grid = open_elevation("mpl:jacksboro")
    assert native_spacing_m(grid) == pytest.approx(74.5, abs=0.5)  # 3 arc-seconds of longitude at 36.6 N
    placed = place(grid, spacing_m=500.0)
    lat, lon, h = placed.geodetic_origin
    assert lat == pytest.approx(36.5896, abs=1e-3) and lon == pytest.approx(-84.2458, abs=1e-3) and h == 0.0
    assert 230 < placed.heights.max() < 1080  # world z = height above the datum, less curvature
