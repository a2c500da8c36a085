"""CIGI queries (channel_worker/query, docs/cigi-queries.md): height of terrain and line of
sight on the bundled scene, their error against the terrain source and the reference ray
march, and their time per batch of 100.

    python bench/bench_cigi_queries.py               # the full run (under a minute)
    python bench/bench_cigi_queries.py --quick       # smoke run; not a measurement
    python bench/bench_cigi_queries.py --replot      # redraw cigi_queries.png from the JSON

- HOT error: height_of_terrain at random points over the whole terrain (polygons removed, so
  only the terrain answers) against the stored surface read directly from the page arrays
  (channel_worker/testing/sight_reference.reference_ground): max and rms.
- LOS error: line_of_sight at random segments (starting 0.5-300 m above the ground within 4 km
  of the airfield, 10 m to 10 km long, -23 to +6 degrees) against the fixed-step ray march
  (0.05 m, bisection), polygons included: hits that disagree, max and rms range error.
- Time: median over --repeats calls of a batch of 100 points (HOT) and of 100 segments up to
  10 km (LOS), after one warm-up call (numba loads its cached kernels on the first).

Runs pinned to one CPU with numba on one thread (the queries are single-threaded anyway).
Writes bench/results/cigi_queries.json and cigi_queries.png.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

# Runnable from a plain checkout too (`python bench/bench_cigi_queries.py` puts bench/ first).
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, pin_to_one_cpu, replot  # bench/ is on the path as a script

NAME = "cigi_queries"
HOT_POINTS = 1000
LOS_SEGMENTS = 200
BATCH = 100
REPEATS = 21
SEED = 2024


def main(argv: list[str] | None = None) -> int:
    parser = bench_parser(__doc__ or "", NAME, f"default {REPEATS}", "3 repeats, 40 segments")
    args = parser.parse_args(argv)
    if replot(args, NAME, print_report, plot):
        return 0
    cpu = pin_to_one_cpu(args.cpu)  # before numba starts its threads
    import numba
    numba.set_num_threads(1)
    from bench_render import machine

    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from channel_worker.query.heights import height_of_terrain
    from channel_worker.query.sight import line_of_sight
    from channel_worker.testing.sight_reference import reference_ground, reference_sight

    repeats = 3 if args.quick else (args.repeats or REPEATS)
    segments = 40 if args.quick else LOS_SEGMENTS
    db = load_scene(demo_scene_path())
    terrain = db.terrain
    assert terrain is not None
    rng = np.random.default_rng(SEED)

    # HOT error against the stored surface, terrain only.
    terrain_only = dataclasses.replace(db, instance_model=db.instance_model[:0],
                                       instance_position=db.instance_position[:0],
                                       instance_rotation=db.instance_rotation[:0])
    x = terrain.origin[0] + rng.uniform(0, terrain.nx * terrain.spacing_m, HOT_POINTS)
    y = terrain.origin[1] + rng.uniform(0, terrain.ny * terrain.spacing_m, HOT_POINTS)
    hot = height_of_terrain(terrain_only, x, y, np.full(HOT_POINTS, np.inf))
    _, top = reference_ground(terrain, x, y)
    hot_err = np.abs(hot.height_m - top)

    # LOS error against the march, polygons included.
    p0, p1 = _segments(rng, segments, db, reference_ground)
    t0 = time.perf_counter()
    ref_hit, ref_range, from_face = reference_sight(db, p0, p1, np.zeros(segments))
    march_s = time.perf_counter() - t0
    los = line_of_sight(db, p0, p1, np.zeros(segments))
    both = los.hit & ref_hit
    los_err = np.abs(los.range_m[both] - ref_range[both])

    # Time per batch of 100 (bundled scene, polygons included).
    hx, hy = x[:BATCH], y[:BATCH]
    lp0, lp1 = _segments(np.random.default_rng(SEED + 1), BATCH, db, reference_ground)
    times: dict[str, list[float]] = {"hot": [], "los": []}
    for k in range(repeats + 1):
        t0 = time.perf_counter()
        height_of_terrain(db, hx, hy, np.full(BATCH, np.inf))
        t1 = time.perf_counter()
        line_of_sight(db, lp0, lp1, np.zeros(BATCH))
        t2 = time.perf_counter()
        if k:  # the first: a warm-up
            times["hot"].append(t1 - t0)
            times["los"].append(t2 - t1)

    record: dict[str, Any] = {
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "settings": {"cpu": cpu, "numba_threads": numba.get_num_threads(), "repeats": repeats, "seed": SEED,
                     "quick": bool(args.quick), "scene": str(demo_scene_path().name),
                     "terrain_voxels": [terrain.nx, terrain.ny], "spacing_m": terrain.spacing_m},
        "hot": {"points": HOT_POINTS, "max_error_m": float(hot_err.max()),
                "rms_error_m": float(np.sqrt((hot_err ** 2).mean())),
                "invalid": int((~hot.valid).sum()), "pattern_tops": int((hot.material > 1).sum())},
        "los": {"segments": segments, "hits": int(ref_hit.sum()), "polygon_hits": int(from_face.sum()),
                "hit_disagreements": int((los.hit != ref_hit).sum()),
                "max_range_error_m": float(los_err.max()) if los_err.size else 0.0,
                "rms_range_error_m": float(np.sqrt((los_err ** 2).mean())) if los_err.size else 0.0,
                "march_step_m": 0.05, "march_seconds": march_s,
                "lengths_m": sorted(np.linalg.norm(p1 - p0, axis=1).round(1).tolist())},
        "time_ms": {key: {"median": 1e3 * statistics.median(v), "min": 1e3 * min(v), "max": 1e3 * max(v),
                          "all": [1e3 * t for t in v]} for key, v in times.items()},
    }
    finish(record, args.out, NAME, print_report, plot)
    return 0


def _segments(rng, n, db, reference_ground):
    """n segments: start 0.5-300 m above the ground within 4 km of the airfield, 10 m - 10 km
    long, climbing -23 to +6 degrees."""
    x, y = rng.uniform(-4000, 4000, n), rng.uniform(-4000, 4000, n)
    ground, _ = reference_ground(db.terrain, x, y)
    p0 = np.c_[x, y, ground + rng.uniform(0.5, 300, n)]
    heading, length, climb = rng.uniform(0, 2 * np.pi, n), rng.uniform(10, 10000, n), rng.uniform(-0.4, 0.1, n)
    p1 = p0 + length[:, None] * np.c_[np.cos(heading) * np.cos(climb), np.sin(heading) * np.cos(climb),
                                      np.sin(climb)]
    return p0, p1


def print_report(record: dict) -> None:
    hot, los, ms = record["hot"], record["los"], record["time_ms"]
    print(f"CIGI queries on {record['settings']['scene']} ({record['machine'].get('cpu', '?')})")
    print()
    print("| query | batch | median ms | min ms | max ms | error vs reference | max | rms |")
    print("|---|---|---|---|---|---|---|---|")
    print(f"| HOT | {BATCH} points | {ms['hot']['median']:.3f} | {ms['hot']['min']:.3f} | {ms['hot']['max']:.3f} "
          f"| terrain source, {hot['points']} points | {hot['max_error_m']:.2e} m | {hot['rms_error_m']:.2e} m |")
    print(f"| LOS | {BATCH} segments <= 10 km | {ms['los']['median']:.3f} | {ms['los']['min']:.3f} "
          f"| {ms['los']['max']:.3f} | 0.05 m march, {los['segments']} segments ({los['hits']} hits, "
          f"{los['polygon_hits']} on polygons, {los['hit_disagreements']} disagree) "
          f"| {los['max_range_error_m']:.2e} m | {los['rms_range_error_m']:.2e} m |")


def plot(record: dict, path: Path) -> bool:
    """Time per batch of each repeat (HOT, LOS). Returns False when matplotlib is missing."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    data = [record["time_ms"]["hot"]["all"], record["time_ms"]["los"]["all"]]
    ax.boxplot(data, tick_labels=[f"HOT, {BATCH} points", f"LOS, {BATCH} segments <= 10 km"])
    ax.set_ylabel("ms per batch")
    ax.set_title(f"CIGI queries; HOT max error {record['hot']['max_error_m']:.1e} m, "
                 f"LOS max error {record['los']['max_range_error_m']:.1e} m", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


if __name__ == "__main__":
    sys.exit(main())
