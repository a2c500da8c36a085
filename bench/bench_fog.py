"""Layered fog (US 5,535,374, channel_worker/pipeline/fog/fog.py): the per-frame table's cost
and its error against the exact integral, for table spacings from 4 x to 1/16 of the sample
spacing (bench/README.md "Fog").

    python bench/bench_fog.py                # the full run (about a minute)
    python bench/bench_fog.py --repeats 15   # steadier medians on a busy machine
    python bench/bench_fog.py --quick        # smoke run (seconds); not a measurement
    python bench/bench_fog.py --replot       # redraw fog.png from fog.json

The structure is a ground fog: 16 sample planes 20 m apart (0 to 300 m), light fog near the
ground, a dense layer one plane thick at 100 m (visibility ~50 m), thinning to clear at 300 m,
clear above. Eyes: in the ground fog, on the dense layer's plane, inside it between planes,
above the fog at 1000 m (a whole number of spacings above plane 0), at 1013.7 m (not) and at
10 km (a table of thousands of entries).

For every eye and table spacing it measures (a) the per-frame table build, fog_params (median
of 5 x --repeats calls); (b) the per-sample lookup, fog_depths over 10^6 rays after a warm-up
call (numba compiles on the first), ns per ray; (c) the transmission error |exp(-tau_table)
- exp(-tau_exact)| against channel_worker/testing/fog_reference.py, largest and mean, over
10^6 random rays (directions uniform over the sphere, ranges log-uniform 10 m to 100 km) and
over a grazing grid (elevations 0 to +-90 degrees, down to 0.001 degrees, ranges 10 m to 100
km and the sky); colours are in [0, 1], so the largest colour error is the largest
transmission error. The exact reference's time per ray is the comparison point, and so is
US 5,535,374's own look-up (the stored average interpolated linearly, resample planes one
sample spacing apart; the record's "patent_linear", "seed_linear" in records before it was
renamed).

Runs pinned to one CPU with numba on one thread. Writes bench/results/fog.json (the record)
and bench/results/fog.png (error and cost against the table spacing; not checked in).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import math
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

# Runnable from a plain checkout too (`python bench/bench_fog.py` puts bench/ first).
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, replot  # bench/ is on the path as a script

from services.rig.options import RenderOptions

SPACING_M = 20.0
#: Ground fog, 1/m at planes 0, 20, ..., 300 m: the dense layer is plane 5 (100 m).
EXTINCTION = (0.010, 0.010, 0.012, 0.015, 0.010, 0.080, 0.010, 0.008, 0.006, 0.005,
              0.004, 0.003, 0.002, 0.001, 0.0005, 0.0)
#: Table spacing / sample spacing.
FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.125, 0.0625)
#: (name, eye height above plane 0, metres).
EYES = (("ground fog", 37.1), ("on the dense plane", 100.0), ("inside the dense layer", 103.3),
        ("above, 1000 m", 1000.0), ("above, 1013.7 m", 1013.7), ("high, 10013.7 m", 10013.7))
#: fog_params is cheap: each median is over this many times --repeats calls.
BUILD_REPEATS_PER_REPEAT = 5
#: Elevations of the grazing grid, degrees (both signs, and 0).
ELEVATIONS_DEG = (90.0, 60.0, 30.0, 10.0, 3.0, 1.0, 0.3, 0.1, 0.03, 0.01, 0.001)
LOOKUP_RAYS = 1_000_000
ERROR_RAYS = 1_000_000
GRID_RANGES = 200
#: The reference runs on chunks of rays (its arrays are rays x planes).
CHUNK = 50_000
QUICK: dict[str, Any] = {"repeats": 3, "lookup_rays": 100_000, "error_rays": 20_000, "grid_ranges": 40,
         "eyes": (EYES[0], EYES[2], EYES[4])}


class Progress:
    """Progress lines on stderr with the seconds since the start."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        print(f"[{time.perf_counter() - self.t0:6.1f} s] {message}", file=sys.stderr, flush=True)

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self.t0


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns the process exit status."""
    parser = bench_parser(__doc__, "fog", "default 9; --quick 3",
                          "3 eyes, 10^5 lookups, 2 x 10^4 error rays: checks the bench runs; "
                          "not a measurement")
    args = parser.parse_args(argv)
    if replot(args, "fog", print_report, plot):
        return 0
    quick = args.quick
    repeats = args.repeats if args.repeats is not None else (QUICK["repeats"] if quick else 9)
    if repeats < 1:
        parser.error("--repeats must be at least 1")

    from common import pin_to_one_cpu

    cpu = pin_to_one_cpu(args.cpu)  # before numba starts its threads
    import numba

    numba.set_num_threads(1)
    from bench_render import machine
    from bench_terrain import git_state

    from channel_worker.pipeline.fog import fog as fog_module

    progress = Progress()
    fog_source = Path(fog_module.__file__).read_bytes()
    record: dict[str, Any] = {
        "benchmark": "layered fog (US 5,535,374): per-frame table build, per-sample lookup and "
                     "transmission error against the exact integral, per table spacing",
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "git": git_state(),
        "fog_py_sha256": hashlib.sha256(fog_source).hexdigest(),
        "table_subdivision_default": getattr(fog_module, "TABLE_SUBDIVISION", None),
        "one_core": {"cpu": cpu, "affinity": sorted(os.sched_getaffinity(0))
                     if hasattr(os, "sched_getaffinity") else None,
                     "numba_threads": numba.get_num_threads()},
        "quick": quick,
        "repeats": repeats,
        "structure": {"spacing_m": SPACING_M, "extinction_per_m": list(EXTINCTION),
                      "axis": [0.0, 0.0, 1.0], "origin": [0.0, 0.0, 0.0],
                      "what": "ground fog 0-300 m, dense layer one plane thick at 100 m "
                              "(sigma 0.08/m), clear above 300 m"},
        "factors": list(FACTORS),
    }
    eyes = QUICK["eyes"] if quick else EYES
    lookup_rays = QUICK["lookup_rays"] if quick else LOOKUP_RAYS
    error_rays = QUICK["error_rays"] if quick else ERROR_RAYS
    grid_ranges = QUICK["grid_ranges"] if quick else GRID_RANGES
    record["rays"] = {
        "lookup": {"count": lookup_rays, "what": "cosines uniform in [-1, 1] (directions "
                   "uniform over the sphere), ranges log-uniform 10 m .. 100 km; random "
                   "seed 1"},
        "random": {"count": error_rays, "what": "as the lookup rays, random seed 2"},
        "grazing": {"elevations_deg": [0.0] + [s * e for e in ELEVATIONS_DEG for s in (1, -1)],
                    "ranges": f"{grid_ranges} log-spaced 10 m .. 100 km, and the sky (inf)"},
    }
    run(record, eyes, repeats, lookup_rays, error_rays, grid_ranges, progress)
    record["frames"] = frame_costs(repeats, quick, progress)
    record["seconds"] = progress.seconds
    finish(record, args.out, "fog", print_report, plot)
    return 0


#: The whole-frame comparison: the channel of bench_terrain.py (1280 x 1024, 60 degrees, 4
#: samples), the bundled scenes with and without the demo scene's valley mist.
FRAME: dict[str, Any] = {"width": 1280, "height": 1024, "fov_h_deg": 60.0, "samples": "rgss4"}
FRAME_EYES = {"level at 60 m": (0.0, -1500.0, 60.0, 0.0, -3.0),
              "climbing at 400 m": (0.0, 2000.0, 400.0, 200.0, -8.0)}


def frame_costs(repeats: int, quick: bool, progress) -> list[dict[str, Any]]:
    """Whole frames on one core, with the demo scene's fog and without it: the bundled
    airfield alone (fog alone makes the background stage paint the sky and earth) and on the
    bundled terrain under haze and clouds (fog adds to every texel and sample)."""
    import dataclasses

    from channel_worker.pipeline.render import render_frame
    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from services.rig.frame import ChannelSpec, Eyepoint
    from services.rig.report import FrameReport

    demo = load_scene(demo_scene_path())
    flat = load_scene(demo_scene_path().with_name("airfield.json"))
    scenes = {"airfield": (dataclasses.replace(flat, fog=demo.fog), flat)}
    if not quick:
        scenes["airfield on terrain, haze, clouds"] = (demo, dataclasses.replace(demo, fog=None))
    channel = ChannelSpec.symmetric("c", FRAME["width"], FRAME["height"], FRAME["fov_h_deg"])
    out = np.empty((FRAME["height"], FRAME["width"], 3), np.float32)
    options = RenderOptions(samples=FRAME["samples"], with_range=False)
    rows = []
    for scene_name, (fogged, clear) in scenes.items():
        for eye_name, (x, y, z, h, p) in FRAME_EYES.items():
            eye = Eyepoint.of(x, y, z, h, p, 0.0)
            row: dict[str, Any] = {"scene": scene_name, "eye": eye_name}
            for label, db in (("fog", fogged), ("no_fog", clear)):
                frames, stages = [], []
                for i in range(repeats + 1):  # the first: a warm-up (numba compiles)
                    report = FrameReport()
                    t0 = time.perf_counter()
                    render_frame(db, channel, eye, options, report=report, out=out)
                    if i:
                        frames.append(time.perf_counter() - t0)
                        stages.append(report.stage_seconds)
                row[label] = {"frame_ms": 1e3 * statistics.median(frames),
                              "stages_ms": {k: 1e3 * statistics.median(s.get(k, 0.0) for s in stages)
                                            for k in sorted({k for s in stages for k in s})}}
            rows.append(row)
            progress(f"frame {scene_name}, {eye_name}: fog {row['fog']['frame_ms']:.1f} ms, "
                     f"none {row['no_fog']['frame_ms']:.1f} ms")
    return rows


def make_fog(factor: float):
    from channel_worker.pipeline.scene.atmosphere import Fog

    return Fog(axis=np.array([0.0, 0.0, 1.0]), origin=np.zeros(3), spacing_m=SPACING_M,
               extinction=np.array(EXTINCTION), colour=np.array([0.8, 0.82, 0.85], np.float32),
               table_spacing_m=SPACING_M * factor)


def random_rays(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(cosines, ranges): directions uniform over the sphere (so cosines uniform in [-1, 1]),
    ranges log-uniform 10 m .. 100 km."""
    rng = np.random.default_rng(seed)
    cos = rng.uniform(-1.0, 1.0, count)
    ranges = np.exp(rng.uniform(math.log(10.0), math.log(1e5), count))
    return cos, ranges


def grazing_rays(n_ranges: int) -> tuple[np.ndarray, np.ndarray]:
    """(cosines, ranges): every elevation of ELEVATIONS_DEG (both signs, and 0) against
    n_ranges log-spaced ranges 10 m .. 100 km and the sky."""
    elev = np.array([0.0] + [s * e for e in ELEVATIONS_DEG for s in (1.0, -1.0)])
    ranges = np.concatenate([np.geomspace(10.0, 1e5, n_ranges), [np.inf]])
    c, r = np.meshgrid(np.sin(np.radians(elev)), ranges, indexing="ij")
    return c.ravel().copy(), r.ravel().copy()


def reference(st, h: float, cos: np.ndarray, ranges: np.ndarray) -> tuple[np.ndarray, float]:
    """Exact depths of the rays (in chunks) and the seconds it took."""
    from channel_worker.testing.fog_reference import axis_optical_depths

    out = np.empty(cos.size)
    t0 = time.perf_counter()
    for a in range(0, cos.size, CHUNK):
        out[a:a + CHUNK] = axis_optical_depths(st, h, cos[a:a + CHUNK], ranges[a:a + CHUNK])
    return out, time.perf_counter() - t0


def transmission_error(ours: np.ndarray, exact: np.ndarray) -> dict[str, float]:
    e = np.abs(np.exp(-ours) - np.exp(-exact))
    return {"max": float(e.max()), "mean": float(e.mean()),
            "p99": float(np.percentile(e, 99.0)), "p999": float(np.percentile(e, 99.9))}


def run(record: dict, eyes, repeats: int, lookup_rays: int, error_rays: int, grid_ranges: int,
        progress: Progress) -> None:
    from channel_worker.pipeline.contract import F_DT, F_N
    from channel_worker.pipeline.fog.fog import fog_depths, fog_params
    from channel_worker.testing.fog_reference import strata

    st = strata(make_fog(1.0))
    look_c, look_r = random_rays(lookup_rays, 1)
    rand_c, rand_r = random_rays(error_rays, 2)
    graz_c, graz_r = grazing_rays(grid_ranges)
    rows: list[dict[str, Any]] = []
    ref_seconds, ref_rays = 0.0, 0
    for name, h in eyes:
        eye = np.array([0.0, 0.0, h])
        exact_rand, sec = reference(st, h, rand_c, rand_r)
        exact_graz, sec2 = reference(st, h, graz_c, graz_r)
        ref_seconds += sec + sec2
        ref_rays += rand_c.size + graz_c.size
        per_ray = 1e6 * (sec + sec2) / (rand_c.size + graz_c.size)
        progress(f"eye {name}: exact reference {per_ray:.2f} us/ray")
        for factor in FACTORS:
            fg = make_fog(factor)
            build = []
            for _ in range(BUILD_REPEATS_PER_REPEAT * repeats + 1):  # the first: a warm-up
                t0 = time.perf_counter()
                tab = fog_params(fg, None, eye=eye)
                build.append(time.perf_counter() - t0)
            build = build[1:]
            fog_depths(tab.params, look_r[:1000], look_c[:1000])  # numba compiles once
            lookup = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                fog_depths(tab.params, look_r, look_c)
                lookup.append(time.perf_counter() - t0)
            ours_rand = fog_depths(tab.params, rand_r, rand_c)
            ours_graz = fog_depths(tab.params, graz_r, graz_c)
            finite = np.isfinite(exact_graz)
            agree = bool(np.array_equal(np.isinf(ours_graz), ~finite))
            row = {"eye": name, "eye_height_m": h, "factor": factor,
                   "table_spacing_m": float(tab.params[F_DT]), "entries": int(tab.params[F_N]),
                   "coarsened": bool(tab.coarsened),
                   "build_us": 1e6 * statistics.median(build),
                   "build_us_min": 1e6 * min(build),
                   "lookup_ns": 1e9 * statistics.median(lookup) / look_c.size,
                   "lookup_ns_min": 1e9 * min(lookup) / look_c.size,
                   "random": transmission_error(ours_rand, exact_rand),
                   "grazing": transmission_error(ours_graz[finite], exact_graz[finite]),
                   "sky_inf_agrees": agree,
                   "nan": int(np.isnan(ours_rand).sum() + np.isnan(ours_graz).sum())}
            row["max_colour_error"] = max(row["random"]["max"], row["grazing"]["max"])
            rows.append(row)
            progress(f"  x {factor:<6g} dt {row['table_spacing_m']:7.3f} m, {row['entries']:4d} "
                     f"entries: build {row['build_us']:7.1f} us, lookup {row['lookup_ns']:5.2f} "
                     f"ns, max T error {row['max_colour_error']:.2e}")
    record["rows"] = rows
    record["patent_linear"] = patent_comparison(eyes, st, rand_c, rand_r, graz_c, graz_r, look_c,
                                                look_r, repeats)
    record["exact_reference"] = {
        "us_per_ray": 1e6 * ref_seconds / ref_rays, "rays": ref_rays,
        "what": "channel_worker/testing/fog_reference.py axis_optical_depths, vectorised numpy "
                f"in chunks of {CHUNK} rays (the ray cut at every plane, trapezoids)"}
    summary = []
    for factor in FACTORS:
        sel = [r for r in rows if r["factor"] == factor]
        summary.append({
            "factor": factor, "table_spacing_m": SPACING_M * factor,
            "entries_max": max(r["entries"] for r in sel),
            "build_us_median": statistics.median(r["build_us"] for r in sel),
            "build_us_max": max(r["build_us"] for r in sel),
            "build_us_min": min(r["build_us_min"] for r in sel),
            "lookup_ns_median": statistics.median(r["lookup_ns"] for r in sel),
            "random_max": max(r["random"]["max"] for r in sel),
            "random_mean": statistics.mean(r["random"]["mean"] for r in sel),
            "grazing_max": max(r["grazing"]["max"] for r in sel),
            "grazing_mean": statistics.mean(r["grazing"]["mean"] for r in sel),
            "max_colour_error": max(r["max_colour_error"] for r in sel)})
    record["summary"] = summary


def patent_comparison(eyes, st, rand_c, rand_r, graz_c, graz_r, look_c, look_r,
                      repeats: int) -> dict[str, Any]:
    """US 5,535,374's own look-up for comparison: the stored average interpolated linearly, with
    the resample planes as far apart as the sample planes (fog.py's table at factor 1; only
    the interpolation differs: the closed form beyond the table and the sky are fog.py's)."""
    from channel_worker.pipeline.fog.fog import fog_params

    worst, means, lookup = 0.0, [], []
    for _, h in eyes:
        tab = fog_params(make_fog(1.0), None, eye=np.array([0.0, 0.0, h]))
        _linear_depths(tab.params, look_r[:1000], look_c[:1000])
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            _linear_depths(tab.params, look_r, look_c)
            times.append(time.perf_counter() - t0)
        lookup.append(1e9 * statistics.median(times) / look_c.size)
        exact_rand, _ = reference(st, h, rand_c, rand_r)
        exact_graz, _ = reference(st, h, graz_c, graz_r)
        finite = np.isfinite(exact_graz)
        e_rand = transmission_error(_linear_depths(tab.params, rand_r, rand_c), exact_rand)
        e_graz = transmission_error(_linear_depths(tab.params, graz_r, graz_c)[finite],
                                    exact_graz[finite])
        worst = max(worst, e_rand["max"], e_graz["max"])
        means.append(e_rand["mean"])
    return {"factor": 1.0, "max_colour_error": worst, "random_mean": statistics.mean(means),
            "lookup_ns_median": statistics.median(lookup),
            "what": "linear interpolation of the stored average between resample planes one "
                    "sample spacing apart (US 5,535,374's look-up)"}


_LINEAR_KERNEL = None


def _linear_depths(f, ranges, cos):
    """Optical depths by US 5,535,374's linear look-up (compiled on first use: fog.py's
    layout)."""
    global _LINEAR_KERNEL
    if _LINEAR_KERNEL is None:
        _LINEAR_KERNEL = _make_linear_kernel()
    return _LINEAR_KERNEL(f, ranges, cos)


def _make_linear_kernel():
    from numba import njit

    from channel_worker.pipeline.contract import F_INV_DT, F_J0, F_N, F_TABLE
    from channel_worker.pipeline.fog.fog import fog_depth

    @njit(cache=False)
    def kernel(f, ranges, cos):
        out = np.empty(ranges.shape[0])
        n = f[F_N]
        for k in range(ranges.shape[0]):
            r = ranges[k]
            d = r * cos[k]
            u = d * f[F_INV_DT] + f[F_J0]
            if np.isinf(r) or u <= 0.0 or u >= n - 1.0:
                out[k] = fog_depth(f, r, cos[k])  # the same closed form outside the table
                continue
            i = int(u)
            w = u - i
            a0 = f[F_TABLE + 2 * i]
            out[k] = (a0 + (f[F_TABLE + 2 * i + 2] - a0) * w) * r
        return out

    return kernel


# --- report ----------------------------------------------------------------------------------

def table(head: list[str], body: list[list[str]]) -> None:
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
    for b in body:
        print("  ".join(c.rjust(w) for c, w in zip(b, widths, strict=True)))


def print_report(record: dict) -> None:
    s = record["structure"]
    sub = record.get("table_subdivision_default")
    print(f"\nlayered fog: {len(s['extinction_per_m'])} planes {s['spacing_m']:g} m apart, one "
          "core; table spacing = sample spacing x factor"
          + (f" (fog.py's default: 1/{sub})" if sub else ""))
    print("\nper eye: table entries, build (median us), lookup (median ns per ray), "
          "transmission error max / mean over the random rays and over the grazing grid")
    table(["eye", "factor", "dt m", "entries", "build us", "lookup ns", "rand max", "rand mean",
           "graz max", "graz mean"],
          [[r["eye"], f"{r['factor']:g}", f"{r['table_spacing_m']:.3g}", str(r["entries"]),
            f"{r['build_us']:.1f}", f"{r['lookup_ns']:.2f}", f"{r['random']['max']:.2e}",
            f"{r['random']['mean']:.1e}", f"{r['grazing']['max']:.2e}",
            f"{r['grazing']['mean']:.1e}"] for r in record["rows"]])
    print("\nsummary over the eyes (max colour error = max transmission error: colours in "
          "[0, 1])")
    table(["factor", "dt m", "entries", "build us", "lookup ns", "max colour err",
           "mean err (rand)", "mean err (graz)"],
          [[f"{r['factor']:g}", f"{r['table_spacing_m']:g}", str(r["entries_max"]),
            f"{r['build_us_median']:.1f}", f"{r['lookup_ns_median']:.2f}",
            f"{r['max_colour_error']:.2e}", f"{r['random_mean']:.1e}",
            f"{r['grazing_mean']:.1e}"] for r in record["summary"]])
    if record.get("frames"):
        print(f"\nwhole frames, one core, {FRAME['width']} x {FRAME['height']}, "
              f"{FRAME['samples']}: median ms with the demo scene's fog and without")
        table(["scene", "eye", "fog", "no fog", "background fog", "visibility fog",
               "visibility no fog"],
              [[r["scene"], r["eye"], f"{r['fog']['frame_ms']:.1f}",
                f"{r['no_fog']['frame_ms']:.1f}",
                # The background stage was named "terrain" in records before the rename.
                f"{r['fog']['stages_ms'].get('background', r['fog']['stages_ms'].get('terrain', 0.0)):.1f}",
                f"{r['fog']['stages_ms'].get('visibility', 0.0):.1f}",
                f"{r['no_fog']['stages_ms'].get('visibility', 0.0):.1f}"]
               for r in record["frames"]])
    linear = record.get("patent_linear", record.get("seed_linear"))
    if linear:
        print(f"\nUS 5,535,374's look-up (the average interpolated linearly, resample planes one "
              f"sample spacing apart): max colour error {linear['max_colour_error']:.2e}, mean "
              f"{linear['random_mean']:.1e}, lookup {linear['lookup_ns_median']:.2f} ns per ray")
    ex = record["exact_reference"]
    print(f"\nexact reference: {ex['us_per_ray']:.2f} us per ray ({ex['rays']:,} rays; "
          f"{ex['what']})")
    bad = [r for r in record["rows"] if r["nan"] or not r["sky_inf_agrees"]]
    if bad:
        print("WARNING: NaN or sky mismatch in " + ", ".join(
            f"{r['eye']} x {r['factor']:g}" for r in bad))
    m = record["machine"]
    print(f"load average {m['load_average_1min']:.2f} at the start, "
          f"{m['load_average_1min_at_end']:.2f} at the end; {record['seconds']:.0f} s in all")


def plot(record: dict, path: Path) -> bool:
    """Two panels: transmission error against table spacing (per eye, largest and mean), and
    the per-frame build and per-sample lookup against it. Returns False (and draws nothing)
    when matplotlib is not installed."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13.0, 5.2))
    cmap = plt.get_cmap("viridis")
    eyes = list(dict.fromkeys(r["eye"] for r in record["rows"]))
    floor = 1e-17  # exact results (error 0) drawn at the bottom of the log axis
    for k, eye in enumerate(eyes):
        pts = [r for r in record["rows"] if r["eye"] == eye]
        x = [r["factor"] for r in pts]
        colour = cmap(k / max(len(eyes) - 1, 1))
        ax.plot(x, [max(r["max_colour_error"], floor) for r in pts], "o-", color=colour,
                label=f"{eye}: max")
        ax.plot(x, [max(r["random"]["mean"], floor) for r in pts], "s:", color=colour, ms=3,
                label=f"{eye}: mean (random rays)")
    ax.axhline(1.0 / 255.0, color="grey", lw=0.8, ls="--")
    ax.annotate("1/255", (min(record["factors"]), 1.0 / 255.0), textcoords="offset points",
                xytext=(2, 3), fontsize=7, color="grey")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.invert_xaxis()
    ax.set_xlabel("table spacing / sample spacing")
    ax.set_ylabel("|T_table - T_exact| (= colour error, linear RGB)")
    ax.set_title("transmission error against the exact integral\n(max over random and grazing "
                 "rays, solid; mean over random rays, dotted)", fontsize=9)
    ax.legend(fontsize=6, ncol=2, loc="lower left")

    summ = record["summary"]
    x = [r["factor"] for r in summ]
    ax2.plot(x, [r["build_us_median"] for r in summ], "o-", color="tab:blue",
             label="table build (fog_params), median us per frame")
    ax2.plot(x, [r["build_us_max"] for r in summ], "o:", color="tab:blue", ms=3,
             label="table build, the eye with the most entries (slowest)")
    ax2.set_xscale("log", base=2)
    ax2.set_yscale("log")
    ax2.invert_xaxis()
    ax2.set_xlabel("table spacing / sample spacing")
    ax2.set_ylabel("us per frame")
    ax3 = ax2.twinx()
    ax3.plot(x, [r["lookup_ns_median"] for r in summ], "s-", color="tab:red",
             label="lookup (fog_depths), ns per ray")
    ax3.axhline(1e3 * record["exact_reference"]["us_per_ray"], color="tab:red", ls="--", lw=0.8)
    ax3.set_yscale("log")
    ax3.set_ylabel("ns per ray (dashed: the exact reference)")
    h1, l1 = ax2.get_legend_handles_labels()
    h2, l2 = ax3.get_legend_handles_labels()
    ax2.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
    ax2.set_title("cost: per-frame table build and per-sample lookup, one core", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


if __name__ == "__main__":
    raise SystemExit(main())
