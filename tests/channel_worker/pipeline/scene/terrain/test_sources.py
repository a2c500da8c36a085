"""Elevation sources (matplotlib samples, GeoTIFF, ESRI ASCII) and colour sources."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain.database import TerrainError
from channel_worker.pipeline.scene.terrain.sources import colour_nodes, open_elevation

rasterio = pytest.importorskip("rasterio")
from affine import Affine  # noqa: E402  (rasterio brings affine: only once it is known installed)


def from_origin(west, north, xsize, ysize):
    """North-up transform (rasterio.transform.from_origin multiplies Affines with `*`, which
    affine 3 warns about, and warnings are errors here)."""
    return Affine(xsize, 0.0, west, 0.0, -ysize, north)


def write_raster(path, values, *, transform, crs=None, nodata=None, driver="GTiff"):
    """values row 0 = north (the file's order)."""
    with rasterio.open(path, "w", driver=driver, height=values.shape[0], width=values.shape[1], count=1,
                       dtype=values.dtype, transform=transform, crs=crs, nodata=nodata) as ds:
        ds.write(values, 1)
    return path


def test_geotiff_geographic_round_trip(tmp_path):
    values = np.arange(20, dtype=np.float32).reshape(4, 5)  # row 0 north
    path = write_raster(tmp_path / "dem.tif", values, transform=from_origin(8.0, 47.5, 0.01, 0.02),
                        crs="EPSG:4326")
    grid = open_elevation(str(path))
    assert grid.crs == "EPSG:4326" and grid.geographic
    np.testing.assert_array_equal(grid.values, values[::-1])  # row 0 south
    np.testing.assert_allclose(grid.x, 8.005 + 0.01 * np.arange(5))
    np.testing.assert_allclose(grid.y, 47.5 - 0.07 + 0.02 * np.arange(4))
    assert grid.values.dtype == np.float64 and grid.info["source"] == str(path)


def test_geotiff_projected_keeps_its_crs(tmp_path):
    values = np.full((3, 3), 5.0, np.float32)
    path = write_raster(tmp_path / "utm.tiff", values, transform=from_origin(500000.0, 4100000.0, 30.0, 30.0),
                        crs="EPSG:32617")
    grid = open_elevation(str(path))
    assert grid.crs == "EPSG:32617" and not grid.geographic
    np.testing.assert_allclose(grid.x, [500015.0, 500045.0, 500075.0])
    np.testing.assert_allclose(grid.y, [4099925.0, 4099955.0, 4099985.0])


def test_esri_ascii_round_trip_with_and_without_prj(tmp_path):
    values = np.arange(12, dtype=np.float32).reshape(3, 4) * 2.5
    path = write_raster(tmp_path / "dem.asc", values, transform=from_origin(1000.0, 2000.0, 10.0, 10.0),
                        driver="AAIGrid")
    assert path.read_text().startswith("ncols")
    grid = open_elevation(str(path))
    assert grid.crs == ""  # no .prj: local metres
    np.testing.assert_array_equal(grid.values, values[::-1])
    np.testing.assert_allclose(grid.x, [1005.0, 1015.0, 1025.0, 1035.0])
    np.testing.assert_allclose(grid.y, [1975.0, 1985.0, 1995.0])
    with_prj = write_raster(tmp_path / "geo.asc", values, transform=from_origin(8.0, 47.0, 0.001, 0.001),
                            crs="EPSG:4326", driver="AAIGrid")
    assert (tmp_path / "geo.prj").exists()
    assert open_elevation(str(with_prj)).crs == "EPSG:4326"


def test_nodata_is_filled_from_the_surroundings_or_refused_with_its_count(tmp_path):
    values = np.full((6, 6), 42.0, np.float32)
    values[2:4, 1:3] = -9999.0
    values[5, 5] = np.nan
    path = write_raster(tmp_path / "holes.tif", values, transform=from_origin(0, 0.06, 0.01, 0.01),
                        crs="EPSG:4326", nodata=-9999.0)
    grid = open_elevation(str(path))
    np.testing.assert_allclose(grid.values, 42.0)
    assert grid.info["nodata_filled"] == 5
    with pytest.raises(TerrainError, match=r"holes.tif: nodata: 5 of 36 cells are nodata \(-9999.0\)"):
        open_elevation(f"{path}?nodata=refuse")
    empty = write_raster(tmp_path / "empty.tif", np.full((2, 2), -1.0, np.float32),
                         transform=from_origin(0, 1, 1, 1), nodata=-1.0)
    with pytest.raises(TerrainError, match=r"empty.tif: nodata: every one of the 4 cells is nodata"):
        open_elevation(str(empty))


def ascii_grid(path, rows, *, cellsize="10", extra=""):
    """An ESRI ASCII grid written as text, rows top (north) first."""
    body = "".join(" ".join(row) + "\n" for row in rows)
    path.write_text(f"ncols {len(rows[0])}\nnrows {len(rows)}\nxllcorner 0\nyllcorner 0\n"
                    f"cellsize {cellsize}\n{extra}{body}")
    return path


@pytest.mark.parametrize("cells", [
    # GDAL reads a grid of whole numbers as integers: nan would be 0, inf the largest float32.
    [["1", "2", "3"], ["4", "nan", "6"], ["7", "inf", "9"]],
    [["1.5", "2", "3"], ["4", "NaN", "6"], ["7", "-Infinity", "1e999"]],
])
def test_esri_ascii_cells_that_are_not_finite_are_nodata(tmp_path, cells):
    path = ascii_grid(tmp_path / "odd.asc", cells)
    bad = sum(1 for row in cells for v in row if v.lower().lstrip("+-")[:3] in ("nan", "inf") or "e999" in v)
    with pytest.raises(TerrainError) as exc:
        open_elevation(f"{path}?nodata=refuse")
    assert str(exc.value).startswith(f"{path}: nodata: {bad} of 9 cells are nodata or not finite, the first "
                                     f"at row 1, column 1 (from 0, the file's first row and column): {cells[1][1]};")
    grid = open_elevation(str(path))  # filled from the neighbours, not 0 or 3.4e38
    assert grid.info["nodata_filled"] == bad
    assert np.all(grid.values >= 1.0) and np.all(grid.values <= 9.0)


def test_geotiff_cells_that_are_not_finite_are_refused_with_the_first_one(tmp_path):
    values = np.full((4, 5), 42.0, np.float32)
    values[2, 3] = np.inf
    values[3, 0] = np.nan
    path = write_raster(tmp_path / "odd.tif", values, transform=from_origin(0, 4, 1, 1))
    with pytest.raises(TerrainError, match=r"odd.tif: nodata: 2 of 20 cells are nodata or not finite, the first "
                                           r"at row 2, column 3 \(.*\): inf;"):
        open_elevation(f"{path}?nodata=refuse")
    np.testing.assert_allclose(open_elevation(str(path)).values, 42.0)


@pytest.mark.parametrize("header,field,value", [
    ({"cellsize": "-10"}, "cellsize", "'-10'"), ({"cellsize": "0"}, "cellsize", "'0'"),
    ({"cellsize": "nan"}, "cellsize", "'nan'"), ({"cellsize": "inf"}, "cellsize", "'inf'"),
    ({"cellsize": "ten"}, "cellsize", "'ten'"),
    ({"cellsize": None, "dx": "10", "dy": "-5"}, "dy", "'-5'"),
])
def test_a_cell_size_that_is_not_finite_and_positive_is_refused(tmp_path, header, field, value):
    size = header.pop("cellsize")
    extra = "".join(f"{k} {v}\n" for k, v in header.items())
    path = ascii_grid(tmp_path / "g.asc", [["1", "2"], ["3", "4"]], cellsize=size, extra=extra)
    if size is None:
        path.write_text(path.read_text().replace("cellsize None\n", ""))
    with pytest.raises(TerrainError, match=rf"g.asc: {field}: {value} is not a finite cell size > 0"):
        open_elevation(str(path))


@pytest.mark.parametrize("mode", ["fill", "refuse"])
@pytest.mark.parametrize("cells,shown,row,col,count", [
    # GDAL reads each of these as 0 (1_000 as 1) and the build would succeed.
    (b"1 2 3\n4 abc 6\n7 8 xyz\n", "'abc'", 1, 1, 2),
    (b"1 2 3\n4 5 6\n7 \xff\xfe 9\n", r"'\xff\xfe'", 2, 1, 1),
    (b"1 2 3\n4 1_000 6\n7 8 9\n", "'1_000'", 1, 1, 1),
    (b"1 2 3\n4 5 0x10\n7 8 9\n", "'0x10'", 1, 2, 1),
    (b"1 2 3\n4 5 1e\n7 8 9\n", "'1e'", 1, 2, 1),  # only digits: numpy's parse fails, the search names it
    # A first row that starts with a word is a damaged cell, not more header (as GDAL would take it).
    (b"abc 2 3\n4 5 6\n7 8 9\n", "'abc'", 0, 0, 1),
])
def test_esri_ascii_cells_that_are_not_numbers_are_refused_in_both_modes(tmp_path, mode, cells, shown, row, col,
                                                                         count):
    path = tmp_path / "bad.asc"
    path.write_bytes(b"ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\n" + cells)
    with pytest.raises(TerrainError) as exc:
        open_elevation(f"{path}?nodata={mode}")
    assert str(exc.value) == (f"{path}: cells: row {row}, column {col} (from 0, the file's first row and column): "
                              f"{shown} is not a number (cells that are not: {count}); the file is damaged")


@pytest.mark.parametrize("cells,count", [("1 2 3\n4 5 6\n7 8\n", 8), ("1 2 3\n4 5 6\n7 8 9 10\n", 10)])
def test_esri_ascii_cell_count_must_be_ncols_by_nrows(tmp_path, cells, count):
    # GDAL pads a short grid with 0 and drops the extra cells of a long one.
    path = tmp_path / "g.asc"
    path.write_text(f"ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\n{cells}")
    with pytest.raises(TerrainError, match=rf"g.asc: cells: the file has {count} cells, not ncols x nrows = "
                                           rf"3 x 3 = 9$"):
        open_elevation(str(path))


@pytest.mark.parametrize("mode", ["fill", "refuse"])
@pytest.mark.parametrize("cell,metres", [
    ("30000000000", "3e+10"),  # GDAL's int32 wraps it to -64771072
    ("1e39", "1e+39"),  # GDAL's float32 clamps it to 3.4e38
    ("-12000.5", "-12000.5"), ("9000.001", "9000"),
])
def test_esri_ascii_heights_outside_the_plausible_range_are_refused(tmp_path, mode, cell, metres):
    path = ascii_grid(tmp_path / "high.asc", [["1", "2", "3"], ["4", "5", "6"], ["7", cell, "9"]])
    with pytest.raises(TerrainError) as exc:
        open_elevation(f"{path}?nodata={mode}")
    assert str(exc.value) == (f"{path}: heights: 1 of 9 cells are outside -12000 .. 9000 m (the Challenger Deep "
                              f"to above Everest), the first at row 2, column 1 (from 0, the file's first row and "
                              f"column): {cell} ({metres} m)")


def test_esri_ascii_heights_are_the_texts_own_values(tmp_path):
    # The limits themselves are plausible; a declared nodata value outside them is nodata, not a
    # height; decimals keep float64 precision (GDAL's float32 would give 8848.8603515625).
    path = ascii_grid(tmp_path / "ok.asc", [["-12000", "9000", "8848.86"], ["4", "-99999", "6"]],
                      extra="NODATA_value -99999\n")
    grid = open_elevation(str(path))
    assert grid.info["nodata_filled"] == 1
    np.testing.assert_array_equal(grid.values[1], [-12000.0, 9000.0, 8848.86])  # row 0 south: the file's last
    with pytest.raises(TerrainError, match=r"ok.asc: nodata: 1 of 6 cells are nodata \(-99999.0\) or not finite, "
                                           r"the first at row 1, column 1 \(.*\): -99999;"):
        open_elevation(f"{path}?nodata=refuse")


def test_geotiff_heights_outside_the_plausible_range_are_refused(tmp_path):
    values = np.full((4, 5), 42.0, np.float32)
    values[1, 2] = 1e30
    values[3, 4] = -32768.0  # SRTM's void, not declared as nodata
    path = write_raster(tmp_path / "high.tif", values, transform=from_origin(0, 4, 1, 1))
    for mode in ("fill", "refuse"):
        with pytest.raises(TerrainError, match=r"high.tif: heights: 2 of 20 cells are outside -12000 .. 9000 m "
                                               r"\(.*\), the first at row 1, column 2 \(from 0, the file's first "
                                               r"row and column\): 1.00000001504\d*e\+30 \(1e\+30 m\)$"):
            open_elevation(f"{path}?nodata={mode}")
    declared = write_raster(tmp_path / "void.tif", np.where(values > 1e6, 42.0, values).astype(np.int16),
                            transform=from_origin(0, 4, 1, 1), nodata=-32768)
    np.testing.assert_allclose(open_elevation(str(declared)).values, 42.0)
    # The range is in metres, after the band's unit: 30000 ft is 9144 m.
    feet = write_raster(tmp_path / "feet.tif", np.full((2, 2), 30000, np.int16), transform=from_origin(0, 2, 1, 1))
    with rasterio.open(feet, "r+") as ds:
        ds.units = ("ft",)
    with pytest.raises(TerrainError, match=r"feet.tif: heights: 4 of 4 .*: 30000 \(9144 m\)$"):
        open_elevation(str(feet))


def test_bad_raster_sources_are_named(tmp_path):
    rotated = write_raster(tmp_path / "rot.tif", np.zeros((3, 3), np.float32),
                           transform=Affine(1.0, 0.2, 0.0, 0.1, -1.0, 3.0))
    with pytest.raises(TerrainError, match=r"rot.tif: transform: .* is rotated"):
        open_elevation(str(rotated))
    (tmp_path / "junk.tif").write_text("not a tiff")
    with pytest.raises(TerrainError, match=r"source: '.*junk.tif' cannot be read"):
        open_elevation(str(tmp_path / "junk.tif"))
    with pytest.raises(TerrainError, match=r"source: '.*none.asc' is not a file"):
        open_elevation(str(tmp_path / "none.asc"))
    with pytest.raises(TerrainError, match="nodata: 'maybe' is not valid"):
        open_elevation(f"{rotated}?nodata=maybe")
    with pytest.raises(TerrainError, match=r"unknown option.*colour"):
        open_elevation(f"{rotated}?colour=red")
    with pytest.raises(TerrainError, match=r"source: 'dem.png' is not mpl:jacksboro"):
        open_elevation("dem.png")
    with pytest.raises(TerrainError, match="'mpl:everest' is not mpl:jacksboro or mpl:topobathy"):
        open_elevation("mpl:everest")


def test_mpl_jacksboro_is_north_up():
    from matplotlib import cbook
    grid = open_elevation("mpl:jacksboro")
    assert grid.values.shape == (344, 403) and grid.geographic
    # y ascends from the southern row (the file's last) to the northern (the file's first, 'ymin')
    assert grid.y[0] == pytest.approx(36.44625 + 0.5 / 1200)
    assert grid.y[-1] == pytest.approx(36.73292 - 0.5 / 1200, abs=1e-5)
    assert grid.x[0] == pytest.approx(-84.41375 + 0.5 / 1200)
    with np.load(cbook.get_sample_data("jacksboro_fault_dem.npz", asfileobj=False)) as dem:
        raw = dem["elevation"]
    # matplotlib's hillshading example draws raw row 0 at the top of a north-up map
    np.testing.assert_array_equal(grid.values[-1], raw[0])
    np.testing.assert_array_equal(grid.values[0], raw[-1])
    assert "public domain" in grid.info["licence"] and "Geological Survey" in grid.info["attribution"]
    # A known feature: the long straight ridge in the north-east quadrant, Pine Mountain, trends
    # north-east, so its flanks face north-west and south-east and the east and north slopes
    # are anti-correlated there. Upside down the ridge would trend south-east (correlation > 0).
    window = grid.values[np.ix_((grid.y >= 36.60) & (grid.y <= 36.72), (grid.x >= -84.20) & (grid.x <= -84.08))]
    dz_dnorth, dz_deast = np.gradient(window, 92.6, 74.5)
    corr = (dz_deast * dz_dnorth).mean() / np.sqrt((dz_deast ** 2).mean() * (dz_dnorth ** 2).mean())
    assert corr < -0.2


def test_mpl_topobathy_has_irregular_latitudes():
    grid = open_elevation("mpl:topobathy")
    assert grid.values.shape == (91, 120) and grid.values.min() < 0 < grid.values.max()
    assert np.all(np.diff(grid.y) > 0) and np.diff(grid.y).max() > 1.03 * np.diff(grid.y).min()


def test_relief_lights_the_slopes_facing_the_sun():
    j, i = np.mgrid[0:21, 0:21].astype(float)
    rising_north = 2.0 * j  # faces south
    lit_from_south = colour_nodes("relief:gray?azimuth=180&altitude=30", rising_north, spacing_m=10.0)
    lit_from_north = colour_nodes("relief:gray?azimuth=0&altitude=30", rising_north, spacing_m=10.0)
    assert lit_from_south.shape == (21, 21, 3)
    assert lit_from_south.min() >= 0.0 and lit_from_north.max() <= 1.0
    assert lit_from_south[10, 10].mean() > lit_from_north[10, 10].mean() + 0.05
    rising_east = 2.0 * i  # faces west
    lit_from_west = colour_nodes("relief:gray?azimuth=270&altitude=30", rising_east, spacing_m=10.0)
    lit_from_east = colour_nodes("relief:gray?azimuth=90&altitude=30", rising_east, spacing_m=10.0)
    assert lit_from_west[10, 10].mean() > lit_from_east[10, 10].mean() + 0.05
    # hypsometric tint: with no relief to shade, higher is further along the colour map (gray: brighter)
    flat_low = colour_nodes("relief:gray", np.where(j < 10, 0.0, 100.0), spacing_m=1e6)
    assert flat_low[2, 2].mean() < flat_low[18, 18].mean()


def test_bad_colour_urls_are_named():
    h = np.zeros((3, 3))
    with pytest.raises(TerrainError, match="'no_such_map' is not a matplotlib colour map"):
        colour_nodes("relief:no_such_map", h, spacing_m=1.0)
    with pytest.raises(TerrainError, match="azimuth: 'west' is not valid"):
        colour_nodes("relief:gist_earth?azimuth=west", h, spacing_m=1.0)
    with pytest.raises(TerrainError, match=r"span: '0.9,0.1' is not valid"):
        colour_nodes("relief:gist_earth?span=0.9,0.1", h, spacing_m=1.0)
    with pytest.raises(TerrainError, match=r"unknown option.*sun"):
        colour_nodes("relief:gist_earth?sun=1", h, spacing_m=1.0)
    with pytest.raises(TerrainError, match="cannot be read"):
        colour_nodes("/nonexistent/photo.png", h, spacing_m=1.0)


def test_an_image_is_stretched_over_the_extent_top_row_north(tmp_path):
    from services.rig.image_io import write_image
    red, green, blue, white = [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1.0, 1.0, 1.0]
    write_image(tmp_path / "map.png", np.array([[red, green], [blue, white]], np.float32))
    colours = colour_nodes(str(tmp_path / "map.png"), np.zeros((11, 21)), spacing_m=5.0)
    assert colours.shape == (11, 21, 3)
    np.testing.assert_allclose(colours[0, 0], blue, atol=1e-6)  # south-west node: bottom-left pixel
    np.testing.assert_allclose(colours[-1, -1], green, atol=1e-6)  # north-east: top-right
    np.testing.assert_allclose(colours[-1, 0], red, atol=1e-6)
    np.testing.assert_allclose(colours[0, -1], white, atol=1e-6)
    mid = colours[5, 10]  # the centre blends all four pixels, in the file's sRGB encoding
    assert 0.1 < mid[0] < 0.5 and 0.1 < mid[2] < 0.5


def test_band_scale_offset_and_feet_are_applied(tmp_path):
    path = tmp_path / "feet.tif"
    with rasterio.open(path, "w", driver="GTiff", height=2, width=2, count=1, dtype="int16",
                       transform=from_origin(0, 2, 1, 1), crs="EPSG:4326") as ds:
        ds.write(np.array([[100, 200], [300, 400]], np.int16), 1)
        ds.scales, ds.offsets = (0.5,), (10.0,)
        ds.units = ("ft",)
    grid = open_elevation(str(path))
    np.testing.assert_allclose(grid.values, (np.array([[300, 400], [100, 200]]) * 0.5 + 10.0) * 0.3048)
    with rasterio.open(path, "r+") as ds:
        ds.units = ("furlong",)
    with pytest.raises(TerrainError, match=r"feet.tif: units: 'furlong'"):
        open_elevation(str(path))


def test_a_missing_backend_is_a_terrain_error_naming_the_extra(monkeypatch):
    import builtins
    real_import = builtins.__import__

    def no_matplotlib(name, *args, **kwargs):
        if name.split(".")[0] == "matplotlib":
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_matplotlib)
    monkeypatch.setattr("importlib.import_module", lambda name: no_matplotlib(name))
    with pytest.raises(TerrainError, match=r"mpl:jacksboro: needs matplotlib.*ig-rig\[gis\]"):
        open_elevation("mpl:jacksboro")
    with pytest.raises(TerrainError, match=r"relief:gist_earth: needs matplotlib"):
        colour_nodes("relief:gist_earth", np.zeros((2, 2)), spacing_m=1.0)
