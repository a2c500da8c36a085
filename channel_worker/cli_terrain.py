"""`ig terrain`: build a voxel terrain database offline (`build`) and describe one (`info`)."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from channel_worker.pipeline.scene.terrain.database import (
    DEFAULT_PAGE_SIZE,
    TerrainDatabase,
    TerrainError,
)
from channel_worker.pipeline.scene.terrain.sources import DEFAULT_COLOUR
from services.rig.cli_common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, error, positive


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig terrain build` and `ig terrain info`."""
    sub = parser.add_subparsers(dest="terrain_action", required=True, metavar="ACTION",
                                help="build: make a database from an elevation source; info: describe one")
    build = sub.add_parser("build", help="build a terrain database (docs/terrain-database.md)",
                           description="Build a voxel terrain database: place the elevation source on an "
                                       "east-north-up grid, colour it, flatten pads, plant trees, average the "
                                       "levels, cut the pages. Exit 2 on bad input.")
    build.add_argument("source", help="elevation: mpl:jacksboro, mpl:topobathy, FILE.tif/.tiff (GeoTIFF) or "
                                      "FILE.asc (ESRI ASCII grid); FILE?nodata=refuse refuses nodata cells "
                                      "instead of filling them")
    build.add_argument("--out", required=True, metavar="DIR.igt", help="the database directory to write")
    build.add_argument("--colour", default=DEFAULT_COLOUR, metavar="URL",
                       help=f"colour source: relief:CMAP[?azimuth=DEG&altitude=DEG&exaggeration=X&span=LO,HI] "
                            f"or an image file stretched over the extent, top row north (default {DEFAULT_COLOUR})")
    build.add_argument("--spacing", type=positive, default=None, metavar="M",
                       help="level-0 voxel width, metres (default: the source's cell size)")
    build.add_argument("--origin", type=_origin, default=None, metavar="LAT,LON,H",
                       help="geodetic position of world (0, 0, 0), degrees and metres (default: the "
                            "source's centre at height 0); write --origin=-33.9,... for a southern latitude")
    build.add_argument("--flatten", type=_pad, action="append", default=[], metavar="X0,Y0,X1,Y1,Z,BLEND",
                       help="flatten a world rectangle (metres) to height Z, blending back over BLEND metres; "
                            "repeatable; write --flatten=-450,... when X0 is negative")
    build.add_argument("--trees", type=_fraction, default=None, metavar="DENSITY",
                       help="cover this fraction (0..1) of the gentle voxels outside the pads with forest")
    build.add_argument("--page-size", type=_page_size, default=DEFAULT_PAGE_SIZE, metavar="N",
                       help=f"voxels per page side (default {DEFAULT_PAGE_SIZE})")
    build.add_argument("--prune", type=_prune, default=None, metavar="DZ,DRGB",
                       help="leave out pages that the next coarser level reproduces within DZ metres and "
                            "DRGB (linear colour)")
    info = sub.add_parser("info", help="describe a terrain database",
                          description="Print a terrain database's levels, pages present and missing per level, "
                                      "extent, height range, source and licence. Exit 2 if it is not valid.")
    info.add_argument("database", metavar="DIR.igt", help="the database directory")


def run(args: argparse.Namespace) -> int:
    """Run `ig terrain build` or `ig terrain info`; 0 ok, 1 the database could not be written,
    2 bad input."""
    return _build(args) if args.terrain_action == "build" else _info(args)


def _build(args: argparse.Namespace) -> int:
    from channel_worker.pipeline.scene.terrain.recipe import build_from_recipe
    from channel_worker.pipeline.scene.terrain.store import save_terrain

    out = Path(args.out)
    if out.exists() and not (out.is_dir() and ((out / "terrain.json").is_file() or not any(out.iterdir()))):
        error("terrain", f"--out: {args.out!r} exists and is not a terrain database")
        return EXIT_BAD_INPUT
    recipe = {"source": args.source, "colour": args.colour, "spacing_m": args.spacing,
              "origin": list(args.origin) if args.origin else None, "flatten": [list(p) for p in args.flatten],
              "trees": {"density": args.trees, "seed": 0} if args.trees is not None else None,
              "page_size": args.page_size, "prune": list(args.prune) if args.prune else None}
    t0 = time.perf_counter()
    try:
        db = build_from_recipe(recipe)
        save_terrain(db, out)
    except TerrainError as exc:
        error("terrain", exc)
        return EXIT_BAD_INPUT
    except OSError as exc:  # the disk, not the input: the command ran but could not write
        error("terrain", f"--out: {args.out!r}: {exc}")
        return EXIT_FAILED
    build = db.info["build"]
    print(f"wrote {out}: {db.nx} x {db.ny} voxels of {db.spacing_m:g} m, {db.levels} levels, "
          f"{build['pages']} pages ({build['pruned_pages']} pruned), z {db.z_min:.1f} .. {db.z_max:.1f} m, "
          f"{time.perf_counter() - t0:.1f} s")
    return EXIT_OK


def _info(args: argparse.Namespace) -> int:
    from channel_worker.pipeline.scene.terrain.store import load_terrain

    try:
        db = load_terrain(args.database)
    except TerrainError as exc:
        error("terrain", exc)
        return EXIT_BAD_INPUT
    print(describe(db))
    return EXIT_OK


def describe(db: TerrainDatabase) -> str:
    """A few lines on a database: extent, levels and their pages, heights, source and licence."""
    east, north = db.extent_m
    o = db.origin
    lines = [f"{db.source}",
             (f"  extent      {east / 1000:.2f} x {north / 1000:.2f} km: world x {o[0]:.1f} .. "
              f"{o[0] + east:.1f}, y {o[1]:.1f} .. {o[1] + north:.1f} m"),
             f"  voxels      {db.nx} x {db.ny} of {db.spacing_m:g} m, pages of {db.page_size} x {db.page_size}",
             f"  heights     z {o[2] + db.z_min:.1f} .. {o[2] + db.z_max:.1f} m (world)"]
    for level in range(db.levels):
        start = int(db.table_offset[level])
        count = int(db.pages_x[level] * db.pages_y[level])
        present = int((db.page_table[start:start + count] >= 0).sum())
        sx, sy = db.level_size(level)
        lines.append(f"  level {level:<5} {sx} x {sy} voxels of {db.spacing_m * (1 << level):g} m, "
                     f"{db.pages_x[level]} x {db.pages_y[level]} pages: {present} present, {count - present} missing")
    if db.patterns:
        lines.append("  patterns    " + ", ".join(f"{k + 1} {p.name} ({float(p.top_m[-1]):g} m)"
                                              for k, p in enumerate(db.patterns)))
    origin = db.info.get("recipe", {}).get("origin")
    if origin:
        lines.append(f"  origin      lat {origin[0]}, lon {origin[1]}, h {origin[2]} m is world (0, 0, 0)")
    for key in ("source", "licence", "attribution"):
        if db.info.get(key):
            lines.append(f"  {key:<11} {db.info[key]}")
    return "\n".join(lines)


def _numbers(text: str, count: int, form: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {form}") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r} is not {form} ({count} finite numbers)")
    return values


def _origin(text: str) -> tuple[float, float, float]:
    """argparse type: LAT,LON,H in degrees and metres."""
    lat, lon, h = _numbers(text, 3, "LAT,LON,H")
    if not (abs(lat) <= 90 and abs(lon) <= 180):
        raise argparse.ArgumentTypeError(f"{text!r}: latitude must be within +-90, longitude +-180")
    return lat, lon, h


def _pad(text: str) -> tuple[float, ...]:
    """argparse type: X0,Y0,X1,Y1,Z,BLEND world metres."""
    x0, y0, x1, y1, z, blend = _numbers(text, 6, "X0,Y0,X1,Y1,Z,BLEND")
    if not (x0 < x1 and y0 < y1 and blend >= 0):
        raise argparse.ArgumentTypeError(f"{text!r} needs X0 < X1, Y0 < Y1 and BLEND >= 0")
    return x0, y0, x1, y1, z, blend


def _fraction(text: str) -> float:
    """argparse type: a number in [0, 1]."""
    (value,) = _numbers(text, 1, "a number in [0, 1]")
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not in [0, 1]")
    return value


def _page_size(text: str) -> int:
    """argparse type: whole voxels per page side in [1, 4096]."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 1 <= value <= 4096:
        raise argparse.ArgumentTypeError(f"{text!r} is not in [1, 4096]")
    return value


def _prune(text: str) -> tuple[float, float]:
    """argparse type: DZ,DRGB tolerances >= 0 (metres, linear colour)."""
    dz, drgb = _numbers(text, 2, "DZ,DRGB")
    if dz < 0 or drgb < 0:
        raise argparse.ArgumentTypeError(f"{text!r} has a negative tolerance")
    return dz, drgb
