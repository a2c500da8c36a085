"""What the benches share: their command line (--repeats, --quick, --cpu, --out, --replot), the
replot short cut (redraw the figure and reprint the tables from the checked-in JSON), and
pinning the process to one CPU."""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Callable
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def bench_parser(doc: str, name: str, repeats_help: str, quick_help: str) -> argparse.ArgumentParser:
    """The parser of bench_NAME.py, whose results are results/NAME.json and NAME.png."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=None,
                        help="timed calls per case after one warm-up; the median is kept "
                             f"({repeats_help})")
    parser.add_argument("--quick", action="store_true", help=quick_help)
    parser.add_argument("--cpu", type=int, default=None,
                        help="the CPU to run on (default: the lowest this process may use)")
    parser.add_argument("--out", type=Path, default=RESULTS,
                        help=f"results folder (default {RESULTS})")
    parser.add_argument("--replot", action="store_true",
                        help=f"only redraw {name}.png (and reprint the tables) from {name}.json")
    return parser


def finish(record: dict, out: Path, name: str, print_report: Callable[[dict], None],
           plot: Callable[[dict, Path], bool]) -> None:
    """Note the load at the end, print the report, write out/NAME.json and the figure."""
    record["machine"]["load_average_1min_at_end"] = (os.getloadavg()[0]
                                                     if hasattr(os, "getloadavg") else None)
    print_report(record)
    out.mkdir(parents=True, exist_ok=True)
    json_path = out / f"{name}.json"
    json_path.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    written = [json_path]
    fig = out / f"{name}.png"
    if plot(record, fig):
        written.append(fig)
    print("wrote " + ", ".join(str(p) for p in written))


def replot(args: argparse.Namespace, name: str, print_report: Callable[[dict], None],
           plot: Callable[[dict, Path], bool]) -> bool:
    """With --replot: reprint and redraw from the saved record, and say so (True)."""
    if not args.replot:
        return False
    record = json.loads((args.out / f"{name}.json").read_text(encoding="utf-8"))
    print_report(record)
    plot(record, args.out / f"{name}.png")
    return True


def pin_to_one_cpu(cpu: int | None) -> int | None:
    """Pin this process to one CPU (default: the lowest it may use) before any worker thread
    starts, so numba's pool and everything else share that core. Returns the CPU, or None where
    the platform cannot pin."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    cpu = min(os.sched_getaffinity(0)) if cpu is None else cpu
    os.sched_setaffinity(0, {cpu})
    return cpu
