"""The background stage's voxel terrain (JP H07-76990), cast straight to the screen, on one
core: frame time and voxels visited against pitch and altitude, what haze and clouds cost,
speed against error for the level bias, a lean Voxel Space peer, and the issue's targets
(bench/README.md).

    python bench/bench_terrain.py                 # what `make bench` runs (9-10 minutes)
    python bench/bench_terrain.py --repeats 9     # steadier medians on a busy machine
    python bench/bench_terrain.py --quick         # smoke run (1-2 minutes); not a measurement
    python bench/bench_terrain.py --replot        # redraw terrain.png from terrain.json
    python bench/bench_terrain.py --peer-only     # only the Voxel Space peer (2-3 minutes)
    python bench/bench_terrain.py --targets-only  # only the targets (section 7; under a minute)
    python bench/bench_terrain.py --detail-only   # only the land's detail (section 8; a minute)

1. Sweep: a 4096 x 4096-voxel, 3 m procedural database (bench/scenes/terrain.py, cached after
   its first build) seen from 50 to 4000 m above the ground under the eye at pitches -90 to 0
   degrees (heading 45, roll 0), 1280 x 1024, 60 degrees across, 4 samples: per cell the time
   of render_background called alone, of the background stage inside render_frame and of the
   whole frame (a scene of terrain only), and the voxels visited.
2. The bundled Jacksboro terrain in the demo scene (terrain, haze, clouds, the airfield's
   polygons), centre channel, along the bundled flight.
3. The stage split into its parts (render_background's `parts`): the terrain cast (the lines
   through the vertical vanishing point, written straight into the pixels over the sky and
   the earth plane), the per-sample depth and the clouds (cloud scan and overlay), with and
   without haze and clouds; the flat airfield (no terrain, no haze) with and without haze and
   clouds, to show that a scene without them skips the stage.
4. The level window each level bias really selects (a flat database coloured by level).
5. Speed against error for level_bias in (-1, 0, 1, 2): stage time at 1280 x 1024 against the
   error of that same render, on every 4th pixel each way, against the exact ray-cast
   reference (channel_worker/testing/terrain_reference.py), on four views.
6. A lean Voxel Space peer (bench/voxel_space.py: Comanche's algorithm, one sample per pixel)
   beside our stage, from the same eyes, same frustum, same database: a 3-degree approach on the
   fractal and the Jacksboro terrain and the sweep's views of pitch -20 to 0 degrees; our
   stage's and whole frame's time (1280 x 1024, rgss4) against the peer's (1 sample), and the
   range error of both against the exact reference. `--peer-only` runs this section alone and
   updates its key in terrain.json.
7. The issue's targets, on the Jacksboro terrain from three eyes (level at 300 m, 2 km up at
   pitch -10, 60 m up at heading 20): our background stage at rolls 0, 30 and 90 degrees and 1
   and 4 samples against the Voxel Space peer from the same eye at roll 0 (it has no roll), the
   range error of our stage at each roll (median, 95th percentile, maximum) against the exact
   reference, and the stage's speed-up from one numba thread to two (that part on two CPUs).
   `--targets-only` runs this section alone and updates its key (targets) in terrain.json.
8. The land's detail (docs/terrain.md "Detail": land classes, fields and hedges, the pads'
   grass, each class's texture code): the cast with and without the scene's terrain.detail on
   the bundled terrain, from the docs' views (docs/images/render_views.py) and points of the
   bundled flight; the detail's share of the cast against the 15 % it may cost.
   `--detail-only` runs this section alone and updates its key (detail) in terrain.json.

The record's keys keep their names from when the stage was called "terrain" and its function
render_terrain (terrain_ms, render_terrain_ms), so that records compare across versions; they
now time the "background" stage and render_background.

Everything runs pinned to one CPU with numba on one thread, after a warm-up (numba compiles on
the first call), except section 7's thread scaling, which widens the pin to two CPUs for its
own frames. Writes bench/results/terrain.json (the record) and bench/results/terrain.png
(four panels; not checked in).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import functools
import math
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

# Runnable from a plain checkout too (`python bench/bench_terrain.py` puts bench/ first).
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, replot  # bench/ is on the path as a script

from services.rig.options import RenderOptions

#: The issue's channel: 1280 x 1024, 60 degrees across, square pixels, 4 samples (rgss4).
WIDTH, HEIGHT, FOV_H_DEG, SAMPLES = 1280, 1024, 60.0, "rgss4"
PITCHES_DEG = (-90, -60, -45, -30, -20, -10, -5, 0)
ALTITUDES_M = (50, 200, 1000, 4000)
HEADING_DEG = 45.0
#: The sweep's eye: 30 % of the database's width in from its south-west corner, looking
#: north-east along the diagonal (up to 12 km of terrain ahead; the nadir footprint from 4 km
#: up stays on the database).
EYE_FRACTION = 0.3
#: Bundled flight points: take-off roll, rotation, climbing turn, descent (as bench_render);
#: the stage split with and without haze and clouds at the first and the last.
FLIGHT_TIMES_S = (2.0, 8.0, 14.0, 20.0)
SPLIT_TIMES_S = (2.0, 20.0)
#: (altitude m, pitch deg, with the haze and cloud variants) views of the fractal database
#: for the stage split.
SPLIT_VIEWS = ((50, -90, False), (200, -10, True), (4000, -90, False))
BIASES = (-1, 0, 1, 2)
#: The error is measured on every ERROR_STRIDE-th pixel each way of the full-size render (320 x
#: 256 pixels: the reference is slow, ~50 us per ray on one core here), on these views.
ERROR_STRIDE = 4
ERROR_VIEWS = ((50, -5), (200, -20), (1000, -30), (4000, -45))
#: Sky and earth share one grey in the error scene, so a sample that misses the terrain has
#: the same colour in the renderer (sky or earth plane) as in the reference (one background).
GREY = "#808080"
#: Haze and clouds of the demo scene (channel_worker/data/airfield_terrain.json); the clouds'
#: extent is set to the fractal database's.
HAZE = {"visibility_m": 30000.0, "scale_height_m": 1500.0, "base_height_m": 0.0,
        "colour": "#c4ccd6"}
CLOUDS = {"cell_m": 400.0, "base_m": 1100.0, "thickness_m": 700.0, "cover": 0.3,
          "extinction_per_m": 0.02, "colour": "#f4f6fa", "seed": 7}
QUICK: dict[str, Any] = {"repeats": 1, "pitches": (-90, -20, 0), "altitudes": (200, 4000),
         "flight": (2.0, 20.0), "biases": (-1, 0, 2), "error_stride": 8,
         "error_views": ((200, -20),), "split_views": ((200, -10, True),), "target_eyes": 1}


class Progress:
    """Progress lines on stderr with the seconds since the start."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        print(f"[{time.perf_counter() - self.t0:6.1f} s] {message}", file=sys.stderr, flush=True)

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self.t0


def median_ms(values: list[float]) -> float:
    return 1e3 * statistics.median(values)


def timed(fn: Callable[[], Any], repeats: int, *, warm: bool = True) -> tuple[list[float], Any]:
    """Call fn once to warm up (unless warm is False), then `repeats` times; every timed call's
    seconds and the last result."""
    out = fn() if warm else None
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
    return walls, out


def git_state() -> dict[str, Any]:
    """The commit measured and the tracked files that differ from it."""
    def run(*cmd: str) -> str | None:
        try:
            return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, check=True,
                                  timeout=10).stdout
        except (OSError, subprocess.SubprocessError):
            return None
    commit = run("git", "rev-parse", "HEAD")
    status = run("git", "status", "--porcelain", "--untracked-files=no")
    return {"commit": commit.strip() if commit else None,
            "modified": None if status is None else [line[3:] for line in status.splitlines()]}


def background_alone(database, view, offsets: np.ndarray, *, level_bias: int = 0,
                     parts: dict[str, float] | None = None):
    """The background stage called by itself, with per-sample depth everywhere (bins None):
    (Background, its counters); parts, if given, receives the seconds of its parts
    ("background.cast", "background.depth", "background.clouds")."""
    from channel_worker.pipeline.background.background import render_background
    from channel_worker.pipeline.geometry.view import frame_constants

    counters: dict[str, int] = {}
    frame = frame_constants(view, database, offsets)
    background = render_background(database, view, frame, RenderOptions(terrain_bias=level_bias),
                                   None, counters, parts=parts)
    return background, counters


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns the process exit status."""
    parser = bench_parser(__doc__, "terrain", "default 5; the bias grid 3; --quick 1",
                          "fewer cells, settings and views, a 160 x 128 error raster, one "
                          "repeat: checks the bench runs; not a measurement")
    parser.add_argument("--peer-only", action="store_true",
                        help="run only the Voxel Space peer comparison and update its key "
                             "(voxel_space_peer) in terrain.json, leaving the rest as it is")
    parser.add_argument("--targets-only", action="store_true",
                        help="run only the issue's targets (section 7) and update its key "
                             "(targets) in terrain.json, leaving the rest as it is")
    parser.add_argument("--detail-only", action="store_true",
                        help="run only the land's detail (section 8) and update its key (detail) "
                             "in terrain.json, leaving the rest as it is")
    args = parser.parse_args(argv)
    if replot(args, "terrain", print_report, plot):
        return 0
    quick = args.quick
    repeats = args.repeats if args.repeats is not None else (QUICK["repeats"] if quick else 5)
    if repeats < 1:
        parser.error("--repeats must be at least 1")
    bias_repeats = args.repeats if args.repeats is not None else (1 if quick else 3)

    from common import pin_to_one_cpu

    # The CPUs this process may use, before the pin: section 7's thread scaling runs on two of
    # them. numba sizes its thread pool by the affinity when it is imported, so a pool of two
    # is asked for first (numba runs on one thread all the same, but for that measurement).
    allowed = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if len(allowed) >= 2:
        os.environ.setdefault("NUMBA_NUM_THREADS", "2")
    cpu = pin_to_one_cpu(args.cpu)  # before numba starts its threads
    import numba

    numba.set_num_threads(1)
    from bench_render import machine

    progress = Progress()
    pair = cpu_pair(cpu, allowed)
    if args.peer_only:
        return section_only(args.out, "voxel_space_peer", functools.partial(
            voxel_space_peer, quick=quick, repeats=repeats, progress=progress), print_peer, cpu,
            progress)
    if args.targets_only:
        return section_only(args.out, "targets", functools.partial(
            targets, quick=quick, repeats=repeats, pair=pair, progress=progress), print_targets,
            cpu, progress)
    if args.detail_only:
        return section_only(args.out, "detail", functools.partial(
            land_detail, quick=quick, repeats=repeats, progress=progress), print_detail, cpu, progress)
    record: dict[str, Any] = {
        "benchmark": "background stage's voxel terrain (JP H07-76990), one core: time and voxels "
                     "against pitch and altitude, options, speed against error for the level "
                     "bias, a Voxel Space peer, the issue's targets",
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "git": git_state(),
        "one_core": {"cpu": cpu, "affinity": sorted(os.sched_getaffinity(0))
                     if hasattr(os, "sched_getaffinity") else None,
                     "numba_threads": numba.get_num_threads()},
        "quick": quick,
        "repeats": repeats,
        "statistic": "medians over the repeats, after one warm-up call. render_terrain_ms: "
                     "wall time of render_background called alone (per-sample depth "
                     "everywhere, bins=None); terrain_ms: FrameReport.stage_seconds"
                     "['background'] inside render_frame (per-sample depth only in sub-areas "
                     "holding polygons); frame_ms: wall time of render_frame",
    }
    sweep(record, quick, repeats, progress)
    bundled(record, quick, repeats, progress)
    no_terrain(record, repeats, progress)
    level_window(record, progress)
    bias_grid(record, quick, bias_repeats, progress)
    voxel_space_peer(record, quick, repeats, progress)
    targets(record, quick, repeats, pair, progress)
    land_detail(record, quick, repeats, progress)
    record["seconds"] = progress.seconds
    finish(record, args.out, "terrain", print_report, plot)
    return 0


# --- 1. the sweep -----------------------------------------------------------------------------

def sweep_channel(width: int = WIDTH, height: int = HEIGHT):
    """The issue's channel: width x height, FOV_H_DEG across, square pixels."""
    from services.rig.frame import ChannelSpec

    half_v = math.degrees(math.atan(math.tan(math.radians(0.5 * FOV_H_DEG)) * height / width))
    return ChannelSpec("bench", width, height, -0.5 * FOV_H_DEG, 0.5 * FOV_H_DEG, -half_v, half_v)


def sweep_eye_xy(terrain) -> tuple[float, float]:
    ex, ey = terrain.extent_m
    return (float(terrain.origin[0]) + EYE_FRACTION * ex,
            float(terrain.origin[1]) + EYE_FRACTION * ey)


def frame_case(database, channel, eyepoint, repeats: int, *, alone: bool = False) -> dict:
    """Time render_frame as a channel worker calls it (colour only, into a reused buffer) and,
    with alone, render_background called by itself (per-sample depth everywhere), alternating
    the two in every repetition so that a busy moment of the machine falls on both alike."""
    from channel_worker.pipeline.geometry.view import make_view
    from channel_worker.pipeline.render import render_frame
    from services.rig.report import FrameReport

    out = np.empty((channel.height, channel.width, 3), np.float32)
    view = make_view(channel, eyepoint)
    offsets = RenderOptions(samples=SAMPLES).sample_offsets()
    options = RenderOptions(samples=SAMPLES, with_range=False)
    runs: list[dict[str, float]] = []
    walls: list[float] = []
    alone_walls: list[float] = []
    report = FrameReport()
    for k in range(repeats + 1):  # the first is the warm-up: numba compiles, pages are read
        report.clear()
        t0 = time.perf_counter()
        render_frame(database, channel, eyepoint, options, report=report, out=out)
        t1 = time.perf_counter()
        if alone:
            background_alone(database, view, offsets)
        t2 = time.perf_counter()
        if k:
            runs.append(dict(report.stage_seconds))
            walls.append(t1 - t0)
            alone_walls.append(t2 - t1)
    if not runs:
        return {}
    counters = report.counters
    stages = list(runs[0])
    return {
        "terrain_ms": (median_ms([r["background"] for r in runs])
                       if "background" in runs[0] else None),
        "render_terrain_ms": median_ms(alone_walls) if alone else None,
        "frame_ms": median_ms(walls),
        "frame_min_ms": 1e3 * min(walls),
        "render_terrain_min_ms": 1e3 * min(alone_walls) if alone else None,
        "render_terrain_ms_all": [1e3 * w for w in alone_walls] if alone else None,
        "frame_ms_all": [1e3 * w for w in walls],
        "terrain_ms_all": [1e3 * r.get("background", math.nan) for r in runs],
        "stages_ms": {s: median_ms([r[s] for r in runs]) for s in stages},
        "voxels": counters.get("terrain_voxels"),
        "lines": counters.get("terrain_lines"),
        "eye_clamped": counters.get("terrain_eye_clamped"),
    }


def sweep(record: dict, quick: bool, repeats: int, progress: Progress) -> None:
    from bench.scenes.terrain import (
        FRACTAL_RECIPE,
        describe,
        eyepoint_above,
        fractal_terrain,
        terrain_scene,
    )

    progress("loading (building on first use) the 4096^2-voxel bench terrain")
    terrain = fractal_terrain()
    database = terrain_scene(terrain)
    channel = sweep_channel()
    x, y = sweep_eye_xy(terrain)
    pitches = QUICK["pitches"] if quick else PITCHES_DEG
    altitudes = QUICK["altitudes"] if quick else ALTITUDES_M
    pixel_rad = math.radians(FOV_H_DEG) / WIDTH
    record["fractal_terrain"] = {"generator": "bench/scenes/terrain.py", "recipe": FRACTAL_RECIPE,
                                 **describe(terrain)}
    record["sweep_settings"] = {
        "channel": {"width": WIDTH, "height": HEIGHT, "frustum_deg": [
            channel.left_deg, channel.right_deg, channel.bottom_deg, channel.top_deg]},
        "samples": SAMPLES, "eye_xy_m": [x, y], "heading_deg": HEADING_DEG, "roll_deg": 0.0,
        "altitudes_agl_m": list(altitudes), "pitches_deg": list(pitches),
        "scene": "terrain only: no polygons, no haze, no clouds", "level_bias": 0,
        "render_options": {"with_range": False, "out_buffer_reused": True, "filter": "box"},
        "pixel_angle_rad": pixel_rad,
    }
    progress("sweep: warm-up (numba compiles on the first call)")
    frame_case(database, channel, eyepoint_above(terrain, x, y, 200.0, heading_deg=HEADING_DEG,
                                                 pitch_deg=-20.0), 0)
    rows = []
    for agl in altitudes:
        for pitch in pitches:
            eye = eyepoint_above(terrain, x, y, float(agl), heading_deg=HEADING_DEG,
                                 pitch_deg=float(pitch))
            case = frame_case(database, channel, eye, repeats, alone=True)
            ground = float(eye.position[2]) - agl
            rows.append({"altitude_agl_m": agl, "pitch_deg": pitch, "eye_z_m": float(eye.position[2]),
                         "ground_z_m": ground,
                         # Width of a level-0 voxel, in pixels, straight below the eye.
                         "level0_voxel_px_at_nadir": terrain.spacing_m / (agl * pixel_rad),
                         **case})
            progress(f"sweep {agl:5d} m {pitch:4d} deg: render_background "
                     f"{case['render_terrain_ms']:6.1f} ms, in the frame {case['terrain_ms']:6.1f}"
                     f" ms, frame {case['frame_ms']:6.1f} ms, {case['voxels']:9,d} voxels")
    record["sweep"] = rows
    record["sweep_check"] = check_voxel_load(rows, altitudes, pitches)
    spread = sorted(max(r["frame_ms_all"]) / min(r["frame_ms_all"]) for r in rows)
    record["sweep_noise"] = {"what": "slowest / fastest of each cell's repeated frames",
                             "median": spread[len(spread) // 2], "worst": spread[-1]}


def check_voxel_load(rows: list[dict], altitudes, pitches) -> dict[str, Any]:
    """Does JP H07-76990's expectation hold: voxels visited about constant with altitude
    (range), growing as the pitch gets shallower?"""
    vox = {(r["altitude_agl_m"], r["pitch_deg"]): r["voxels"] for r in rows}
    by_pitch = {}
    for p in pitches:
        v = [vox[(a, p)] for a in altitudes]
        by_pitch[str(p)] = {"min": min(v), "max": max(v),
                            "max_over_min": max(v) / max(min(v), 1),
                            "highest_over_lowest_altitude": v[-1] / max(v[0], 1)}
    by_alt = {}
    for a in altitudes:
        v = [vox[(a, p)] for p in pitches]  # steepest first
        drops = [f"{pitches[i]} -> {pitches[i + 1]} deg: {v[i]:,} -> {v[i + 1]:,}"
                 for i in range(len(v) - 1) if v[i + 1] < 0.9 * v[i]]
        by_alt[str(a)] = {"voxels_steepest_to_shallowest": v,
                          "shallowest_over_steepest": v[-1] / max(v[0], 1),
                          "peak_pitch_deg": pitches[int(np.argmax(v))],
                          "drops_over_10_percent": drops}
    constant = all(d["max_over_min"] <= 2.0 for d in by_pitch.values())
    growing = all(not d["drops_over_10_percent"] for d in by_alt.values())
    return {"voxels_by_pitch_over_altitudes": by_pitch, "voxels_by_altitude_over_pitch": by_alt,
            "constant_with_altitude": constant, "criterion_constant": "max / min over the "
            "altitudes at most 2 at every pitch", "grows_as_pitch_gets_shallower": growing,
            "criterion_grows": "no step from a steeper to a shallower pitch loses more than "
            "10 % of the voxels, at every altitude"}


# --- 2. the bundled terrain ------------------------------------------------------------------

def bundled(record: dict, quick: bool, repeats: int, progress: Progress) -> None:
    from bench.scenes.terrain import describe
    from channel_worker.pipeline.geometry.view import make_view
    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from host_sim.flight import bundled_flight
    from services.rig.rigfile import default_rig_path, load_rig

    progress("bundled terrain: loading the demo scene (builds the terrain on first use)")
    demo = load_scene(demo_scene_path())
    if demo.terrain is None:
        raise RuntimeError(f"{demo_scene_path()}: the demo scene has no terrain")
    channel = load_rig(default_rig_path()).with_size(WIDTH, HEIGHT).channels[1].spec
    flight = bundled_flight()
    offsets = RenderOptions(samples=SAMPLES).sample_offsets()
    times_s = QUICK["flight"] if quick else FLIGHT_TIMES_S
    variants = {"terrain+haze+clouds (demo)": demo,
                "terrain+haze": dataclasses.replace(demo, clouds=None),
                "terrain+clouds": dataclasses.replace(demo, haze=None),
                "terrain": dataclasses.replace(demo, haze=None, clouds=None)}
    points, split = [], []
    for t in times_s:
        eye = flight.eyepoint_at(t)
        case = frame_case(demo, channel, eye, repeats)
        points.append({"t_s": t, "position_m": [float(v) for v in eye.position],
                       "hpr_deg": [eye.heading_deg, eye.pitch_deg, eye.roll_deg], **case})
        view = make_view(channel, eye)
        for name, db in variants.items() if t in SPLIT_TIMES_S else ():
            split.append({"scene": "demo (Jacksboro)", "view": f"flight t={t:g} s",
                          "variant": name, **stage_split(db, view, offsets, repeats)})
        progress(f"bundled t={t:4.1f} s: terrain {case['terrain_ms']:6.1f} ms, frame "
                 f"{case['frame_ms']:6.1f} ms, {case['voxels']:,} voxels")
    record["bundled"] = {"scene": "channel_worker/data/airfield_terrain.json (demo_scene_path)",
                         "terrain": describe(demo.terrain),
                         "channel": {"name": channel.name, "width": channel.width,
                                     "height": channel.height, "frustum_deg": [
                                         channel.left_deg, channel.right_deg, channel.bottom_deg,
                                         channel.top_deg]},
                         "samples": SAMPLES, "points": points}

    # The stage split on the fractal database too.
    from bench.scenes.terrain import eyepoint_above, fractal_terrain, terrain_scene

    terrain = fractal_terrain()
    ex, ey = terrain.extent_m
    clouds = dict(CLOUDS, extent_m=[float(terrain.origin[0]), float(terrain.origin[1]),
                                    float(terrain.origin[0]) + ex, float(terrain.origin[1]) + ey])
    full = terrain_scene(terrain, haze=HAZE, clouds=clouds)
    fractal_variants = {"terrain+haze+clouds": full,
                        "terrain+haze": dataclasses.replace(full, clouds=None),
                        "terrain+clouds": dataclasses.replace(full, haze=None),
                        "terrain": dataclasses.replace(full, haze=None, clouds=None)}
    x, y = sweep_eye_xy(terrain)
    for agl, pitch, all_variants in QUICK["split_views"] if quick else SPLIT_VIEWS:
        view = make_view(sweep_channel(), eyepoint_above(terrain, x, y, float(agl),
                                                         heading_deg=HEADING_DEG,
                                                         pitch_deg=float(pitch)))
        for name, db in fractal_variants.items():
            if not all_variants and name != "terrain":
                continue
            split.append({"scene": "fractal", "view": f"{agl} m, pitch {pitch}", "variant": name,
                          **stage_split(db, view, offsets, repeats)})
        progress(f"stage split, fractal {agl} m pitch {pitch}: done")
    record["stage_split"] = {
        "method": "render_background called alone (per-sample depth everywhere, bins=None) "
                  "with parts: cast_ms = parts['background.cast'] (the air and sky table, and "
                  "the terrain cast into every pixel over the sky and the earth plane, or the "
                  "sky and earth alone without terrain), depth_ms = parts['background.depth'] "
                  "(the per-sample terrain depth), clouds_ms = parts['background.clouds'] (the "
                  "cloud scan and the cloud overlay); total_ms = the call's wall time; medians "
                  "over the repetitions after one warm-up call",
        "haze": HAZE, "clouds": CLOUDS, "rows": split}


#: The parts of the background stage render_background reports, and their record keys.
PARTS = {"background.cast": "cast_ms", "background.depth": "depth_ms",
         "background.clouds": "clouds_ms"}


def stage_split(database, view, offsets: np.ndarray, repeats: int) -> dict[str, Any]:
    """The parts of one render_background (terrain cast, per-sample depth, clouds) and the
    whole call, in milliseconds: medians over the repetitions, each timing all of them in one
    call, after one warm-up call."""
    counters: dict[str, int] = {}
    runs: list[dict[str, float]] = []
    totals: list[float] = []
    for k in range(repeats + 1):  # the first is the warm-up
        parts: dict[str, float] = {}
        t0 = time.perf_counter()
        _, counters = background_alone(database, view, offsets, parts=parts)
        t1 = time.perf_counter()
        if k:
            runs.append(parts)
            totals.append(t1 - t0)
    return {**{key: median_ms([r.get(part, 0.0) for r in runs]) for part, key in PARTS.items()},
            "total_ms": median_ms(totals), "voxels": counters.get("terrain_voxels"),
            "lines": counters.get("terrain_lines")}


# --- 3. a scene without terrain --------------------------------------------------------------

def no_terrain(record: dict, repeats: int, progress: Progress) -> None:
    """The flat airfield (no terrain, no haze) skips the stage; haze or clouds alone run it."""
    from channel_worker.pipeline.geometry.view import make_view
    from channel_worker.pipeline.scene.load import bundled_scene_path, demo_scene_path, load_scene
    from host_sim.flight import bundled_flight
    from services.rig.rigfile import default_rig_path, load_rig

    flat = load_scene(bundled_scene_path())
    demo = load_scene(demo_scene_path())
    channel = load_rig(default_rig_path()).with_size(WIDTH, HEIGHT).channels[1].spec
    eye = bundled_flight().eyepoint_at(20.0)
    variants = {"airfield (no terrain, no haze)": flat,
                "airfield + haze": dataclasses.replace(flat, haze=demo.haze),
                "airfield + haze + clouds": dataclasses.replace(flat, haze=demo.haze,
                                                                clouds=demo.clouds),
                "airfield on terrain + haze + clouds (demo)": demo}
    rows = []
    for name, db in variants.items():
        case = frame_case(db, channel, eye, max(repeats, 5))
        rows.append({"scene": name, "terrain_stage_run": case["terrain_ms"] is not None, **case})
    # What deciding to skip costs: render_background on the flat scene returns no_background()
    # at once (render_frame does not even call it).
    from channel_worker.pipeline.background.background import render_background
    from channel_worker.pipeline.geometry.view import frame_constants

    view = make_view(channel, eye)
    frame = frame_constants(view, flat, RenderOptions(samples=SAMPLES).sample_offsets())
    options = RenderOptions(samples=SAMPLES)
    walls, result = timed(lambda: render_background(flat, view, frame, options, None, {}), 1000)
    record["no_terrain"] = {
        "eyepoint": "bundled flight t = 20 s", "channel": channel.name, "samples": SAMPLES,
        "rows": rows,
        "render_terrain_on_flat_scene": {"returns_no_background": not result.on,
                                         "median_us": 1e6 * statistics.median(walls)}}
    progress("flat airfield with and without haze and clouds: done")


# --- 4. the level window ---------------------------------------------------------------------

#: sRGB red of each level of the probe database (green and blue 0).
LEVEL_RED = (40, 90, 130, 165, 195, 220, 240, 255)


def level_probe_database(n: int = 8192, spacing: float = 1.0, page_size: int = 64):
    """A flat database whose level L is coloured (LEVEL_RED[L], 0, 0); every page of a level is
    one stored page, so it costs a few pages."""
    from channel_worker.pipeline.scene.terrain.database import TerrainDatabase, page_layout

    pages_x, pages_y, table_offset = page_layout(n, n, page_size)
    levels = len(pages_x)
    z = np.zeros((levels, page_size, page_size, 4), np.float32)
    rgb = np.zeros((levels, page_size, page_size, 4, 3), np.uint8)
    table = np.empty(int((pages_x * pages_y).sum()), np.int32)
    for lv in range(levels):
        rgb[lv, ..., 0] = LEVEL_RED[lv]
        count = int(pages_x[lv] * pages_y[lv])
        table[table_offset[lv]:table_offset[lv] + count] = lv
    return TerrainDatabase(
        spacing_m=spacing, origin=np.array([-0.5 * n * spacing, -0.5 * n * spacing, 0.0]), nx=n,
        ny=n, page_size=page_size, levels=levels, pages_x=pages_x, pages_y=pages_y,
        table_offset=table_offset, page_table=table, z=z, rgb=rgb,
        pattern=np.zeros((levels, page_size, page_size), np.uint8), z_min=0.0, z_max=0.0,
        source="<bench level probe>")


def level_window(record: dict, progress: Progress) -> None:
    """Which level each bias draws straight below the eye, as the eye climbs: the measured
    window of voxel widths in pixels (docs/terrain.md: 2**bias to 2**(bias + 1))."""
    from bench.scenes.terrain import terrain_scene
    from channel_worker.pipeline.background.terrain import _SRGB_LUT
    from channel_worker.pipeline.geometry.view import make_view
    from services.rig.frame import ChannelSpec, Eyepoint

    probe = level_probe_database()
    database = terrain_scene(probe)
    # A 64 x 64 channel with the sweep's pixel angle (60 / 1280 degrees): the level choice
    # depends only on the angle of a pixel.
    pixel_rad = math.radians(FOV_H_DEG) / WIDTH
    half = 0.5 * 64 * math.degrees(pixel_rad)
    channel = ChannelSpec("probe", 64, 64, -half, half, -half, half)
    reds = _SRGB_LUT[np.array(LEVEL_RED[:probe.levels])]
    centre = np.array([[0.5, 0.5]])
    rows = []
    for bias in BIASES:
        seen = []
        for k in range(12, -25, -1):  # level-0 voxel from 8 px down to 1/64 px, quarter octaves
            level0_px = 2.0 ** (k / 4.0)
            agl = probe.spacing_m / (level0_px * pixel_rad)
            eye = Eyepoint(position=np.array([0.0, 0.0, agl]), heading_deg=0.0, pitch_deg=-90.0,
                           roll_deg=0.0)
            bg, _ = background_alone(database, make_view(channel, eye), centre, level_bias=bias)
            level = int(np.argmin(np.abs(reds - bg.rgb[32, 32, 0])))
            seen.append({"altitude_m": agl, "level0_voxel_px": level0_px, "level": level,
                         "voxel_px": level0_px * 2 ** level})
        # Where a coarser level exists and a finer one was possible, the choice is the window's.
        free = [s["voxel_px"] for s in seen if 0 < s["level"] < probe.levels - 1]
        rows.append({"bias": bias, "voxel_px_min": min(free) if free else None,
                     "voxel_px_max": max(free) if free else None,
                     "documented_px": [2.0 ** bias, 2.0 ** (bias + 1)], "samples": seen})
    record["level_window"] = {
        "method": "flat database, level L coloured (LEVEL_RED[L], 0, 0); a nadir view's centre "
                  "pixel at 37 heights (level-0 voxel 8 px to 1/64 px wide, quarter octaves), "
                  "pixel angle 60/1280 degrees; voxel_px_min/max over the heights where the "
                  "level drawn is neither the finest nor the coarsest",
        "rows": rows}
    progress("level window per bias: " + ", ".join(
        f"bias {r['bias']}: {r['voxel_px_min']}-{r['voxel_px_max']} px" for r in rows))


# --- 5. speed against error ------------------------------------------------------------------

def bias_grid(record: dict, quick: bool, repeats: int, progress: Progress) -> None:
    from bench.scenes.terrain import eyepoint_above, fractal_terrain, terrain_scene
    from channel_worker.pipeline.geometry.view import make_view

    terrain = fractal_terrain()
    database = terrain_scene(terrain, sky=GREY, earth=GREY)
    background = database.sky_colour.astype(np.float64)
    x, y = sweep_eye_xy(terrain)
    stride = QUICK["error_stride"] if quick else ERROR_STRIDE
    views = QUICK["error_views"] if quick else ERROR_VIEWS
    biases = QUICK["biases"] if quick else BIASES
    rgss4 = RenderOptions(samples=SAMPLES).sample_offsets()
    centre = np.array([[0.5, 0.5]])
    both = np.concatenate([rgss4, centre])  # the reference traces these five per pixel

    cases = []
    for agl, pitch in views:
        eye = eyepoint_above(terrain, x, y, float(agl), heading_deg=HEADING_DEG,
                             pitch_deg=float(pitch))
        view = make_view(sweep_channel(), eye)
        background_alone(database, view, rgss4)  # warm-up: the view's pages are read
        t0 = time.perf_counter()
        ref = reference_subset(terrain, view, both, stride)
        cases.append({"agl": agl, "pitch": pitch, "view": view, **ref,
                      "ref_rgb": np.where(ref["hit"][..., None], ref["rgb"],
                                          background).mean(axis=2),
                      "ref_hit4": ref["hit"][..., :len(rgss4)],
                      "ref_seconds": time.perf_counter() - t0})
        progress(f"reference: {ref['hit'].shape[1]} x {ref['hit'].shape[0]} pixels x "
                 f"{len(both)} rays, {agl} m pitch {pitch}: {cases[-1]['ref_seconds']:.1f} s")
    rows = []
    for bias in biases:
        per_view = []
        for c in cases:
            walls, (bg, counters) = timed(functools.partial(
                background_alone, database, c["view"], rgss4, level_bias=bias), repeats,
                warm=False)
            bgc, _ = background_alone(database, c["view"], centre, level_bias=bias)
            per_view.append({"altitude_agl_m": c["agl"], "pitch_deg": c["pitch"],
                             "terrain_ms": median_ms(walls),
                             "terrain_ms_all": [1e3 * w for w in walls],
                             "voxels": counters["terrain_voxels"],
                             "lines": counters["terrain_lines"],
                             **subset_error(bg, bgc, c)})
        row = {"level_bias": bias,
               "terrain_ms": float(np.mean([v["terrain_ms"] for v in per_view])),
               "voxels": int(np.mean([v["voxels"] for v in per_view]))}
        for key in ("colour_mean", "colour_p99", "coverage_disagree", "range_median",
                    "range_p95"):
            row[key] = float(np.mean([v[key] for v in per_view]))
        row["views"] = per_view
        rows.append(row)
        progress(f"bias {bias:2d}: {row['terrain_ms']:6.1f} ms, colour error "
                 f"{row['colour_mean']:.4f}")
    h, w = cases[0]["hit"].shape[:2]
    record["speed_vs_error"] = {
        "scene": f"fractal terrain only, sky = earth = {GREY} (a miss is the same colour in both)",
        "timing": {"width": WIDTH, "height": HEIGHT, "samples": SAMPLES, "repeats": repeats,
                   "what": "render_background alone, level_bias as given; no warm-up call "
                           "per setting (one per view before the grid)"},
        "error": {"pixels": f"every {stride}th pixel each way of the same {WIDTH} x {HEIGHT} "
                            f"render ({w} x {h} pixels, from pixel {stride // 2})",
                  "width": w, "height": h, "stride": stride,
                  "reference": "channel_worker/testing/terrain_reference.py reference_rays: "
                               "exact ray casting of the level-0 surface, rays through the rgss4 "
                               "samples and the centre of each of those pixels",
                  "colour": "per pixel mean absolute linear-RGB error (over channels) of our "
                            "pixel against the reference's mean of its 5 rays (misses take the "
                            "grey background); colour_mean is the mean over pixels, colour_p99 "
                            "the 99th percentile",
                  "coverage_disagree": "share of rgss4 samples where (our inv_z > 0) differs "
                                       "from the reference's hit",
                  "range": "relative error of our pixel range (a render with one centre "
                           "sample) against the centre ray's, where both see terrain: median "
                           "and 95th percentile",
                  "reference_seconds": [c["ref_seconds"] for c in cases]},
        "views": [{"altitude_agl_m": c["agl"], "pitch_deg": c["pitch"]} for c in cases],
        "aggregate": "terrain_ms, voxels and every error: mean over the views",
        "rows": rows}


def reference_subset(terrain, view, offsets: np.ndarray, stride: int) -> dict[str, np.ndarray]:
    """The exact reference for every stride-th pixel (each way) of a view: the rays through
    the given sample offsets of pixels (stride // 2 + k stride), as reference_terrain traces
    them for a whole raster. Returns ys, xs and (h, w, S) rgb / range / hit."""
    from channel_worker.pipeline.geometry.view import screen_mapping
    from channel_worker.testing.terrain_reference import reference_rays

    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    xs = np.arange(stride // 2, view.width, stride)
    ys = np.arange(stride // 2, view.height, stride)
    sx = xs[None, :, None] + offsets[None, None, :, 0]
    sy = ys[:, None, None] + offsets[None, None, :, 1]
    d = np.empty((ys.size, xs.size, offsets.shape[0], 3))
    d[..., 0] = (sx - sx_off) / sx_scale  # guard: the channel's scales are nonzero
    d[..., 1] = (sy - sy_off) / sy_scale
    d[..., 2] = 1.0
    rgb, range_m, hit = reference_rays(terrain, view.eye,
                                       d.reshape(-1, 3) @ np.asarray(view.world_to_eye))
    shape = d.shape[:3]
    return {"ys": ys, "xs": xs, "rgb": rgb.reshape(shape + (3,)),
            "range": range_m.reshape(shape), "hit": hit.reshape(shape)}


def subset_error(bg, bgc, case: dict) -> dict[str, float]:
    """Colour, coverage and range error of our full-size render (bg: rgss4, bgc: one centre
    sample) at the reference's pixels."""
    pick = np.ix_(case["ys"], case["xs"])
    err = np.abs(bg.rgb[pick].astype(np.float64) - case["ref_rgb"]).mean(axis=2)
    ours = bg.inv_z[pick] > 0.0
    ref_hit_c = case["hit"][..., -1]
    r_ref = case["range"][..., -1]
    r_ours = bgc.range_m[pick].astype(np.float64)
    seen = ref_hit_c & np.isfinite(r_ours)
    rel = np.abs(r_ours[seen] - r_ref[seen]) / r_ref[seen]
    return {"colour_mean": float(err.mean()), "colour_p99": float(np.percentile(err, 99)),
            "coverage_disagree": float((ours != case["ref_hit4"]).mean()),
            "range_median": float(np.median(rel)) if rel.size else 0.0,
            "range_p95": float(np.percentile(rel, 95)) if rel.size else 0.0}


# --- 6. a lean Voxel Space peer ---------------------------------------------------------------

#: The approach of the peer comparison: eyepoints on a GLIDE_DEG glide path at the given
#: horizontal distances from its aim point (on the ground), heading along it, pitched down
#: GLIDE_DEG, roll 0. Jacksboro: runway 36 of the bundled airfield (threshold at y = -1000 m,
#: the runway at z = 0), aiming 300 m past the threshold; the hills under the path clear it by
#: 6.5 m at the least (2 km out, a path of 105 m over a 94 m crest: a real approach over
#: Tennessee hills). Fractal: aim point and heading chosen once by a search of aim points
#: every 150 m and eight headings, for the lowest aim whose path clears the terrain by at
#: least 40 m over its last 8 km with at least 5 km of database ahead: this one clears it by
#: 65 m, with 7.4 km ahead.
GLIDE_DEG = 3.0
APPROACHES: tuple[dict[str, Any], ...] = (
    {"terrain": "fractal", "aim_xy_m": (-944.0, -344.0), "heading_deg": 315.0,
     "distances_m": (8000.0, 4000.0, 2000.0, 1000.0, 500.0)},
    {"terrain": "jacksboro", "aim_xy_m": (0.0, -700.0), "heading_deg": 0.0,
     "distances_m": (12000.0, 6000.0, 3000.0, 1500.0, 750.0)},
)
#: The sweep's views the peer can draw at all: a horizon shift is no camera pitch of -30 degrees
#: or steeper (straight down there is no horizon to shift).
PEER_SWEEP_PITCHES_DEG = (-20, -10, -5, 0)
#: Range error on every PEER_STRIDE-th pixel each way (approach views: 320 x 256 reference rays)
#: and every PEER_SWEEP_STRIDE-th on the sweep's views (160 x 128).
PEER_STRIDE, PEER_SWEEP_STRIDE = 4, 8
PEER_QUICK: dict[str, Any] = {"distances": 2, "sweep": ((200, -10),), "stride": 16}
#: The issue's target: our terrain stage at 4 samples at most this many times the peer's time
#: at one sample.
PEER_TARGET_RATIO = 1.0


def glide_eyepoints(terrain, approach: dict[str, Any], distances) -> list[tuple[float, Any]]:
    """(distance m, Eyepoint) on the approach's glide path, GLIDE_DEG above the aim point."""
    from bench.scenes.terrain import ground_z
    from services.rig.frame import Eyepoint

    ax, ay = approach["aim_xy_m"]
    h = math.radians(approach["heading_deg"])
    aim_z = ground_z(terrain, ax, ay)
    out = []
    for d in distances:
        x, y = ax - d * math.sin(h), ay - d * math.cos(h)
        z = aim_z + d * math.tan(math.radians(GLIDE_DEG))
        below = ground_z(terrain, x, y)
        if z <= below:
            raise RuntimeError(f"{approach['terrain']} approach: the eye {d:g} m out ({z:.1f} m) "
                               f"is not above the ground under it ({below:.1f} m)")
        out.append((d, Eyepoint(position=np.array([x, y, z]), heading_deg=approach["heading_deg"],
                                pitch_deg=-GLIDE_DEG, roll_deg=0.0)))
    return out


def range_error(range_m: np.ndarray, terrain: np.ndarray, ref_range: np.ndarray,
                ref_hit: np.ndarray) -> dict[str, float]:
    """Relative range error where both the renderer (its terrain mask) and the reference see
    terrain (median, 95th percentile, maximum), and the share of pixels where they disagree on
    it."""
    r = range_m.astype(np.float64)
    seen = ref_hit & terrain
    rel = np.abs(r[seen] - ref_range[seen]) / ref_range[seen]  # guard: a hit's range is > 0
    return {"range_median": float(np.median(rel)) if rel.size else 0.0,
            "range_p95": float(np.percentile(rel, 95)) if rel.size else 0.0,
            "range_max": float(rel.max()) if rel.size else 0.0,
            "coverage_disagree": float((terrain != ref_hit).mean())}


def peer_case(terrain, database, maps, eye, repeats: int, stride: int) -> dict[str, Any]:
    """Our frame and the peer's from one eye, timed alternately in every repetition (a busy
    moment of the machine falls on both alike: stage_against_peer), and the range error of
    both."""
    from channel_worker.pipeline.geometry.view import make_view

    view = make_view(sweep_channel(), eye)
    timed = stage_against_peer(database, maps, eye, eye,
                               RenderOptions(samples=SAMPLES, with_range=False), repeats)
    peer = timed["peer_frame"]
    stage = [1e-3 * t for t in timed["ours_ms_all"]]
    frame = [1e-3 * t for t in timed["frame_ms_all"]]
    peer_walls = [1e-3 * t for t in timed["peer_ms_all"]]
    t0 = time.perf_counter()
    centre = np.array([[0.5, 0.5]])
    ref = reference_subset(terrain, view, centre, stride)
    ref_seconds = time.perf_counter() - t0
    ours_c, _ = background_alone(database, view, centre)  # one centre sample: its range
    pick = np.ix_(ref["ys"], ref["xs"])
    ref_range, ref_hit = ref["range"][..., 0], ref["hit"][..., 0]
    terrain_ms, peer_ms = median_ms(stage), median_ms(peer_walls)
    return {"terrain_ms": terrain_ms, "frame_ms": median_ms(frame), "peer_ms": peer_ms,
            "ratio_terrain_over_peer": terrain_ms / peer_ms,
            "ratio_frame_over_peer": median_ms(frame) / peer_ms,
            "terrain_ms_all": [1e3 * w for w in stage], "frame_ms_all": [1e3 * w for w in frame],
            "peer_ms_all": [1e3 * w for w in peer_walls],
            "voxels": timed["voxels"], "peer_samples": peer.samples,
            # Our terrain is where inv_z > 0 (the earth plane beyond the database has a range
            # too); the peer's where it has a range.
            "ours": range_error(ours_c.range_m[pick], ours_c.inv_z[..., 0][pick] > 0.0,
                                ref_range, ref_hit),
            "peer": range_error(peer.range_m[pick], np.isfinite(peer.range_m[pick]), ref_range,
                                ref_hit),
            "reference_hit_share": float(ref_hit.mean()), "reference_seconds": ref_seconds,
            "error_pixels": [int(ref_hit.shape[1]), int(ref_hit.shape[0])], "stride": stride}


def voxel_space_peer(record: dict, quick: bool, repeats: int, progress: Progress) -> None:
    """Our terrain stage and the lean Voxel Space peer, side by side (record["voxel_space_peer"])."""
    from bench.scenes.terrain import describe, eyepoint_above, fractal_terrain, terrain_scene
    from bench.voxel_space import GROWTH, voxel_maps
    from channel_worker.pipeline.scene.terrain.bundled import load_bundled_terrain

    progress("Voxel Space peer: loading both databases and taking their level-0 maps")
    terrains = {"fractal": fractal_terrain(), "jacksboro": load_bundled_terrain()}
    maps, map_seconds = {}, {}
    for name, terrain in terrains.items():
        t0 = time.perf_counter()
        maps[name] = voxel_maps(terrain)
        map_seconds[name] = time.perf_counter() - t0
    databases = {name: terrain_scene(t) for name, t in terrains.items()}

    views: list[dict[str, Any]] = []
    for approach in APPROACHES:
        distances = approach["distances_m"][:PEER_QUICK["distances"]] if quick \
            else approach["distances_m"]
        for d, eye in glide_eyepoints(terrains[approach["terrain"]], approach, distances):
            views.append({"set": f"approach, {approach['terrain']}", "terrain": approach["terrain"],
                          "view": f"{d / 1e3:g} km out, {eye.position[2]:.0f} m", "eye": eye,
                          "stride": PEER_QUICK["stride"] if quick else PEER_STRIDE})
    fractal = terrains["fractal"]
    x, y = sweep_eye_xy(fractal)
    sweep_views = PEER_QUICK["sweep"] if quick else [(a, p) for a in ALTITUDES_M
                                                     for p in PEER_SWEEP_PITCHES_DEG]
    for agl, pitch in sweep_views:
        eye = eyepoint_above(fractal, x, y, float(agl), heading_deg=HEADING_DEG,
                             pitch_deg=float(pitch))
        views.append({"set": "sweep, fractal", "terrain": "fractal",
                      "view": f"{agl} m, pitch {pitch}", "eye": eye,
                      "stride": PEER_QUICK["stride"] if quick else PEER_SWEEP_STRIDE})

    rows = []
    for v in views:
        name = v["terrain"]
        case = peer_case(terrains[name], databases[name], maps[name], v["eye"], repeats,
                         v["stride"])
        eye = v.pop("eye")
        rows.append({**v, "position_m": [float(c) for c in eye.position],
                     "hpr_deg": [eye.heading_deg, eye.pitch_deg, eye.roll_deg], **case})
        progress(f"peer, {v['set']}, {v['view']}: ours {case['terrain_ms']:6.1f} ms (frame "
                 f"{case['frame_ms']:6.1f}), peer {case['peer_ms']:5.1f} ms, x "
                 f"{case['ratio_terrain_over_peer']:.1f}; range p95 ours "
                 f"{100 * case['ours']['range_p95']:.3f} %, peer "
                 f"{100 * case['peer']['range_p95']:.3f} %")
    summary = []
    for name in dict.fromkeys(r["set"] for r in rows):
        sel = [r for r in rows if r["set"] == name]
        summary.append({"set": name, "views": len(sel),
                        **{key: float(np.mean([r[key] for r in sel]))
                           for key in ("terrain_ms", "frame_ms", "peer_ms")},
                        "ratio_terrain_over_peer_worst": max(r["ratio_terrain_over_peer"]
                                                             for r in sel),
                        **{f"{who}_{key}": float(np.mean([r[who][key] for r in sel]))
                           for who in ("ours", "peer")
                           for key in ("range_median", "range_p95", "coverage_disagree")}})
        s = summary[-1]
        s["ratio_terrain_over_peer"] = s["terrain_ms"] / s["peer_ms"]
        s["ratio_frame_over_peer"] = s["frame_ms"] / s["peer_ms"]
    worst = max(r["ratio_terrain_over_peer"] for r in rows)
    record["voxel_space_peer"] = {
        "what": "our background stage (JP H07-76990 voxel terrain) at 4 samples against a lean "
                "Voxel Space renderer (bench/voxel_space.py) at 1 sample, same eyes, same "
                "channel frustum, same database, one thread on one pinned core",
        "peer": {"algorithm": "Voxel Space (NovaLogic, Comanche 1992; US 5,550,959, US "
                              "6,020,893; S. Macke's description, "
                              "github.com/s-macke/VoxelSpace): per screen column a "
                              "front-to-back march over the height map along the column's "
                              "ground ray with a y-buffer; nearest map cell; one sample per "
                              "pixel; pitch as a horizon shift, no roll",
                 "maps": "level 0 of the database: cell height = the surface at the voxel "
                         "centre (mean of its corners), colour = mean of its corners in linear "
                         "light (sRGB 8-bit); pattern voxels as columns to the pattern's top",
                 "step": f"dz = one cell + {GROWTH:g} z (z: depth along the view)",
                 "output": "(H, W, 3) float32 linear RGB and (H, W) float32 range from the eye "
                           "to the map sample drawn, row-major like our frame, buffers reused",
                 "numba": "one @njit kernel, no parallel loop"},
        "ours": {"samples": SAMPLES, "what": "render_frame on a terrain-only scene (no polygons, "
                                             "haze or clouds) as a channel worker calls it: "
                                             "with_range=False, output buffer reused; "
                                             "terrain_ms = FrameReport.stage_seconds"
                                             "['background'], frame_ms = the call's wall time"},
        "channel": {"width": WIDTH, "height": HEIGHT, "fov_h_deg": FOV_H_DEG,
                    "square_pixels": True},
        "timing": "medians over the repeats after one warm-up frame each; ours and the peer's "
                  "frame alternate in every repetition",
        "error": "relative range error |r - r_ref| / r_ref at the centre of every stride-th pixel "
                 "each way (from pixel stride // 2) where both the renderer and the reference "
                 "see terrain (median and 95th percentile), and the share of those pixels where "
                 "they disagree on seeing terrain (ours: inv_z > 0, so the earth plane beyond "
                 "the database is not terrain; the peer: a finite range); the reference is "
                 "channel_worker/testing/terrain_reference.py reference_rays (exact ray casting "
                 "of the level-0 surface) through the pixel centre; ours: render_background "
                 "alone with one centre sample (its range_m), as in speed_vs_error; the peer: "
                 "its range_m",
        "glide_deg": GLIDE_DEG, "approaches": [dict(a) for a in APPROACHES],
        "sweep": {"eye_xy_m": [x, y], "heading_deg": HEADING_DEG,
                  "views": [list(v) for v in sweep_views]},
        "terrains": {name: describe(t) for name, t in terrains.items()},
        "voxel_maps_seconds": map_seconds,
        "aggregate": "per set of views: mean of the times (ratio = mean ours / mean peer), "
                     "the worst view's ratio, means of the error figures",
        "rows": rows, "summary": summary,
        "target": {"what": "our terrain stage at 4 samples <= 1.0 x the peer's time at 1 sample "
                           "(issue 14), on every view", "required": PEER_TARGET_RATIO,
                   "measured_worst": worst, "met": worst <= PEER_TARGET_RATIO},
        "quick": quick, "repeats": repeats}


# --- 7. the targets ------------------------------------------------------------------

#: The targets' eyes on the bundled Jacksboro terrain, all above the ground at TARGET_XY_M (3 km
#: south of the airfield's centre): (name, height above the ground m, heading deg, pitch deg).
TARGET_XY_M = (0.0, -3000.0)
TARGET_EYES: tuple[tuple[str, float, float, float], ...] = (
    ("level, 300 m", 300.0, 0.0, 0.0),
    ("2 km, pitch -10", 2000.0, 0.0, -10.0),
    ("60 m, heading 20", 60.0, 20.0, 0.0),
)
TARGET_ROLLS_DEG = (0.0, 30.0, 90.0)
#: Samples per pixel of our stage and their patterns (services/rig/options.py
#: SAMPLE_PATTERNS); the thread scaling runs at TARGET_THREAD_SAMPLES.
TARGET_SAMPLES = {1: "centre", 4: "rgss4"}
TARGET_THREAD_SAMPLES = 4
#: Range error on every TARGET_STRIDE-th pixel each way (160 x 128 reference rays per view).
TARGET_STRIDE = 8
#: The issue's targets, as (required, aim): our background stage over the peer's time at roll
#: 0 (at most), at rolls 30 and 90 over the peer's at roll 0 (at most), and the stage's time on
#: one numba thread over its time on two (at least).
TARGET_ROLL0 = (1.0, 0.5)
TARGET_ROLLED = (1.2, 0.6)
TARGET_THREADS = (1.85, 1.95)


def cpu_pair(cpu: int | None, allowed: list[int]) -> tuple[int, int] | None:
    """The two CPUs of section 7's thread scaling: the pinned one and the next this process
    was allowed (None where there is no second one, or no pinning)."""
    others = [c for c in allowed if c != cpu]
    return None if cpu is None or not others else (cpu, others[0])


def _all_threads_on(cpus: set[int]) -> None:
    """Every thread of this process (numba's workers too) allowed on cpus."""
    tasks = Path("/proc/self/task")
    tids = [int(t.name) for t in tasks.iterdir()] if tasks.is_dir() else [0]
    for tid in tids:
        with contextlib.suppress(ProcessLookupError):  # a thread that ended meanwhile
            os.sched_setaffinity(tid, cpus)


@contextlib.contextmanager
def on_cpus(cpus: set[int]) -> Iterator[None]:
    """Run on the given CPUs, then back on the main thread's CPUs of before. Each thread
    keeps the affinity it was started with, so numba's workers, started under the one-CPU pin,
    are moved too (all the threads of /proc/self/task)."""
    before = os.sched_getaffinity(0)
    _all_threads_on(cpus)
    try:
        yield
    finally:
        _all_threads_on(before)


def stage_against_peer(database, maps, eye, peer_eye, options: RenderOptions,
                       repeats: int) -> dict[str, Any]:
    """Our background stage (render_frame from eye, as a channel worker calls it) and the
    peer's frame (from peer_eye), timed alternately in every repetition after one warm-up
    each, as peer_case does."""
    from bench.voxel_space import render_voxel_space
    from channel_worker.pipeline.geometry.view import make_view
    from channel_worker.pipeline.render import render_frame
    from services.rig.report import FrameReport

    channel = sweep_channel()
    peer_view = make_view(channel, peer_eye)
    out = np.empty((channel.height, channel.width, 3), np.float32)
    report = FrameReport()
    peer = None
    stage, frame, peer_walls = [], [], []
    for k in range(repeats + 1):  # the first is the warm-up: numba compiles, pages are read
        report.clear()
        t0 = time.perf_counter()
        render_frame(database, channel, eye, options, report=report, out=out)
        t1 = time.perf_counter()
        peer = render_voxel_space(maps, peer_view, sky=database.sky_colour,
                                  earth=database.earth_colour, out=peer)
        t2 = time.perf_counter()
        if k:
            stage.append(report.stage_seconds["background"])
            frame.append(t1 - t0)
            peer_walls.append(t2 - t1)
    assert peer is not None  # repeats + 1 >= 1 frames
    ours_ms, peer_ms = median_ms(stage), median_ms(peer_walls)
    return {"ours_ms": ours_ms, "peer_ms": peer_ms, "ratio": ours_ms / peer_ms,
            "ours_ms_all": [1e3 * w for w in stage], "peer_ms_all": [1e3 * w for w in peer_walls],
            "frame_ms_all": [1e3 * w for w in frame],
            "voxels": report.counters.get("terrain_voxels"),
            "lines": report.counters.get("terrain_lines"),
            "eye_clamped": report.counters.get("terrain_eye_clamped"),
            "peer_frame": peer}


def target_error(terrain, database, view, stride: int) -> tuple[dict[str, Any], dict]:
    """Range error of our stage (render_background alone, one centre sample) at the centre
    of every stride-th pixel each way against the exact reference: (error, reference)."""
    centre = np.array([[0.5, 0.5]])
    t0 = time.perf_counter()
    ref = reference_subset(terrain, view, centre, stride)
    seconds = time.perf_counter() - t0
    ours_c, _ = background_alone(database, view, centre)
    pick = np.ix_(ref["ys"], ref["xs"])
    error = range_error(ours_c.range_m[pick], ours_c.inv_z[..., 0][pick] > 0.0,
                        ref["range"][..., 0], ref["hit"][..., 0])
    return {**error, "reference_hit_share": float(ref["hit"][..., 0].mean()),
            "reference_seconds": seconds}, ref


def thread_scaling(database, eye, repeats: int) -> dict[str, Any]:
    """The background stage (render_frame, TARGET_THREAD_SAMPLES samples) on one numba
    thread and on two, alternating in every repetition after one warm-up each."""
    import numba

    from channel_worker.pipeline.render import render_frame
    from services.rig.report import FrameReport

    channel = sweep_channel()
    options = RenderOptions(samples=TARGET_SAMPLES[TARGET_THREAD_SAMPLES], with_range=False)
    out = np.empty((channel.height, channel.width, 3), np.float32)
    report = FrameReport()
    walls: dict[int, list[float]] = {1: [], 2: []}
    try:
        for k in range(2 * repeats + 1):  # the first is the warm-up
            for threads in (1, 2):
                numba.set_num_threads(threads)
                report.clear()
                render_frame(database, channel, eye, options, report=report, out=out)
                if k:
                    walls[threads].append(report.stage_seconds["background"])
    finally:
        numba.set_num_threads(1)
    t1, t2 = median_ms(walls[1]), median_ms(walls[2])
    return {"t1_ms": t1, "t2_ms": t2, "speedup": t1 / t2,
            "t1_ms_all": [1e3 * w for w in walls[1]], "t2_ms_all": [1e3 * w for w in walls[2]]}


def _verdict(what: str, required: str, aim: str, measured: list[float], *,
             at_most: bool, bounds: tuple[float, float]) -> dict[str, Any]:
    """One target of the issue, judged on its worst case."""
    if not measured:
        return {"what": what, "required": required, "aim": aim, "measured_worst": None,
                "measured_mean": None, "met_required": None, "met_aim": None}
    worst = max(measured) if at_most else min(measured)
    def ok(bound: float) -> bool:
        return worst <= bound if at_most else worst >= bound
    return {"what": what, "required": required, "aim": aim, "measured_worst": worst,
            "measured_mean": float(np.mean(measured)), "met_required": ok(bounds[0]),
            "met_aim": ok(bounds[1])}


def targets(record: dict, quick: bool, repeats: int, pair: tuple[int, int] | None,
            progress: Progress) -> None:
    """The issue's targets on the Jacksboro terrain (record["targets"])."""
    import numba

    from bench.scenes.terrain import describe, eyepoint_above, terrain_scene
    from bench.voxel_space import voxel_maps
    from channel_worker.pipeline.geometry.view import make_view
    from channel_worker.pipeline.jit import thread_pool_size
    from channel_worker.pipeline.scene.terrain.bundled import load_bundled_terrain
    from services.rig.frame import Eyepoint

    progress("targets: loading the Jacksboro terrain and taking its Voxel Space maps")
    terrain = load_bundled_terrain()
    database = terrain_scene(terrain)
    maps = voxel_maps(terrain)
    channel = sweep_channel()
    eyes = TARGET_EYES[:QUICK["target_eyes"]] if quick else TARGET_EYES
    stride = TARGET_STRIDE
    rows: list[dict[str, Any]] = []
    peer_errors: list[dict[str, Any]] = []
    level_eyes = {}
    for name, agl, heading, pitch in eyes:
        level = eyepoint_above(terrain, *TARGET_XY_M, agl, heading_deg=heading, pitch_deg=pitch)
        level_eyes[name] = level
        for roll in TARGET_ROLLS_DEG:
            eye = Eyepoint(position=level.position, heading_deg=level.heading_deg,
                           pitch_deg=level.pitch_deg, roll_deg=roll)
            error, ref = target_error(terrain, database, make_view(channel, eye), stride)
            for samples, pattern in TARGET_SAMPLES.items():
                options = RenderOptions(samples=pattern, with_range=False)
                case = stage_against_peer(database, maps, eye, level, options, repeats)
                peer = case.pop("peer_frame")
                rows.append({"eye": name, "roll": roll, "samples": samples,
                             "pattern": options.samples,
                             "position_m": [float(c) for c in eye.position],
                             "hpr_deg": [eye.heading_deg, eye.pitch_deg, eye.roll_deg], **case,
                             **error})
                progress(f"targets, {name}, roll {roll:g}, {samples} sample(s): ours "
                         f"{case['ours_ms']:6.1f} ms, peer {case['peer_ms']:5.1f} ms, x "
                         f"{case['ratio']:.2f}; range p95 {100 * error['range_p95']:.3f} %, "
                         f"max {100 * error['range_max']:.2f} %")
            if roll == 0.0:  # the peer's own error, from the eye it draws (roll 0)
                pick = np.ix_(ref["ys"], ref["xs"])
                peer_errors.append({"eye": name, **range_error(
                    peer.range_m[pick], np.isfinite(peer.range_m[pick]), ref["range"][..., 0],
                    ref["hit"][..., 0])})

    scaling: dict[str, Any]
    pool = thread_pool_size()
    if pair is None or pool < 2:
        scaling = {"skipped": "no second CPU to run on, or numba's pool has one thread "
                              f"(NUMBA_NUM_THREADS {pool})",
                   "rows": []}
        progress("targets: thread scaling skipped (one CPU)")
    else:
        srows = []
        with on_cpus(set(pair)):
            for name, level in level_eyes.items():
                case = thread_scaling(database, level, repeats)
                srows.append({"eye": name, **case})
                progress(f"targets, threads, {name}: 1 thread {case['t1_ms']:6.1f} ms, 2 "
                         f"threads {case['t2_ms']:6.1f} ms, x {case['speedup']:.2f}")
            affinity_during = sorted(os.sched_getaffinity(0))
        scaling = {"cpus": list(pair), "affinity_during": affinity_during,
                   "affinity_after": sorted(os.sched_getaffinity(0)),
                   "numba_pool": pool,
                   "threading_layer": numba.threading_layer(),
                   "samples": TARGET_THREAD_SAMPLES, "roll": 0.0, "rows": srows,
                   "speedup_mean": float(np.mean([r["speedup"] for r in srows])),
                   "speedup_worst": min(r["speedup"] for r in srows)}

    summary = []
    for roll in TARGET_ROLLS_DEG:
        for samples in TARGET_SAMPLES:
            sel = [r for r in rows if r["roll"] == roll and r["samples"] == samples]
            if sel:
                summary.append({"roll": roll, "samples": samples, "eyes": len(sel),
                                "ours_ms_mean": float(np.mean([r["ours_ms"] for r in sel])),
                                "peer_ms_mean": float(np.mean([r["peer_ms"] for r in sel])),
                                "ratio_mean": float(np.mean([r["ratio"] for r in sel])),
                                "ratio_worst": max(r["ratio"] for r in sel)})
    verdicts = [
        _verdict("terrain (background) stage against the Voxel Space peer at roll 0, 1 and 4 "
                 "samples: ours / peer", "<= 1.0x", "<= 0.5x",
                 [r["ratio"] for r in rows if r["roll"] == 0.0], at_most=True,
                 bounds=TARGET_ROLL0),
        _verdict("terrain (background) stage at rolls 30 and 90 against the peer at roll 0, 1 "
                 "and 4 samples: ours / peer", "<= 1.2x", "<= 0.6x",
                 [r["ratio"] for r in rows if r["roll"] != 0.0], at_most=True,
                 bounds=TARGET_ROLLED),
        _verdict("background stage on 2 numba threads over 1 (t1 / t2), roll 0, "
                 f"{TARGET_THREAD_SAMPLES} samples", ">= 1.85x", ">= 1.95x",
                 [r["speedup"] for r in scaling["rows"]], at_most=False, bounds=TARGET_THREADS),
    ]
    record["targets"] = {
        "what": "the issue's targets: our background stage (terrain cast straight to the "
                "screen) against the lean Voxel Space peer (bench/voxel_space.py, 1 sample) "
                "from the same eye at roll 0 (the peer has no roll), at rolls 0, 30 and 90 "
                "and 1 and 4 samples; the range error of our stage at each roll; the stage's "
                "speed-up from one numba thread to two",
        "terrain": {"name": "bundled Jacksboro (load_bundled_terrain)", **describe(terrain)},
        "scene": "terrain only (bench/scenes/terrain.py terrain_scene): no polygons, haze or "
                 "clouds",
        "channel": {"width": WIDTH, "height": HEIGHT, "fov_h_deg": FOV_H_DEG,
                    "square_pixels": True},
        "eyes": [{"eye": name, "xy_m": list(TARGET_XY_M), "agl_m": agl, "heading_deg": heading,
                  "pitch_deg": pitch} for name, agl, heading, pitch in eyes],
        "rolls_deg": list(TARGET_ROLLS_DEG),
        "samples": {str(n): pattern for n, pattern in TARGET_SAMPLES.items()},
        "timing": "ours_ms: FrameReport.stage_seconds['background'] inside render_frame "
                  "(RenderOptions(samples=1 or 4, with_range=False), output buffer reused); "
                  "peer_ms: render_voxel_space's wall time from the same eye at roll 0; the two "
                  "alternate in every repetition; medians over the repeats after one warm-up "
                  "frame each; ratio = ours_ms / peer_ms. One numba thread on one pinned CPU, "
                  "except the thread scaling",
        "error": f"once per eye and roll (not per sample count): relative range error |r - "
                 f"r_ref| / r_ref at the centre of every {stride}th pixel each way (from pixel "
                 f"{stride // 2}) where both our stage and the reference see terrain: median, "
                 "95th percentile, maximum; coverage_disagree: the share of those pixels where "
                 "they disagree on seeing terrain (ours: inv_z > 0); ours: render_background "
                 "alone with one centre sample (its range_m); the reference: "
                 "channel_worker/testing/terrain_reference.py reference_rays through the pixel "
                 "centres. peer_error: the peer's, from the roll-0 eye, the same way",
        "stride": stride, "repeats": repeats, "quick": quick,
        "rows": rows, "peer_error": peer_errors, "summary": summary,
        "summary_what": "per (roll, samples) over the eyes: mean of the times, mean of the "
                        "per-eye ratios and the worst (highest) ratio",
        "thread_scaling": {
            "what": f"the background stage (render_frame, {TARGET_THREAD_SAMPLES} samples, "
                    "roll 0) with numba.set_num_threads(1) and (2), alternating in every "
                    "repetition, with every thread of the process allowed on two CPUs for "
                    "these frames only (the one-CPU pin restored after); speedup = t1 / t2 of "
                    "the medians", **scaling},
        "targets": verdicts,
        "judged": "each target on its worst case: the highest ratio over the eyes (and sample "
                  "counts), the lowest speed-up over the eyes",
    }


# --- 8. the land's detail ---------------------------------------------------------------------

#: The detail may cost this share of the terrain cast (the issue's constraint).
DETAIL_BUDGET = 0.15


def land_detail(record: dict, quick: bool, repeats: int, progress: Progress) -> None:
    """The cast with the demo scene's terrain.detail and without it, from the docs' views and
    points of the bundled flight (centre channel, the sweep's size)."""
    from channel_worker.pipeline.geometry.view import make_view
    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from host_sim.flight import bundled_flight
    from services.rig.frame import Eyepoint
    from services.rig.rigfile import default_rig_path, load_rig

    sys.path.insert(0, str(REPO / "docs" / "images"))
    from render_views import VIEWS

    demo = load_scene(demo_scene_path())
    plain = dataclasses.replace(demo, terrain_land=None)
    channel = load_rig(default_rig_path()).with_size(WIDTH, HEIGHT).channels[1].spec
    offsets = RenderOptions(samples=SAMPLES).sample_offsets()
    eyes = {name: Eyepoint(np.array(xyz, np.float64), *hpr) for name, (xyz, hpr) in VIEWS.items()}
    flight = bundled_flight()
    for t in (QUICK["flight"][:1] if quick else (0.0, 10.0, 20.0)):
        eyes[f"flight t={t:g} s"] = flight.eyepoint_at(t)
    rows = []
    for name, eye in eyes.items():
        view = make_view(channel, eye)
        # Interleaved, one call of each at a time: this machine's speed drifts over seconds, and
        # the difference wanted is a few tens of milliseconds.
        runs: dict[str, list[dict[str, float]]] = {"with": [], "without": []}
        for k in range(2 * repeats + 1):  # the first is the warm-up
            for key, db in (("with", demo), ("without", plain)):
                parts: dict[str, float] = {}
                t0 = time.perf_counter()
                background_alone(db, view, offsets, parts=parts)
                parts["total"] = time.perf_counter() - t0
                if k:
                    runs[key].append(parts)
        # The fastest of the repeats, not the median: the difference wanted is a few tens of
        # milliseconds, and on a shared 2-core VM the medians of two runs of this section
        # differed by more than that (a share of 12 % and one of 30 % for the same view);
        # anything else running only ever slows a call down.
        with_detail, without = ({"cast_ms": 1000.0 * min(r["background.cast"] for r in runs[key]),
                                 "total_ms": 1000.0 * min(r["total"] for r in runs[key])}
                                for key in ("with", "without"))
        # The detail's cost: what it adds to the cast, against the stage (cast, per-sample depth
        # and clouds) and against the cast alone.
        added = with_detail["cast_ms"] - without["cast_ms"]
        share = added / without["total_ms"] if without["total_ms"] > 0 else 0.0
        cast_share = added / without["cast_ms"] if without["cast_ms"] > 0 else 0.0
        rows.append({"view": name, "with_detail": with_detail, "without": without, "detail_share": share,
                     "cast_share": cast_share})
        progress(f"detail {name}: cast {without['cast_ms']:6.1f} -> {with_detail['cast_ms']:6.1f} ms, "
                 f"+{100 * share:.1f} % of the stage ({100 * cast_share:+.1f} % of the cast)")
    record["detail"] = {
        "method": "render_background called alone on the demo scene with its terrain.detail and with "
                  "terrain_land=None, one call of each in turn, centre channel at the sweep's size and "
                  "samples; cast_ms = parts['background.cast'], total_ms the whole render_background (cast, "
                  "per-sample depth, clouds), the fastest of the repeats after one warm-up of each; "
                  "detail_share = (cast with - cast without) / stage without (the budget's measure), "
                  "cast_share = the same over the cast without",
        "budget": DETAIL_BUDGET, "rows": rows,
        "worst_share": max(r["detail_share"] for r in rows),
    }


def print_detail(section: dict) -> None:
    print(f"\nthe land's detail (budget {100 * section['budget']:.0f} % of the terrain stage), one core")
    print(f"{'view':<22}{'stage without':>14}{'cast without':>14}{'cast with':>11}{'of stage':>10}{'of cast':>9}")
    for r in section["rows"]:
        print(f"{r['view']:<22}{r['without']['total_ms']:>11.1f} ms{r['without']['cast_ms']:>11.1f} ms"
              f"{r['with_detail']['cast_ms']:>8.1f} ms{100 * r['detail_share']:>9.1f}%"
              f"{100 * r.get('cast_share', 0.0):>8.1f}%")
    verdict = "within" if section["worst_share"] <= section["budget"] else "OVER"
    print(f"worst {100 * section['worst_share']:.1f} %: {verdict} the budget")


def section_only(out: Path, key: str, run: Callable[[dict], None],
                 show: Callable[[dict], None], cpu: int | None, progress: Progress) -> int:
    """--peer-only, --targets-only: run one section (run(record) fills record[key]) and put it
    into terrain.json beside the other sections' (they keep their own date and machine; this
    one records its own)."""
    import json

    import numba
    from bench_render import machine

    path = out / "terrain.json"
    record = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    fresh: dict[str, Any] = {}
    run(fresh)
    section = fresh[key]
    section.update({"date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
                    "machine": machine(), "git": git_state(),
                    "one_core": {"cpu": cpu, "numba_threads": numba.get_num_threads()},
                    "seconds": progress.seconds})
    section["machine"]["load_average_1min_at_end"] = (os.getloadavg()[0]
                                                      if hasattr(os, "getloadavg") else None)
    record[key] = section
    show(section)
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {path} ({key})")
    return 0


# --- report ----------------------------------------------------------------------------------

def table(head: list[str], body: list[list[str]]) -> None:
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
    for b in body:
        print("  ".join(c.rjust(w) for c, w in zip(b, widths, strict=True)))


def print_report(record: dict) -> None:
    """The tables and the verdict on JP H07-76990's expectations."""
    rows = record["sweep"]
    s = record["sweep_settings"]
    altitudes, pitches = s["altitudes_agl_m"], s["pitches_deg"]
    cell = {(r["altitude_agl_m"], r["pitch_deg"]): r for r in rows}
    t = record["fractal_terrain"]
    print(f"\nfractal terrain {t['voxels'][0]} x {t['voxels'][1]} voxels at {t['spacing_m']:g} m "
          f"({t['levels']} levels), {s['channel']['width']} x {s['channel']['height']}, "
          f"{SAMPLES}, one core; heading {s['heading_deg']:g}, roll 0; rows: height above the "
          "ground under the eye, columns: pitch")
    for title, key, fmt in (("voxels visited (thousands)", "voxels", lambda v: f"{v / 1e3:,.0f}"),
                            ("render_background alone (per-sample depth everywhere), median ms",
                             "render_terrain_ms", lambda v: f"{v:.1f}"),
                            (("background stage inside render_frame (no polygons, so no "
                              "per-sample depth), median ms"), "terrain_ms",
                             lambda v: f"{v:.1f}"),
                            ("whole frame (terrain-only scene), median ms", "frame_ms",
                             lambda v: f"{v:.1f}")):
        print(f"\n{title}")
        table(["agl m"] + [f"{p}" for p in pitches],
              [[str(a)] + [fmt(cell[(a, p)][key]) for p in pitches] for a in altitudes])
    chk = record["sweep_check"]
    print("\nJP H07-76990: voxels visited about constant with altitude (range) -> "
          + ("HOLDS" if chk["constant_with_altitude"] else "DOES NOT HOLD"))
    for p, d in chk["voxels_by_pitch_over_altitudes"].items():
        print(f"  pitch {p:>4s}: {d['min']:>10,} .. {d['max']:>10,} voxels over the altitudes "
              f"(x {d['max_over_min']:.1f}; highest / lowest altitude x "
              f"{d['highest_over_lowest_altitude']:.2f})")
    print("  a level-0 voxel straight below the eye is " + ", ".join(
        f"{cell[(a, pitches[0])]['level0_voxel_px_at_nadir']:.2g} px at {a} m" for a in altitudes)
        + ": below the level window the finest level is magnified and fewer voxels cover the "
          "view")
    print("JP H07-76990: voxels visited grow as the pitch gets shallower -> "
          + ("HOLDS" if chk["grows_as_pitch_gets_shallower"] else "DOES NOT HOLD everywhere"))
    for a, d in chk["voxels_by_altitude_over_pitch"].items():
        drops = "; ".join(d["drops_over_10_percent"]) or "none"
        print(f"  {a:>5s} m: shallowest / steepest x {d['shallowest_over_steepest']:.1f}, "
              f"peak at pitch {d['peak_pitch_deg']}; drops: {drops}")

    b = record["bundled"]
    print(f"\nbundled Jacksboro terrain, demo scene (terrain, haze, clouds, airfield), "
          f"{b['channel']['name']} channel {b['channel']['width']} x {b['channel']['height']}")
    table(["t s", "terrain ms", "frame ms", "voxels", "lines"],
          [[f"{p['t_s']:g}", f"{p['terrain_ms']:.1f}", f"{p['frame_ms']:.1f}", f"{p['voxels']:,}",
            f"{p.get('lines', '-')}"] for p in b["points"]])

    split = record["stage_split"]["rows"]
    print("\nbackground stage split (median ms): cast = air, sky table and the terrain cast "
          "into the pixels, depth = per-sample depth (everywhere: render_background alone), "
          "clouds = cloud scan and overlay")
    if split and "cast_ms" not in split[0]:
        print("  (a record of the pre-image design, before the direct cast: not shown)")
    else:
        table(["scene", "view", "variant", "cast", "depth", "clouds", "total", "voxels"],
              [[r["scene"], r["view"], r["variant"], f"{r['cast_ms']:.1f}",
                f"{r['depth_ms']:.1f}", f"{r['clouds_ms']:.1f}", f"{r['total_ms']:.1f}",
                f"{r['voxels']:,}" if r["voxels"] is not None else "-"] for r in split])

    nt = record["no_terrain"]
    print(f"\na scene without terrain or haze ({nt['channel']} channel, {nt['eyepoint']})")
    table(["scene", "background stage", "background ms", "frame ms"],
          [[r["scene"], "run" if r["terrain_stage_run"] else "skipped",
            f"{r['terrain_ms']:.1f}" if r["terrain_ms"] is not None else "-",
            f"{r['frame_ms']:.1f}"] for r in nt["rows"]])
    rt = nt["render_terrain_on_flat_scene"]
    skipped = rt.get("returns_no_background", rt.get("returns_none"))
    print(f"  render_background on the flat scene returns no_background(): {skipped} "
          f"({rt['median_us']:.1f} us)")

    print("\nlevel window each bias selects (voxel width in pixels where it is free to choose)")
    table(["bias", "measured px", "documented px"],
          [[str(r["bias"]), (f"{r['voxel_px_min']:.2f} .. {r['voxel_px_max']:.2f}"
                             if r["voxel_px_min"] is not None else "-"),
            f"{r['documented_px'][0]:g} .. {r['documented_px'][1]:g}"]
           for r in record["level_window"]["rows"]])

    sv = record["speed_vs_error"]
    e = sv["error"]
    print(f"\nspeed against error: background stage at {WIDTH} x {HEIGHT} (median ms) and its "
          f"error on every {e['stride']}th pixel ({e['width']} x {e['height']}) against the exact "
          f"reference; mean over {len(sv['views'])} views")
    table(["bias", "ms", "voxels", "colour mean", "colour p99", "coverage", "range med",
           "range p95"],
          [[str(r["level_bias"]), f"{r['terrain_ms']:.1f}", f"{r['voxels']:,}",
            f"{r['colour_mean']:.4f}", f"{r['colour_p99']:.4f}",
            f"{r['coverage_disagree']:.4f}", f"{r['range_median']:.4f}",
            f"{r['range_p95']:.4f}"] for r in sv["rows"]])
    if "voxel_space_peer" in record:  # records before the peer have none
        print_peer(record["voxel_space_peer"])
    if "targets" in record:  # nor the targets
        print_targets(record["targets"])
    if "detail" in record:  # nor the land's detail
        print_detail(record["detail"])
    m = record["machine"]
    noise = record["sweep_noise"]
    print(f"\nnoise: the slowest of a sweep cell's frames is x {noise['median']:.2f} the fastest "
          f"(median over the cells; worst x {noise['worst']:.2f}); above about x 1.3, another "
          "process shared the CPU: rerun")
    print(f"load average {m['load_average_1min']:.2f} at the start, "
          f"{m['load_average_1min_at_end']:.2f} at the end; {record['seconds']:.0f} s in all")


def print_peer(peer: dict) -> None:
    """The side-by-side table of our terrain stage and the Voxel Space peer."""
    ch = peer["channel"]
    print(f"\nVoxel Space peer: our background stage ({peer['ours']['samples']}) against the "
          f"lean Voxel Space renderer (1 sample), {ch['width']} x {ch['height']}, one core, median "
          "ms; relative range error at pixel centres against the exact reference (median, p95, "
          "per cent) and the share of pixels disagreeing on terrain or not (cov, per cent)")
    head = ["set", "view", "ours", "frame", "peer", "ours/peer", "frame/peer", "med ours",
            "med peer", "p95 ours", "p95 peer", "cov ours", "cov peer"]

    def cells(r: dict, ours: dict, theirs: dict) -> list[str]:
        return [f"{r['terrain_ms']:.1f}", f"{r['frame_ms']:.1f}", f"{r['peer_ms']:.1f}",
                f"{r['ratio_terrain_over_peer']:.1f}", f"{r['ratio_frame_over_peer']:.1f}",
                *(f"{100.0 * d[key]:.3f}" for key in ("range_median", "range_p95",
                                                      "coverage_disagree")
                  for d in (ours, theirs))]

    body = [[r["set"], r["view"], *cells(r, r["ours"], r["peer"])] for r in peer["rows"]]
    for s in peer["summary"]:
        body.append([s["set"], f"mean of {s['views']}", *cells(
            s, {k: s[f"ours_{k}"] for k in ("range_median", "range_p95", "coverage_disagree")},
            {k: s[f"peer_{k}"] for k in ("range_median", "range_p95", "coverage_disagree")})])
    table(head, body)
    t = peer["target"]
    print(f"target: {t['what']}: worst ours / peer x {t['measured_worst']:.1f} -> "
          + ("MET" if t["met"] else "NOT MET"))


def print_targets(section: dict) -> None:
    """Section 7's tables: every row, the summary per roll and sample count, the thread
    scaling and the verdict on each of the issue's targets."""
    ch = section["channel"]
    print(f"\ntargets: our background stage against the Voxel Space peer (1 sample, roll 0, "
          f"same eye), Jacksboro terrain, {ch['width']} x {ch['height']}, one core, median ms; "
          f"our relative range error at pixel centres (every {section['stride']}th pixel) "
          "against the exact reference, per cent: median, p95, max, and the share of pixels "
          "disagreeing on terrain or not (cov)")
    table(["eye", "roll", "samples", "ours ms", "peer ms", "ours/peer", "voxels", "range med",
           "range p95", "range max", "cov"],
          [[r["eye"], f"{r['roll']:g}", str(r["samples"]), f"{r['ours_ms']:.1f}",
            f"{r['peer_ms']:.1f}", f"{r['ratio']:.2f}",
            f"{r['voxels']:,}" if r["voxels"] is not None else "-",
            *(f"{100.0 * r[k]:.3f}" for k in ("range_median", "range_p95", "range_max",
                                              "coverage_disagree"))]
           for r in section["rows"]])
    if section.get("peer_error"):
        print("the peer's own range error (roll 0), per cent")
        table(["eye", "range med", "range p95", "range max", "cov"],
              [[e["eye"], *(f"{100.0 * e[k]:.3f}" for k in ("range_median", "range_p95",
                                                            "range_max", "coverage_disagree"))]
               for e in section["peer_error"]])
    print("per roll and sample count, over the eyes")
    table(["roll", "samples", "ours ms", "peer ms", "mean ours/peer", "worst ours/peer"],
          [[f"{s['roll']:g}", str(s["samples"]), f"{s['ours_ms_mean']:.1f}",
            f"{s['peer_ms_mean']:.1f}", f"{s['ratio_mean']:.2f}", f"{s['ratio_worst']:.2f}"]
           for s in section["summary"]])
    sc = section["thread_scaling"]
    if sc.get("skipped"):
        print(f"thread scaling: skipped ({sc['skipped']})")
    else:
        print(f"thread scaling: background stage, roll 0, {sc['samples']} samples, on CPUs "
              f"{sc['cpus']} ({sc['threading_layer']} threading layer)")
        table(["eye", "1 thread ms", "2 threads ms", "t1/t2"],
              [[r["eye"], f"{r['t1_ms']:.1f}", f"{r['t2_ms']:.1f}", f"{r['speedup']:.2f}"]
               for r in sc["rows"]] + [["mean", "", "", f"{sc['speedup_mean']:.2f}"]])
    for t in section["targets"]:
        if t["measured_worst"] is None:
            print(f"target: {t['what']}: not measured")
            continue
        verdict = ("AIM MET" if t["met_aim"] else "REQUIRED MET" if t["met_required"]
                   else "NOT MET")
        print(f"target: {t['what']}: required {t['required']}, aim {t['aim']}; worst x "
              f"{t['measured_worst']:.2f}, mean x {t['measured_mean']:.2f} -> {verdict}")


def plot(record: dict, path: Path) -> bool:
    """Four panels: voxels and stage time against pitch per altitude, the stage split, time
    against error. Returns False (and draws nothing) when matplotlib is not installed."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(13.0, 11.0))
    s = record["sweep_settings"]
    cmap = plt.get_cmap("viridis")
    alts = s["altitudes_agl_m"]
    for k, agl in enumerate(alts):
        pts = [r for r in record["sweep"] if r["altitude_agl_m"] == agl]
        colour = cmap(k / max(len(alts) - 1, 1))
        pitch = [r["pitch_deg"] for r in pts]
        axes[0, 0].plot(pitch, [r["voxels"] for r in pts], "o-", color=colour, label=f"{agl} m")
        axes[0, 1].plot(pitch, [r["render_terrain_ms"] for r in pts], "o-", color=colour,
                        label=f"{agl} m")
        axes[0, 1].plot(pitch, [r["frame_ms"] for r in pts], ":", color=colour)
    axes[0, 0].set_yscale("log")
    axes[0, 0].set_xlabel("pitch, degrees")
    axes[0, 0].set_ylabel("voxels visited per frame")
    axes[0, 0].set_title("voxels visited (fractal terrain, height above ground)", fontsize=9)
    axes[0, 0].legend(fontsize=7)
    axes[0, 1].set_xlabel("pitch, degrees")
    axes[0, 1].set_ylabel("median ms, one core")
    axes[0, 1].set_title(f"render_background alone (solid), whole frame of a terrain-only scene "
                         f"(dotted)\n{WIDTH} x {HEIGHT}, {SAMPLES}, fractal terrain", fontsize=9)
    axes[0, 1].legend(fontsize=7)

    split = record["stage_split"]["rows"]
    labels = [(f"{r['view']}: " if r["scene"] == "fractal"
               else f"Jacksboro {r['view'].removeprefix('flight ')}: ")
              + r["variant"].removesuffix(" (demo)") for r in split]
    ypos = np.arange(len(split))
    left = np.zeros(len(split))
    for key, bar_colour in (("cast_ms", "tab:brown"), ("depth_ms", "tab:blue"),
                            ("clouds_ms", "tab:gray")):
        v = np.array([r.get(key, 0.0) for r in split])
        axes[1, 0].barh(ypos, v, left=left, color=bar_colour, label=key.removesuffix("_ms"))
        left += v
    axes[1, 0].set_yticks(ypos, labels, fontsize=6)
    axes[1, 0].invert_yaxis()
    axes[1, 0].set_xlabel("median ms, one core")
    axes[1, 0].set_title("background stage split: terrain cast, per-sample depth, clouds",
                         fontsize=9)
    axes[1, 0].legend(fontsize=7)

    sv = record["speed_vs_error"]
    bias_colour = {-1: "tab:green", 0: "tab:blue", 1: "tab:orange", 2: "tab:red"}
    ax = axes[1, 1]
    pts = sorted(sv["rows"], key=lambda r: r["level_bias"])
    ax.plot([r["colour_mean"] for r in pts], [r["terrain_ms"] for r in pts], "-", color="0.5",
            lw=0.8)
    for r in pts:
        ax.plot(r["colour_mean"], r["terrain_ms"], "o", color=bias_colour.get(r["level_bias"], "k"),
                label=f"level bias {r['level_bias']}")
    ax.set_xlabel(f"mean colour error against the exact reference (every "
                  f"{sv['error']['stride']}th pixel, linear RGB)")
    ax.set_ylabel(f"background stage, median ms at {WIDTH} x {HEIGHT}")
    ax.set_title("speed against error: level bias", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")  # long bar labels on the left
    plt.close(fig)
    return True


if __name__ == "__main__":
    raise SystemExit(main())
