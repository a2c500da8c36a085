"""How one channel's frame scales with threads: the bundled demo scene, the default rig's centre
channel (1024 x 768, 4 samples, as a worker renders it), 1, 2, 4, ... threads up to the cores
this process may use.

    python bench/bench_threads.py            # results/threads.json and threads.png
    python bench/bench_threads.py --quick    # two eyepoints, three repeats
    python bench/bench_threads.py --replot   # redraw and reprint from results/threads.json

The pool is sized to every usable core before numba starts (services/rig/threads.py), and each
frame runs with RenderOptions(threads=N), as a worker with `[render] threads = N` does. Every
eyepoint is rendered at every thread count in turn (alternating the order between repeats),
--repeats times; a case's figure is the median. The speed-up at N threads is the sum of the
eyepoints' one-thread medians over the sum of their N-thread medians, for the frame and for
each stage; a stage's share is its median over the frame's at the most threads.

Targets (issue 29): 16 threads over 1 at least 10x (aim 13x) on a 16-core machine; no serial
stage above 2 % of the frame at 16 threads. On a machine with fewer cores the bench measures
what it can and says that the 16-thread rows were not measured.
"""

from __future__ import annotations

import datetime as dt
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, replot  # bench/ is on the path as a script

from services.rig.threads import size_thread_pool, usable_cores

#: Eyepoints of the bundled flight: take-off roll, rotation, banked climbing turn, descent.
TIMES_S = (2.0, 8.0, 14.0, 20.0)
QUICK_TIMES_S = (2.0, 14.0)
SAMPLES = "rgss4"
#: Targets of issue 29.
SPEEDUP_THREADS = 16
SPEEDUP_REQUIRED, SPEEDUP_AIM = 10.0, 13.0
SERIAL_SHARE_MAX = 0.02
#: Stages that run on one thread whatever the count (render.py): each must stay under
#: SERIAL_SHARE_MAX of the frame at the most threads.
SERIAL_STAGES = ("view", "cull", "transform", "backface", "clip", "project", "edges", "binning")


def thread_counts(cores: int) -> list[int]:
    """1, 2, 4, ... up to cores, and cores itself."""
    counts, n = [], 1
    while n < cores:
        counts.append(n)
        n *= 2
    counts.append(cores)
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = bench_parser(__doc__ or "", "threads", "default 5, 3 with --quick",
                          "two eyepoints, three repeats")
    args = parser.parse_args(argv)
    if replot(args, "threads", print_report, plot):
        return 0
    pool = size_thread_pool(0)  # before numba is imported: every usable core
    repeats = args.repeats or (3 if args.quick else 5)
    from bench_frame import load

    setup = load(quick=True)
    from host_sim.flight import bundled_flight

    flight = bundled_flight()
    setup["eyes"] = [(t, flight.eyepoint_at(t), flight.phase_at(t)) for t in (QUICK_TIMES_S if args.quick
                                                                               else TIMES_S)]
    record = measure(setup, repeats, pool, args.quick)
    finish(record, args.out, "threads", print_report, plot)
    return 0


def measure(setup: dict[str, Any], repeats: int, pool: int, quick: bool) -> dict[str, Any]:
    import numba
    from bench_render import machine
    from bench_terrain import git_state

    from channel_worker.pipeline.render import render_frame
    from services.rig.options import RenderOptions
    from services.rig.report import FrameReport

    channel = setup["channel"]
    out = np.empty((channel.height, channel.width, 3), np.float32)
    counts = thread_counts(pool)
    report = FrameReport()

    def one(eye, threads: int) -> tuple[float, dict[str, float], dict[str, float]]:
        options = RenderOptions(samples=SAMPLES, threads=threads)
        report.clear()
        t0 = time.perf_counter()
        render_frame(setup["scene"], channel, eye, options, report=report, out=out)
        return time.perf_counter() - t0, dict(report.stage_seconds), dict(report.part_seconds)

    print("warm-up: numba compiles the kernels on the first frame (cached afterwards)", file=sys.stderr)
    t_start = time.perf_counter()
    for _t, eye, _phase in setup["eyes"]:
        for n in counts:
            one(eye, n)
    rows = []
    for t, eye, phase in setup["eyes"]:
        walls: dict[int, list[float]] = {n: [] for n in counts}
        stages: dict[int, list[dict[str, float]]] = {n: [] for n in counts}
        for k in range(repeats):
            for n in counts if k % 2 else counts[::-1]:
                wall, st, parts = one(eye, n)
                walls[n].append(wall)
                stages[n].append({**st, **parts})
        row: dict[str, Any] = {"time_s": t, "phase": phase}
        for n in counts:
            names = stages[n][0].keys()
            row[f"threads_{n}"] = {
                "frame_ms": statistics.median(walls[n]) * 1e3,
                "frame_ms_all": [w * 1e3 for w in walls[n]],
                "stages_ms": {s: statistics.median(d.get(s, 0.0) for d in stages[n]) * 1e3 for s in names},
            }
        rows.append(row)
        print(f"  t = {t:4.1f} s: " + ", ".join(f"{n} threads {row[f'threads_{n}']['frame_ms']:.1f} ms"
                                               for n in counts), file=sys.stderr)
    record = {
        "benchmark": "bench_threads.py",
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": {**machine(), "usable_cores": usable_cores(), "pool": pool,
                    "threading_layer": numba.threading_layer()},
        "git": git_state(),
        "channel": {"name": channel.name, "width": channel.width, "height": channel.height},
        "samples": SAMPLES, "quick": quick, "repeats": repeats, "statistic": "median",
        "thread_counts": counts, "rows": rows,
        "seconds": time.perf_counter() - t_start,
    }
    record["summary"] = summarise(rows, counts)
    return record


def summarise(rows: list[dict[str, Any]], counts: list[int]) -> dict[str, Any]:
    """Speed-ups over one thread (frame and stages), stage shares at the most threads, verdicts."""
    def total(n: int, stage: str | None = None) -> float:
        if stage is None:
            return sum(r[f"threads_{n}"]["frame_ms"] for r in rows)
        return sum(r[f"threads_{n}"]["stages_ms"].get(stage, 0.0) for r in rows)

    top = counts[-1]
    stages = list(rows[0][f"threads_{top}"]["stages_ms"])
    speedup = {str(n): total(1) / total(n) for n in counts}
    by_stage = {s: {str(n): (total(1, s) / total(n, s) if total(n, s) > 0 else None) for n in counts}
                for s in stages}
    share = {s: total(top, s) / total(top) for s in stages}
    serial = {s: share.get(s, 0.0) for s in SERIAL_STAGES}
    measured_16 = top >= SPEEDUP_THREADS
    return {
        "frame_ms": {str(n): total(n) / len(rows) for n in counts},
        "speedup": speedup, "speedup_by_stage": by_stage, "share_at_most_threads": share,
        "targets": {
            "speedup_16": {"what": f"{SPEEDUP_THREADS} threads over 1, whole frame",
                           "required": SPEEDUP_REQUIRED, "aim": SPEEDUP_AIM,
                           "measured": speedup.get(str(SPEEDUP_THREADS)) if measured_16 else None,
                           "met": (speedup[str(SPEEDUP_THREADS)] >= SPEEDUP_REQUIRED) if measured_16 else None,
                           "note": None if measured_16 else f"not measured: {top} usable cores"},
            "serial_stages": {"what": f"each serial stage's share of the frame at {top} threads",
                              "required": SERIAL_SHARE_MAX, "measured": serial,
                              "over": [s for s, v in serial.items() if v > SERIAL_SHARE_MAX],
                              "met": all(v <= SERIAL_SHARE_MAX for v in serial.values()) if measured_16
                              else None},
        },
    }


def print_report(record: dict[str, Any]) -> None:
    m = record["machine"]
    s = record["summary"]
    counts = record["thread_counts"]
    print(f"\n{record['channel']['width']} x {record['channel']['height']}, {record['samples']}, "
          f"{m['cpu']}, {m['usable_cores']} usable cores, threading layer {m['threading_layer']}")
    print(f"{'threads':>8} {'frame ms':>9} {'speed-up':>9}")
    for n in counts:
        print(f"{n:>8} {s['frame_ms'][str(n)]:9.1f} {s['speedup'][str(n)]:9.2f}")
    top = counts[-1]
    print(f"\n{'stage':>18} {'1 thread ms':>12} {f'{top} threads ms':>14} {'speed-up':>9} {'share':>7}")
    rows = record["rows"]
    for stage, share in s["share_at_most_threads"].items():
        one = sum(r["threads_1"]["stages_ms"].get(stage, 0.0) for r in rows) / len(rows)
        many = sum(r[f"threads_{top}"]["stages_ms"].get(stage, 0.0) for r in rows) / len(rows)
        up = s["speedup_by_stage"][stage][str(top)]
        print(f"{stage:>18} {one:12.2f} {many:14.2f} {up if up is not None else float('nan'):9.2f} {share:7.1%}")
    for name, t in s["targets"].items():
        print(f"target {name}: {t['what']}: measured {t['measured']}, required {t['required']}, met {t['met']}"
              + (f" ({t['note']})" if t.get("note") else ""))


def plot(record: dict[str, Any], path: Path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    counts = record["thread_counts"]
    s = record["summary"]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(counts, [s["speedup"][str(n)] for n in counts], "o-", label="frame")
    for stage in ("background", "visibility"):
        if stage in s["speedup_by_stage"]:
            ax.plot(counts, [s["speedup_by_stage"][stage][str(n)] or 0 for n in counts], ".--", label=stage)
    ax.plot(counts, counts, ":", color="grey", label="linear")
    ax.set_xlabel("threads")
    ax.set_ylabel("speed-up over one thread")
    ax.set_title(f"{record['channel']['width']} x {record['channel']['height']} x 4, {record['machine']['cpu']}",
                 fontsize=8)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True


if __name__ == "__main__":
    sys.exit(main())
