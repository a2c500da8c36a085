"""Per-stage frame time of the channel pipeline rendering the bundled airfield (bench/README.md).

    python bench/bench_render.py                 # what `make bench` runs
    python bench/bench_render.py --repeats 15
    python bench/bench_render.py --quick         # smoke run: 2 repeats, t = 2 and 14 s

For every channel of the default rig (left, centre, right: 60 x 45 degrees each), raster size
(1024 x 768, the rig's own, and 1280 x 1024), sample count (1, 4) and eyepoint of the bundled
flight (t = 2, 8, 14, 20 s), it times

    render_frame(database, channel, eyepoint, RenderOptions(samples=N), report=FrameReport())

after a warm-up render of each size and sample count (numba compiles its kernels on the first
call). Each stage's time is the median over the repeats. It prints a table, writes
bench/results/render.json (the record: machine, versions, date, every case) and the figure
bench/results/render_stages.png (stacked bars per stage; not checked in).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

# Runnable from a plain checkout too (`python bench/bench_render.py` puts bench/ first on the path).
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
from host_sim.flight import bundled_flight
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions
from services.rig.report import FrameReport
from services.rig.rigfile import default_rig_path, load_rig

RESULTS = Path(__file__).resolve().parent / "results"
SIZES = ((1024, 768), (1280, 1024))
SAMPLES = (1, 4)
#: Eyepoints: take-off roll, rotation, banked climbing turn, descent.
TIMES_S = (2.0, 8.0, 14.0, 20.0)
QUICK_TIMES_S = (2.0, 14.0)
QUICK_REPEATS = 2


def measure(database: Database, channel: ChannelSpec, eyepoint: Eyepoint, samples: int,
            repeats: int) -> tuple[dict[str, float], float, FrameReport]:
    """Median seconds per stage, the median frame total, and the median frame's report, over `repeats` renders."""
    runs = []
    # As the rig's workers render: colour only (no ranges), into one reused array.
    out = np.empty((channel.height, channel.width, 3), np.float32)
    for _ in range(repeats):
        report = FrameReport()
        render_frame(database, channel, eyepoint, RenderOptions(samples=samples, with_range=False),
                     report=report, out=out)
        runs.append(report)
    stages = {stage: statistics.median(r.stage_seconds[stage] for r in runs)
              for stage in runs[0].stage_seconds}
    by_total = sorted(runs, key=lambda r: r.total_seconds)
    return stages, statistics.median(r.total_seconds for r in runs), by_total[len(by_total) // 2]


def machine() -> dict[str, Any]:
    """What the numbers were measured on."""
    import numba

    return {
        "cpu": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "numba_threading_layer": str(numba.config.THREADING_LAYER),
        "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
    }


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass  # not Linux: fall back to what platform knows
    return platform.processor() or platform.machine()


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per size and sample count: the median and the worst frame over every channel and eyepoint.

    The worst channel sets the rate a frame-locked rig can hold.
    """
    out = []
    for (width, height) in SIZES:
        for samples in SAMPLES:
            cases = [r for r in rows
                     if (r["width"], r["height"], r["samples"]) == (width, height, samples)]
            if not cases:
                continue
            worst = max(cases, key=lambda r: r["total_ms"])
            out.append({"width": width, "height": height, "samples": samples,
                        "median_ms": statistics.median(r["total_ms"] for r in cases),
                        "worst_ms": worst["total_ms"],
                        "worst_case": f"{worst['channel']} t={worst['t_s']:g} s",
                        "fps_at_worst": 1e3 / worst["total_ms"]})
    return out


def print_table(rows: list[dict[str, Any]], summary: list[dict[str, Any]],
                stages: list[str]) -> None:
    """Stage columns in milliseconds, then the total and fps, one line per case."""
    head = ["size", "spp", "t s", "channel"] + stages + ["total", "fps"]
    body = [[f"{r['width']}x{r['height']}", str(r["samples"]), f"{r['t_s']:g}", r["channel"]]
            + [f"{r['stages_ms'][s]:.2f}" for s in stages]
            + [f"{r['total_ms']:.2f}", f"{1e3 / r['total_ms']:.1f}"] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    print("median milliseconds per stage")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
    for b in body:
        print("  ".join(c.rjust(w) for c, w in zip(b, widths, strict=True)))
    print()
    print("per size and sample count, over every channel and eyepoint")
    for s in summary:
        print(f"  {s['width']}x{s['height']} {s['samples']} spp: median {s['median_ms']:.2f} ms, "
              f"worst {s['worst_ms']:.2f} ms ({s['worst_case']}) = {s['fps_at_worst']:.1f} fps")


def plot(rows: list[dict[str, Any]], stages: list[str], path: Path) -> bool:
    """One panel per size and sample count, a stacked bar per eyepoint and channel.

    Returns False (and draws nothing) when matplotlib is not installed: the JSON is the record.
    """
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt

    panels = [(w, h, s) for (w, h) in SIZES for s in SAMPLES
              if any((r["width"], r["height"], r["samples"]) == (w, h, s) for r in rows)]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.6), sharey=True,
                             squeeze=False)
    colours = plt.get_cmap("tab10")
    for ax, (w, h, s) in zip(axes[0], panels, strict=True):
        cases = [r for r in rows if (r["width"], r["height"], r["samples"]) == (w, h, s)]
        labels = [f"{r['t_s']:g} s\n{r['channel']}" for r in cases]
        bottom = np.zeros(len(cases))
        for k, stage in enumerate(stages):
            ms = np.array([r["stages_ms"][stage] for r in cases])
            ax.bar(labels, ms, bottom=bottom, label=stage, color=colours(k % 10))
            bottom += ms
        ax.set_title(f"{w} x {h}, {s} sample{'s' if s > 1 else ''}", fontsize=9)
        ax.tick_params(axis="x", labelsize=6)
    axes[0][0].set_ylabel("median time per frame, ms")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles[::-1], labels[::-1], fontsize=7, loc="center right")  # top stage first
    fig.suptitle("render_frame per stage: bundled airfield along the bundled flight, one channel",
                 fontsize=10)
    fig.tight_layout(rect=(0.0, 0.0, 0.93, 1.0))  # leave the right margin to the legend
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns the process exit status."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=None,
                        help="timed renders per case; the median is kept (default 7, --quick 2)")
    parser.add_argument("--quick", action="store_true",
                        help=f"{QUICK_REPEATS} repeats at t = 2 and 14 s: checks the bench runs; "
                             "not a measurement")
    parser.add_argument("--out", type=Path, default=RESULTS,
                        help=f"results folder (default {RESULTS})")
    args = parser.parse_args(argv)
    repeats = args.repeats if args.repeats is not None else (QUICK_REPEATS if args.quick else 7)
    if repeats < 1:
        parser.error("--repeats must be at least 1")
    times_s = QUICK_TIMES_S if args.quick else TIMES_S

    database = load_scene(bundled_scene_path())
    rig = load_rig(default_rig_path())
    flight = bundled_flight()

    # Warm-up: compile every numba kernel and fault in the buffers of each size and sample count.
    for width, height in SIZES:
        for samples in SAMPLES:
            render_frame(database, rig.with_size(width, height).channels[1].spec,
                         flight.eyepoint_at(times_s[0]), RenderOptions(samples=samples))

    rows: list[dict[str, Any]] = []
    stages: list[str] = []
    for width, height in SIZES:
        channels = [ch.spec for ch in rig.with_size(width, height).channels]
        for samples in SAMPLES:
            for t_s in times_s:
                eyepoint = flight.eyepoint_at(t_s)
                for channel in channels:
                    med, total, frame = measure(database, channel, eyepoint, samples, repeats)
                    stages = stages or list(med)
                    rows.append({"width": width, "height": height, "samples": samples, "t_s": t_s,
                                 "phase": flight.phase_at(t_s), "channel": channel.name,
                                 "stages_ms": {s: 1e3 * v for s, v in med.items()},
                                 "total_ms": 1e3 * total, "frame_report": frame.to_dict()})
            print(f"  measured {width}x{height}, {samples} spp", file=sys.stderr)

    summary = summarise(rows)
    print_table(rows, summary, stages)
    args.out.mkdir(parents=True, exist_ok=True)
    report = {
        "benchmark": "channel_worker.pipeline.render.render_frame, per stage",
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "scene": {"file": bundled_scene_path().name, "features": database.feature_count,
                  "instances": int(database.instance_model.shape[0])},
        "rig": {"source": default_rig_path().name,
                "channels": {ch.name: {"yaw_deg": ch.spec.yaw_deg,
                                       "frustum_deg": [ch.spec.left_deg, ch.spec.right_deg,
                                                       ch.spec.bottom_deg, ch.spec.top_deg]}
                             for ch in rig.channels}},
        "quick": args.quick,
        "repeats": repeats,
        "statistic": "median over repeats; total is the median of per-frame totals",
        "stages": stages,
        "results": rows,
        "summary": summary,
    }
    json_path = args.out / "render.json"
    json_path.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    png_path = args.out / "render_stages.png"
    if plot(rows, stages, png_path):
        print(f"wrote {json_path} and {png_path}")
    else:
        print(f"wrote {json_path} (no figure: matplotlib is not installed; "
              "pip install -e '.[bench]')")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
