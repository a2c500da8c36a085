"""The whole frame of the bundled demo scene on one channel, on one thread and on two
(bench/README.md).

    python bench/bench_frame.py                # 7 repeats per case (under a minute once compiled)
    python bench/bench_frame.py --repeats 15   # steadier medians on a busy machine
    python bench/bench_frame.py --quick        # smoke run: 1 repeat, t = 2 and 20 s; not a measurement
    python bench/bench_frame.py --replot       # reprint the tables, redraw frame.png from frame.json
    python bench/bench_frame.py --profile 20   # profile 20 one-thread frames -> results/frame_profile.txt

The scene is what `ig demo` draws (channel_worker/data/airfield_terrain.json: the airfield's
polygons on the bundled Jacksboro voxel terrain, haze, layered fog, a cloud layer); the channel
is the default rig's centre channel (services/rig/data/default_rig.toml: 1024 x 768, 60 x 45
degrees); the eyepoints are the bundled flight's (host_sim/flight.py) at t = 2, 8, 14, 20 s
(take-off roll, rotation, banked climbing turn, descent); the options are the demo's (rgss4,
box filter) as a worker renders them (colour only, into a reused buffer), with
RenderOptions(threads=1) and RenderOptions(threads=2). Each case's frame time is the median of
--repeats calls of render_frame after a warm-up; the one-thread and two-thread frames of an
eyepoint alternate, so that a busy moment of the machine falls on both alike. Per case it
keeps FrameReport.stage_seconds (the median of each stage) and the stages' counters.

Targets (issue 14): the whole frame at most 33 ms on one core (required), 16.7 ms (aim); the
speed-up on two threads at least 1.7 (required), 1.9 (aim).

Writes bench/results/frame.json (the record) and bench/results/frame.png (stacked stage bars
and the speed-up per stage; not checked in). With --profile N it only profiles: N one-thread
frames over the eyepoints, with pyinstrument if it is installed, else cProfile, into
bench/results/frame_profile.txt.
"""

from __future__ import annotations

import datetime as dt
import io
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

# Runnable from a plain checkout too (`python bench/bench_frame.py` puts bench/ first).
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, replot  # bench/ is on the path as a script

from services.rig.options import RenderOptions

#: Eyepoints of the bundled flight: take-off roll, rotation, banked climbing turn, descent.
TIMES_S = (2.0, 8.0, 14.0, 20.0)
QUICK_TIMES_S = (2.0, 20.0)
THREADS = (1, 2)
SAMPLES = "rgss4"
#: Targets of issue 14: whole frame (ms, one core) and two-thread speed-up.
FRAME_MS_REQUIRED, FRAME_MS_AIM = 33.0, 16.7
SPEEDUP_REQUIRED, SPEEDUP_AIM = 1.7, 1.9


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns the process exit status."""
    parser = bench_parser(__doc__, "frame", "default 7; --quick 1",
                          "1 repeat at t = 2 and 20 s: checks the bench runs; not a measurement")
    parser.add_argument("--profile", type=int, metavar="N", default=0,
                        help="only profile N one-thread frames (spread over the eyepoints) "
                             "into frame_profile.txt: pyinstrument if installed, else cProfile")
    args = parser.parse_args(argv)
    if replot(args, "frame", print_report, plot):
        return 0
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else 7)
    if repeats < 1 or args.profile < 0:
        parser.error("--repeats must be at least 1 and --profile N at least 0")

    from channel_worker.pipeline.jit import thread_pool_size

    if thread_pool_size() < max(THREADS):
        parser.error(f"numba was started with {thread_pool_size()} threads; this bench needs "
                     f"{max(THREADS)} (NUMBA_NUM_THREADS)")
    setup = load(args.quick)
    if args.profile:
        return profile(setup, args.profile, args.out, args.cpu)
    record = measure(setup, repeats, args.quick, args.cpu)
    finish(record, args.out, "frame", print_report, plot)
    return 0


# --- the scene, channel and eyepoints ---------------------------------------------------------

def load(quick: bool) -> dict[str, Any]:
    """The demo scene (its terrain built on first use), the centre channel, the eyepoints."""
    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from host_sim.flight import bundled_flight
    from services.rig.memory import keep_freed_memory
    from services.rig.rigfile import default_rig_path, load_rig

    keep_freed_memory()  # as a worker does before its first frame
    print("loading the demo scene (builds the bundled terrain on first use)", file=sys.stderr)
    scene = load_scene(demo_scene_path())
    channel = next(ch.spec for ch in load_rig(default_rig_path()).channels
                   if ch.spec.name == "centre")
    flight = bundled_flight()
    times = QUICK_TIMES_S if quick else TIMES_S
    return {"scene": scene, "scene_path": demo_scene_path(), "channel": channel,
            "eyes": [(t, flight.eyepoint_at(t), flight.phase_at(t)) for t in times]}


class _OneCore:
    """Pins the calling thread to one CPU (--cpu, default the lowest it may use) for the
    one-thread frames and lets it go again afterwards. Only the calling thread: numba's pool
    started unpinned, so the two-thread frames have both cores, and with threads=1 the calling
    thread runs every parallel loop itself (numba's omp and tbb layers; the record names the
    layer). Where the platform cannot pin, nothing is pinned."""

    def __init__(self, cpu: int | None) -> None:
        self.all = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
        self.cpu = cpu if cpu is not None or self.all is None else min(self.all)

    def __enter__(self) -> None:
        if self.cpu is not None:
            os.sched_setaffinity(0, {self.cpu})

    def __exit__(self, *exc: object) -> None:
        if self.cpu is not None and self.all is not None:
            os.sched_setaffinity(0, self.all)


class OtherLoad:
    """How many CPUs other processes kept busy while this one ran (Linux /proc/stat): the
    machine's busy time less this process's own CPU time, over the wall time. On a 2-CPU machine
    anything near 1 takes the second thread's core, and the two-thread figures then measure the
    machine, not the renderer (the load average lags by a minute and cannot tell)."""

    def __init__(self) -> None:
        self.start = self._sample()

    @staticmethod
    def _sample() -> tuple[float, float, float] | None:
        try:
            fields = Path("/proc/stat").read_text(encoding="utf-8").split("\n", 1)[0].split()[1:]
        except OSError:
            return None  # not Linux: unknown
        ticks = [int(v) for v in fields]
        busy = (sum(ticks[:8]) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")  # less idle, iowait
        own = os.times()
        return time.perf_counter(), busy, own.user + own.system

    def cpus(self) -> float | None:
        end = self._sample()
        if self.start is None or end is None or end[0] <= self.start[0]:
            return None
        return max(0.0, (end[1] - self.start[1]) - (end[2] - self.start[2])) / (end[0] - self.start[0])


def frame(setup: dict[str, Any], eye, threads: int, out: np.ndarray, report) -> float:
    """One render_frame as a worker calls it; its wall-clock seconds."""
    from channel_worker.pipeline.render import render_frame

    options = RenderOptions(samples=SAMPLES, with_range=False, threads=threads)
    report.clear()
    t0 = time.perf_counter()
    render_frame(setup["scene"], setup["channel"], eye, options, report=report, out=out)
    return time.perf_counter() - t0


# --- the measurement --------------------------------------------------------------------------

def measure(setup: dict[str, Any], repeats: int, quick: bool, cpu: int | None) -> dict[str, Any]:
    import numba
    from bench_render import machine
    from bench_terrain import git_state

    from services.rig.report import FrameReport

    channel = setup["channel"]
    out = np.empty((channel.height, channel.width, 3), np.float32)
    report = FrameReport()
    one_core = _OneCore(cpu)
    t_start = time.perf_counter()
    print("warm-up: numba compiles the kernels on the first frame (cached afterwards)",
          file=sys.stderr)
    for threads in THREADS:
        frame(setup, setup["eyes"][0][1], threads, out, report)
    rows = []
    for t_s, eye, phase in setup["eyes"]:
        walls: dict[int, list[float]] = {n: [] for n in THREADS}
        stages: dict[int, list[dict[str, float]]] = {n: [] for n in THREADS}
        parts: dict[int, list[dict[str, float]]] = {n: [] for n in THREADS}
        counters: dict[int, dict[str, int]] = {}
        other = OtherLoad()
        for k in range(repeats + 1):  # the first is this eyepoint's warm-up (pages are read)
            # Alternate which thread count goes first, so neither always follows the other.
            for threads in THREADS if k % 2 else THREADS[::-1]:
                if threads == 1:
                    with one_core:
                        wall = frame(setup, eye, threads, out, report)
                else:
                    wall = frame(setup, eye, threads, out, report)
                if k:
                    walls[threads].append(wall)
                    stages[threads].append(dict(report.stage_seconds))
                    parts[threads].append(dict(report.part_seconds))
                    counters[threads] = dict(report.counters)
        row: dict[str, Any] = {"t_s": t_s, "phase": phase, "other_cpus": other.cpus(),
                               "position_m": [float(v) for v in eye.position],
                               "hpr_deg": [eye.heading_deg, eye.pitch_deg, eye.roll_deg]}
        for n in THREADS:
            names = list(stages[n][0])
            row[f"threads_{n}"] = {
                "frame_ms": 1e3 * statistics.median(walls[n]), "frame_min_ms": 1e3 * min(walls[n]),
                "frame_ms_all": [1e3 * w for w in walls[n]],
                "stages_ms": {s: 1e3 * statistics.median(r[s] for r in stages[n]) for s in names},
                "parts_ms": {s: 1e3 * statistics.median(r.get(s, 0.0) for r in parts[n])
                             for s in parts[n][0]},
                "counters": counters[n]}
        row["speedup"] = row["threads_1"]["frame_ms"] / row["threads_2"]["frame_ms"]
        rows.append(row)
        busy = row["other_cpus"]
        print(f"t = {t_s:4.1f} s ({phase}): 1 thread {row['threads_1']['frame_ms']:6.1f} ms, "
              f"2 threads {row['threads_2']['frame_ms']:6.1f} ms, x {row['speedup']:.2f}"
              + (f"; other processes kept {busy:.2f} CPUs busy" if busy is not None else ""),
              file=sys.stderr)
    scene = setup["scene"]
    return {
        "benchmark": "render_frame of the demo scene, one channel, on 1 and 2 threads",
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": {**machine(), "threading_layer": numba.threading_layer(),
                    "affinity": sorted(one_core.all) if one_core.all is not None else None},
        "git": git_state(),
        "scene": {"file": str(Path(setup["scene_path"]).relative_to(REPO))
                  if Path(setup["scene_path"]).is_relative_to(REPO) else str(setup["scene_path"]),
                  "features": scene.feature_count,
                  "instances": int(scene.instance_model.shape[0]),
                  "terrain_voxels": [int(scene.terrain.nx), int(scene.terrain.ny)]
                  if scene.terrain is not None else None,
                  "haze": scene.haze is not None, "fog": scene.fog is not None,
                  "clouds": scene.clouds is not None},
        "channel": {"name": channel.name, "width": channel.width, "height": channel.height,
                    "frustum_deg": [channel.left_deg, channel.right_deg, channel.bottom_deg,
                                    channel.top_deg], "yaw_deg": channel.yaw_deg},
        "render_options": RenderOptions(samples=SAMPLES, with_range=False).to_mapping()
        | {"threads": list(THREADS)},
        "one_thread_cpu": one_core.cpu,
        "quick": quick, "repeats": repeats,
        "statistic": "per eyepoint and thread count: the median of the repeats' wall-clock frame "
                     "times (render_frame) and of each stage's FrameReport.stage_seconds, after "
                     "one warm-up frame; one- and two-thread frames alternate; speed-up = "
                     "1-thread median / 2-thread median; other_cpus: CPUs other processes "
                     "kept busy during the eyepoint's frames (/proc/stat busy time less this "
                     "process's CPU time, over the wall time; null where unknown)",
        "rows": rows,
        "summary": summarise(rows),
        "seconds": time.perf_counter() - t_start,
    }


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Worst and median frame per thread count, the speed-ups, each stage's speed-up (its
    summed medians over the eyepoints), and the targets' verdicts."""
    worst = {n: max(r[f"threads_{n}"]["frame_ms"] for r in rows) for n in THREADS}
    median = {n: statistics.median(r[f"threads_{n}"]["frame_ms"] for r in rows) for n in THREADS}
    total = {n: sum(r[f"threads_{n}"]["frame_ms"] for r in rows) for n in THREADS}
    stages = list(rows[0]["threads_1"]["stages_ms"])
    stage_speedup = {}
    for s in stages:
        one = sum(r["threads_1"]["stages_ms"].get(s, 0.0) for r in rows)
        two = sum(r["threads_2"]["stages_ms"].get(s, 0.0) for r in rows)
        stage_speedup[s] = one / two if two > 0.0 else None
    for s in rows[0]["threads_1"].get("parts_ms", {}):
        one = sum(r["threads_1"]["parts_ms"].get(s, 0.0) for r in rows)
        two = sum(r["threads_2"]["parts_ms"].get(s, 0.0) for r in rows)
        stage_speedup[s] = one / two if two > 0.0 else None
    speedup = total[1] / total[2]
    return {
        "worst_frame_ms": {str(n): worst[n] for n in THREADS},
        "median_frame_ms": {str(n): median[n] for n in THREADS},
        "speedup_overall": speedup, "speedup_min": min(r["speedup"] for r in rows),
        "speedup_by_stage": stage_speedup,
        "other_cpus_max": max((r["other_cpus"] for r in rows if r.get("other_cpus") is not None),
                              default=None),
        "targets": {
            "frame_one_core": {"what": "the slowest eyepoint's frame on one thread, ms",
                               "required": FRAME_MS_REQUIRED, "aim": FRAME_MS_AIM,
                               "measured": worst[1], "met": worst[1] <= FRAME_MS_REQUIRED,
                               "aim_met": worst[1] <= FRAME_MS_AIM},
            "speedup_two_threads": {"what": "sum of the eyepoints' 1-thread medians over the "
                                            "sum of their 2-thread medians",
                                    "required": SPEEDUP_REQUIRED, "aim": SPEEDUP_AIM,
                                    "measured": speedup, "met": speedup >= SPEEDUP_REQUIRED,
                                    "aim_met": speedup >= SPEEDUP_AIM}},
    }


# --- the profile ------------------------------------------------------------------------------

def profile(setup: dict[str, Any], frames: int, out_dir: Path, cpu: int | None) -> int:
    """Profile `frames` one-thread frames over the eyepoints (after a warm-up) into
    frame_profile.txt and print its top."""
    from services.rig.report import FrameReport

    channel = setup["channel"]
    out = np.empty((channel.height, channel.width, 3), np.float32)
    report = FrameReport()
    eyes = [eye for _, eye, _ in setup["eyes"]]
    for eye in eyes:  # warm-up: compiling is not what is profiled
        frame(setup, eye, 1, out, report)

    def run() -> None:
        with _OneCore(cpu):
            for k in range(frames):
                frame(setup, eyes[k % len(eyes)], 1, out, report)

    try:
        import pyinstrument
    except ImportError:
        pyinstrument = None
    t0 = time.perf_counter()
    if pyinstrument is not None:
        tool = f"pyinstrument {pyinstrument.__version__}"
        profiler = pyinstrument.Profiler(interval=0.0005)
        profiler.start()
        run()
        profiler.stop()
        text = profiler.output_text(unicode=False, color=False, show_all=False)
    else:
        import cProfile
        import pstats

        tool = "cProfile (pyinstrument is not installed)"
        prof = cProfile.Profile()
        prof.runcall(run)
        stream = io.StringIO()
        stats = pstats.Stats(prof, stream=stream)
        stats.sort_stats("tottime").print_stats(30)
        stats.sort_stats("cumulative").print_stats(40)
        text = stream.getvalue().replace(str(REPO) + os.sep, "")
    seconds = time.perf_counter() - t0
    times = ", ".join(f"{t:g}" for t, _, _ in setup["eyes"])
    head = (f"# {frames} frames of the demo scene, {channel.name} channel {channel.width} x "
            f"{channel.height}, {SAMPLES}, threads=1, eyepoints of the bundled flight at t = "
            f"{times} s in turn; {seconds:.1f} s in all under {tool}\n"
            "# numba reports each call of a compiled kernel to the profiler, so a kernel shows "
            "by its name (its own time is the kernel's), but nothing inside it does.\n\n")
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "frame_profile.txt"
    path.write_text(head + text, encoding="utf-8")
    print(head + "\n".join(text.splitlines()[:60]))
    print(f"wrote {path}")
    return 0


# --- report -----------------------------------------------------------------------------------

def table(head: list[str], body: list[list[str]]) -> None:
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
    for b in body:
        print("  ".join(c.rjust(w) for c, w in zip(b, widths, strict=True)))


def print_report(record: dict[str, Any]) -> None:
    """Frame times per eyepoint and thread count, the stages, the targets."""
    rows, summary, ch = record["rows"], record["summary"], record["channel"]
    print(f"\nwhole frame of the demo scene ({record['scene']['file']}), {ch['name']} channel "
          f"{ch['width']} x {ch['height']}, {record['render_options']['samples']}, median ms "
          f"over {record['repeats']} repeats")
    table(["t s", "phase", "1 thread", "2 threads", "speed-up", "other CPUs"],
          [[f"{r['t_s']:g}", r["phase"], f"{r['threads_1']['frame_ms']:.1f}",
            f"{r['threads_2']['frame_ms']:.1f}", f"{r['speedup']:.2f}",
            f"{r['other_cpus']:.2f}" if r.get("other_cpus") is not None else "-"]
           for r in rows])
    print("(other CPUs: how many CPUs other processes kept busy meanwhile, from /proc/stat; near "
          "1 on a 2-CPU machine they took the second thread's core and the 2-thread figures "
          "measure the machine, not the renderer)")

    stages = list(rows[0]["threads_1"]["stages_ms"])
    print("\nper stage (FrameReport.stage_seconds), median ms; speed-up = the stage's summed "
          "1-thread medians over its 2-thread ones")
    head = ["stage"] + [f"{r['t_s']:g}s {n}T" for r in rows for n in THREADS] + ["speed-up"]
    body = []
    for s in stages:
        sp = summary["speedup_by_stage"].get(s)
        body.append([s] + [f"{r[f'threads_{n}']['stages_ms'].get(s, 0.0):.2f}"
                           for r in rows for n in THREADS]
                    + [f"{sp:.2f}" if sp is not None else "-"])
        # The stage's parts (FrameReport.part_seconds, e.g. background.cast) under it.
        for part in rows[0]["threads_1"].get("parts_ms", {}):
            if part.startswith(s + "."):
                sp = summary["speedup_by_stage"].get(part)
                body.append([part[len(s):]] + [
                    f"{r[f'threads_{n}'].get('parts_ms', {}).get(part, 0.0):.2f}"
                    for r in rows for n in THREADS] + [f"{sp:.2f}" if sp is not None else "-"])
    body.append(["frame"] + [f"{r[f'threads_{n}']['frame_ms']:.2f}" for r in rows for n in THREADS]
                + [f"{summary['speedup_overall']:.2f}"])
    table(head, body)

    tg = summary["targets"]
    f, s = tg["frame_one_core"], tg["speedup_two_threads"]

    def verdict(t: dict[str, Any]) -> str:
        return "aim met" if t["aim_met"] else ("required met" if t["met"] else "NOT MET")

    print(f"\ntargets (issue 14): whole frame on one core <= {f['required']:g} ms required, "
          f"{f['aim']:g} aim: slowest eyepoint {f['measured']:.1f} ms -> {verdict(f)}")
    print(f"                    2-thread speed-up >= {s['required']:g} required, {s['aim']:g} aim: "
          f"{s['measured']:.2f} (lowest eyepoint {summary['speedup_min']:.2f}) -> {verdict(s)}")
    m = record["machine"]
    print(f"machine: {m['cpu']}, {m['logical_cpus']} logical CPUs, numba {m['numba']} "
          f"({m['threading_layer']}); load average {m['load_average_1min']:.2f} at the start, "
          f"{m.get('load_average_1min_at_end', float('nan')):.2f} at the end")


def plot(record: dict[str, Any], path: Path) -> bool:
    """Stacked stage bars per eyepoint and thread count with the frame targets; the speed-up
    per stage and per eyepoint with the speed-up targets. False without matplotlib."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt

    rows, summary = record["rows"], record["summary"]
    stages = list(rows[0]["threads_1"]["stages_ms"])
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13.0, 5.0), gridspec_kw={"width_ratios": [3, 2]})
    colours = plt.get_cmap("tab20")
    labels = [f"{r['t_s']:g} s\n{n} thr" for r in rows for n in THREADS]
    x = np.arange(len(labels), dtype=np.float64) + np.repeat(np.arange(len(rows)) * 0.5,
                                                             len(THREADS))
    bottom = np.zeros(len(labels))
    for k, s in enumerate(stages):
        ms = np.array([r[f"threads_{n}"]["stages_ms"].get(s, 0.0) for r in rows for n in THREADS])
        ax.bar(x, ms, bottom=bottom, label=s, color=colours(k % 20))
        bottom += ms
    ax.plot(x, [r[f"threads_{n}"]["frame_ms"] for r in rows for n in THREADS], "k_", ms=14,
            label="frame (wall)")
    ax.axhline(FRAME_MS_REQUIRED, color="tab:red", ls="--", lw=1,
               label=f"{FRAME_MS_REQUIRED:g} ms required")
    ax.axhline(FRAME_MS_AIM, color="tab:green", ls="--", lw=1, label=f"{FRAME_MS_AIM:g} ms aim")
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_ylabel("median ms per frame")
    ch = record["channel"]
    ax.set_title(f"demo scene, {ch['name']} channel {ch['width']} x {ch['height']}, "
                 f"{record['render_options']['samples']}: stages per eyepoint and thread count",
                 fontsize=9)
    ax.legend(fontsize=6, ncol=2)

    sp = {s: v for s, v in summary["speedup_by_stage"].items() if v is not None}
    names = list(sp) + ["frame"] + [f"t={r['t_s']:g} s" for r in rows]
    values = list(sp.values()) + [summary["speedup_overall"]] + [r["speedup"] for r in rows]
    colour = ["tab:blue"] * len(sp) + ["k"] + ["tab:gray"] * len(rows)
    ax2.barh(np.arange(len(names)), values, color=colour)
    ax2.set_yticks(np.arange(len(names)), names, fontsize=7)
    ax2.invert_yaxis()
    ax2.axvline(1.0, color="k", lw=0.5)
    ax2.axvline(SPEEDUP_REQUIRED, color="tab:red", ls="--", lw=1,
                label=f"{SPEEDUP_REQUIRED:g} required")
    ax2.axvline(SPEEDUP_AIM, color="tab:green", ls="--", lw=1, label=f"{SPEEDUP_AIM:g} aim")
    ax2.set_xlim(0.0, max(2.0, *values) * 1.05)
    ax2.set_xlabel("speed-up, 2 threads over 1")
    ax2.set_title("speed-up: per stage (summed over the eyepoints),\nwhole frame, per eyepoint",
                  fontsize=9)
    ax2.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)  # below
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


if __name__ == "__main__":
    raise SystemExit(main())
