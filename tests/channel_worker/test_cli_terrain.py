"""`ig terrain build` and `ig terrain info`."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.scene.terrain.store import load_terrain
from services.cli import main


@pytest.fixture(scope="module")
def dem(tmp_path_factory):
    rasterio = pytest.importorskip("rasterio")
    from affine import Affine
    path = tmp_path_factory.mktemp("dem") / "hill.tif"
    rows, cols = 60, 80
    j, i = np.mgrid[0:rows, 0:cols]
    values = (300.0 + 80.0 * np.exp(-((i - 50) ** 2 + (j - 20) ** 2) / 60.0)).astype(np.float32)
    with rasterio.open(path, "w", driver="GTiff", height=rows, width=cols, count=1, dtype="float32",
                       crs="EPSG:4326", transform=Affine(0.0005, 0, 8.0, 0, -0.0005, 47.03)) as ds:
        ds.write(values, 1)
    return path


def test_build_then_info(dem, tmp_path, capsys):
    out = tmp_path / "hill.igt"
    assert main(["terrain", "build", str(dem), "--out", str(out), "--spacing", "20", "--origin", "47.015,8.02,300",
                 "--flatten=-200,-300,200,300,0,100", "--trees", "0.2", "--page-size", "16",
                 "--prune", "0.5,0.01", "--colour", "relief:terrain?azimuth=300"]) == 0
    said = capsys.readouterr().out
    assert said.startswith(f"wrote {out}:") and "voxels of 20 m" in said
    db = load_terrain(out)
    assert db.page_size == 16 and db.info["recipe"]["flatten"] == [[-200.0, -300.0, 200.0, 300.0, 0.0, 100.0]]
    assert db.info["recipe"]["origin"] == [47.015, 8.02, 300.0] and db.pattern.any()
    assert db.info["build"]["prune_tolerance"] == [0.5, 0.01]
    assert main(["terrain", "info", str(out)]) == 0
    info = capsys.readouterr().out
    for text in ("level 0", f"{db.levels - 1}", "present", "missing", "extent", "z ", "licence", "lat 47.015"):
        assert text in info
    # building again over the same database replaces it
    assert main(["terrain", "build", str(dem), "--out", str(out), "--spacing", "40"]) == 0
    assert load_terrain(out).spacing_m == 40.0


def test_build_the_matplotlib_sample(tmp_path, capsys):
    out = tmp_path / "j.igt"
    assert main(["terrain", "build", "mpl:jacksboro", "--out", str(out), "--spacing", "400"]) == 0
    assert main(["terrain", "info", str(out)]) == 0
    assert "U.S. Geological Survey" in capsys.readouterr().out


@pytest.mark.parametrize("argv,option", [
    (["--spacing", "0"], "--spacing"), (["--spacing", "nan"], "--spacing"),
    (["--origin", "95,0,0"], "--origin"), (["--origin", "1,2"], "--origin"),
    (["--flatten=1,2,3"], "--flatten"), (["--flatten=5,0,1,1,0,0"], "--flatten"),
    (["--trees", "2"], "--trees"), (["--page-size", "0"], "--page-size"), (["--page-size", "1.5"], "--page-size"),
    (["--prune", "1"], "--prune"), (["--prune=-1,0"], "--prune"),
])
def test_bad_options_exit_2_naming_the_option_and_value(argv, option, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["terrain", "build", "mpl:jacksboro", "--out", str(tmp_path / "x.igt"), *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert option in err and argv[-1].split("=")[-1] in err
    assert not (tmp_path / "x.igt").exists()


def test_bad_input_at_run_time_exits_2_with_one_line(dem, tmp_path, capsys):
    cases = [
        (["terrain", "build", "mpl:nowhere", "--out", str(tmp_path / "a.igt")], "source: 'mpl:nowhere'"),
        (["terrain", "build", str(dem), "--out", str(tmp_path / "b.igt"), "--colour", "relief:nope"],
         "'nope' is not a matplotlib colour map"),
        (["terrain", "build", str(dem), "--out", str(tmp_path / "c.igt"), "--spacing", "100000"],
         "spacing_m: 100000.0"),
        (["terrain", "info", str(tmp_path)], "terrain.json: no such file"),
    ]
    for argv, message in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("ig terrain: error: ") and message in err and err.count("\n") == 1
    (tmp_path / "notes.txt").write_text("keep me")
    assert main(["terrain", "build", str(dem), "--out", str(tmp_path)]) == 2
    assert "--out" in capsys.readouterr().err and (tmp_path / "notes.txt").exists()


@pytest.mark.parametrize("cells,cellsize,message", [
    ("1 2 3\n4 nan 6\n7 8 inf\n", "10",
     "nodata: 2 of 9 cells are nodata or not finite, the first at row 1, column 1"),
    ("1 2 3\n4 5 6\n7 8 9\n", "-10", "cellsize: '-10' is not a finite cell size > 0"),
    ("1 2 3\n4 5 6\n7 8 9\n", "0", "cellsize: '0' is not a finite cell size > 0"),
])
def test_cells_that_are_not_finite_and_bad_cell_sizes_exit_2_with_one_line(tmp_path, capsys, cells, cellsize,
                                                                           message):
    pytest.importorskip("rasterio")
    path = tmp_path / "dem.asc"
    path.write_text(f"ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize {cellsize}\n{cells}")
    out = tmp_path / "dem.igt"
    assert main(["terrain", "build", f"{path}?nodata=refuse", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ig terrain: error: ") and message in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("mode", ["fill", "refuse"])
@pytest.mark.parametrize("cells,message", [
    # Each built with exit 0 before: GDAL read the cell as 0, wrapped it or clamped it.
    (b"1 2 3\n4 abc 6\n7 8 9\n", "cells: row 1, column 1 (from 0, the file's first row and column): 'abc' is not "
                                 "a number"),
    (b"1 2 3\n4 5 6\n\xff\xfe 8 9\n", r"cells: row 2, column 0 (from 0, the file's first row and column): "
                                      r"'\xff\xfe' is not a number"),
    (b"1 2 3\n4 5 6\n7 8 30000000000\n", "heights: 1 of 9 cells are outside -12000 .. 9000 m (the Challenger Deep "
                                         "to above Everest), the first at row 2, column 2 (from 0, the file's first "
                                         "row and column): 30000000000 (3e+10 m)"),
    (b"1 2 3\n4 1e39 6\n7 8 9\n", "heights: 1 of 9 cells are outside -12000 .. 9000 m"),
    (b"1 2 3\n4 5 6\n7 8\n", "cells: the file has 8 cells, not ncols x nrows = 3 x 3 = 9"),
])
def test_damaged_cells_and_implausible_heights_exit_2_with_one_line_in_both_modes(tmp_path, capsys, mode, cells,
                                                                                  message):
    pytest.importorskip("rasterio")
    path = tmp_path / "dem.asc"
    path.write_bytes(b"ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\n" + cells)
    out = tmp_path / "dem.igt"
    assert main(["terrain", "build", f"{path}?nodata={mode}", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"ig terrain: error: {path}: ") and message in err and err.count("\n") == 1
    assert not out.exists()


def test_help_describes_every_option(capsys):
    from services.cli import build_parser
    for argv in (["terrain", "--help"], ["terrain", "build", "--help"], ["terrain", "info", "--help"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 0
    assert "--prune" in capsys.readouterr().out
    terrain = build_parser()._subparsers._group_actions[0].choices["terrain"]
    for action in terrain._actions:
        assert action.help
    for sub in terrain._subparsers._group_actions[0].choices.values():
        for action in sub._actions:
            assert action.help, action.dest
