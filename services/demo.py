"""`ig demo`: the whole rig as separate processes on this machine, on the bundled flight.

The default rate was chosen by measurement: on the 2-core development machine the default rig
(three 1024 x 768 channels, 4 samples) renders about 2 frames a second, frame-locked, so
20 simulated seconds at 15 Hz (301 frames) take about two and a half minutes.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import IO

import grpc

from ig.v1 import compositor_pb2, compositor_pb2_grpc
from services.rig.cli_common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    error,
    load_rig_or_report,
    non_negative,
    pixels,
    positive,
)
from services.rig.grpc_util import RPC_DEADLINE_S, make_channel
from services.rig.rigfile import Rig, rig_toml

#: Exit code after Ctrl-C (128 + SIGINT), as shells report it.
EXIT_INTERRUPTED = 130


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig demo`."""
    parser.add_argument("--rate", type=positive, default=15.0,
                        help="host frame rate, Hz (default 15: the run is frame-locked, so a rate above what "
                             "the machine renders only slows the simulation)")
    parser.add_argument("--duration", type=non_negative, default=20.0,
                        help="simulated seconds of the bundled flight to fly (default 20)")
    parser.add_argument("--width", type=pixels, default=None, help="override every channel's width, pixels")
    parser.add_argument("--height", type=pixels, default=None, help="override every channel's height, pixels")
    parser.add_argument("--samples", default="4", help="samples per pixel, a count or a pattern name (default 4)")
    parser.add_argument("--filter", default="box",
                        help="pixel reconstruction filter: box, tent, gaussian (default box)")
    parser.add_argument("--exr-every", type=int, default=30,
                        help="also write a linear EXR every N frames (default 30; 0: never)")
    parser.add_argument("--out", default="out/demo",
                        help="output directory: frames/, report.json, rig.toml, logs/ (default out/demo)")
    parser.add_argument("--scene", default=None,
                        help="scene JSON (default: the bundled airfield on the bundled terrain, "
                             "with haze and clouds)")
    parser.add_argument("--rig", default=None,
                        help="rig file (default: the bundled three-channel rig); its addresses are replaced "
                             "by free ports on 127.0.0.1")
    parser.add_argument("--verbose", action="store_true", help="show the processes' logs instead of writing "
                                                               "them to OUT/logs")


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def local_rig(rig: Rig) -> Rig:
    """The rig with every service on a free 127.0.0.1 port, so a demo never collides with a rig
    already running on the fixed ports."""
    chans = tuple(replace(ch, address=f"127.0.0.1:{free_port()}") for ch in rig.channels)
    return replace(rig, host_address=f"127.0.0.1:{free_port()}",
                   compositor_address=f"127.0.0.1:{free_port()}", channels=chans)


class Processes:
    """The processes a demo started; stop_all stops every one of them, whatever happened.

    Each child runs in its own session (process group): Ctrl-C in the terminal reaches the demo
    only, which then stops the children in order (SIGTERM, then SIGKILL after a timeout)
    instead of having them all die at once mid-frame.
    """

    def __init__(self, log_dir: Path, verbose: bool) -> None:
        self.log_dir = log_dir
        self.verbose = verbose
        self.procs: dict[str, subprocess.Popen] = {}
        self._logs: list[IO[str]] = []

    def start(self, name: str, argv: list[str], env: dict[str, str] | None = None) -> subprocess.Popen:
        """Start `python -m services.cli ARGV` as name; its output goes to LOG_DIR/name.log."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        # Kept open for the process's life, closed by stop_all.
        out = None if self.verbose else open(self.log_dir / f"{name}.log", "w")  # noqa: SIM115
        if out is not None:
            self._logs.append(out)
        proc = subprocess.Popen([sys.executable, "-m", "services.cli", *argv], stdout=out,
                                stderr=subprocess.STDOUT, env={**os.environ, **(env or {})},
                                start_new_session=True)
        self.procs[name] = proc
        return proc

    def failed(self) -> dict[str, int]:
        """Processes that have exited with a non-zero code, and their codes."""
        return {n: p.returncode for n, p in self.procs.items() if p.poll() not in (None, 0)}

    def log_tail(self, name: str, lines: int = 15) -> str:
        """The last lines of a process's log ("" with --verbose, where the log went to the terminal)."""
        path = self.log_dir / f"{name}.log"
        if self.verbose or not path.exists():
            return ""
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])

    def stop_all(self, timeout_s: float = 10.0) -> None:
        """SIGTERM every running process group, wait up to timeout_s seconds, then SIGKILL."""
        for proc in self.procs.values():
            if proc.poll() is None:
                _signal_group(proc, signal.SIGTERM)
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal_group(proc, signal.SIGKILL)
                proc.wait()
        for f in self._logs:
            f.close()
        self._logs.clear()


def _signal_group(proc: subprocess.Popen, signum: int) -> None:
    with contextlib.suppress(ProcessLookupError):  # exited in the meantime
        os.killpg(proc.pid, signum)


def _progress(address: str) -> compositor_pb2.GetCompositorReportResponse | None:
    try:
        with make_channel(address) as ch:
            return compositor_pb2_grpc.CompositorServiceStub(ch).GetCompositorReport(
                compositor_pb2.GetCompositorReportRequest(), timeout=RPC_DEADLINE_S)
    except grpc.RpcError:
        return None  # not up yet, or already gone: the next poll will tell


def format_report(doc: dict) -> str:
    """The report as a text table."""
    rows = [("run", doc["run_id"]), ("frames published", doc["frames_published"]),
            ("frames complete", doc["frames_complete"])]
    rows += [(f"incomplete: {k}", v) for k, v in doc["frames_incomplete"].items()]
    rows += [("late images", doc["late_images"])]
    rejected = doc["rejected_submissions"]
    rows += [(f"rejected: {k}", v) for k, v in rejected.items()] if rejected else [("rejected submissions", 0)]
    rows += [(f"skipped frames: {k}", v) for k, v in doc["frames_skipped"].items()]
    host = doc.get("host") or {}
    rows += [(f"host ack timeouts: {k}", v) for k, v in host.get("ack_timeouts", {}).items()]
    if "eyepoints_rejected" in host:
        rows.append(("host eyepoints rejected", host["eyepoints_rejected"]))
    rows += [("frames written", doc["frames_written"]), ("write errors", doc["write_errors"])]
    width = max(len(r[0]) for r in rows)
    lines = [f"  {k:<{width}}  {v}" for k, v in rows]
    lines.append("")
    lines.append(f"  {'milliseconds':<{width}}  {'p50':>9} {'p95':>9} {'p99':>9}")
    figures = [(f"render {c}", p) for c, p in doc["render_time"].items()]
    figures.append(("control-to-composite latency", doc["control_to_composite_latency"]))
    for name, p in figures:
        cells = " ".join(f"{p[k]:9.1f}" if p[k] is not None else f"{'-':>9}" for k in ("p50_ms", "p95_ms", "p99_ms"))
        lines.append(f"  {name:<{width}}  {cells}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the rig; 0 when every frame was complete, 1 otherwise, 2 on bad input, 130 on Ctrl-C."""
    rig = load_rig_or_report(args.rig, "demo")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        # The demo's flags over the rig's [render] table, written into the demo's rig file, which
        # `ig compile` and every worker read: they cannot render with different options.
        rig = replace(rig, render=rig.render.replace(samples=args.samples, filter=args.filter))
    except ValueError as exc:
        error("demo", exc)
        return EXIT_BAD_INPUT
    if args.scene and not Path(args.scene).is_file():
        error("demo", f"--scene: {args.scene!r} is not a file")
        return EXIT_BAD_INPUT
    from channel_worker.pipeline.scene.load import SceneError, demo_scene_path, load_scene

    scene_path = args.scene or str(demo_scene_path())
    if not args.scene:
        # Build the bundled terrain once here (a few seconds on first use) instead of in every
        # worker at once. A scene of the user's is checked by the workers, whose errors end
        # the demo with their message.
        try:
            load_scene(scene_path)
        except SceneError as exc:
            error("demo", exc)
            return EXIT_FAILED
    if args.width or args.height:
        first = rig.channels[0].spec
        rig = rig.with_size(args.width or first.width, args.height or first.height)
    rig = local_rig(rig)
    out = Path(args.out)
    frames_dir = out / "frames"
    try:
        out.mkdir(parents=True, exist_ok=True)
        for old in list(frames_dir.glob("frame_*")) + [out / "report.json"]:
            old.unlink(missing_ok=True)  # a previous demo's frames would mix with this one's
        rig_path = out / "rig.toml"
        rig_path.write_text(rig_toml(rig))
    except OSError as exc:
        error("demo", f"--out: {exc}")
        return EXIT_BAD_INPUT
    expected = int(round(args.duration * args.rate)) + 1
    procs = Processes(out / "logs", args.verbose)
    print(f"ig demo: {len(rig.channels)} channels ({', '.join(rig.channel_names)}), "
          f"{rig.channels[0].spec.width} x {rig.channels[0].spec.height} each, {expected} frames at "
          f"{args.rate:g} Hz; logs in {out / 'logs'}", flush=True)
    scene = ["--scene", scene_path]

    # Ctrl-C and SIGTERM only raise a flag that the watch loop reads every second: an exception
    # raised from a handler can land inside a gRPC call of the progress poll and be lost there.
    stop: dict[str, str | None] = {"why": None}

    def on_signal(signum, frame):
        stop["why"] = "interrupted" if signum == signal.SIGINT else "terminated"

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    started = time.monotonic()
    failure = None
    try:
        # The kernels compile once, here, into the cache every worker then loads from: three
        # workers compiling at once on a small machine would take minutes while the host waits.
        t0 = time.monotonic()
        print("ig demo: compiling the render kernels once for every worker (minutes on the first "
              "run of these sources, seconds once cached) ...", end="", flush=True)
        compiler = procs.start("compile", ["compile", "--rig", str(rig_path), *scene])
        while compiler.poll() is None and not stop["why"]:
            time.sleep(0.2)
        print(f" {time.monotonic() - t0:.0f} s", flush=True)
        if compiler.returncode not in (None, 0):
            failure = ("compile", compiler.returncode)
        elif not stop["why"]:
            failure = _run_rig(procs, rig, rig_path, out, args, scene, expected, stop)
        if stop["why"]:
            print(f"\nig demo: {stop['why']}; stopping every process", file=sys.stderr)
            procs.stop_all()
            return EXIT_INTERRUPTED if stop["why"] == "interrupted" else EXIT_FAILED
    finally:
        procs.stop_all()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if failure:
        name, code = failure
        print(f"ig demo: {name} exited with code {code}; every process was stopped", file=sys.stderr)
        tail = procs.log_tail(name)
        if tail:
            print(f"--- last lines of {out / 'logs' / (name + '.log')} ---\n{tail}", file=sys.stderr)
        return EXIT_BAD_INPUT if code == EXIT_BAD_INPUT else EXIT_FAILED
    report_path = out / "report.json"
    if not report_path.exists():
        print(f"ig demo: no report was written; see {out / 'logs'}", file=sys.stderr)
        return EXIT_FAILED
    doc = json.loads(report_path.read_text())
    print(format_report(doc))
    print(f"\n{doc['frames_complete']} stitched frames in {time.monotonic() - started:.0f} s wall-clock")
    print(f"frames: {frames_dir}/frame_NNNNNN.png\nreport: {report_path}")
    ok = doc["frames_complete"] > 0 and not any(doc["frames_incomplete"].values())
    return EXIT_OK if ok else EXIT_FAILED


def _run_rig(procs: Processes, rig: Rig, rig_path: Path, out: Path, args: argparse.Namespace,
             scene: list[str], expected: int, stop: dict[str, str | None]) -> tuple[str, int] | None:
    """Start the compositor, a worker per channel and the host; watch until the run is over."""
    compositor = procs.start("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out),
                                            "--exr-every", str(args.exr_every), "--once"])
    # One numba thread per worker: the workers already run in parallel with each other.
    for ch in rig.channels:
        procs.start(f"worker-{ch.name}", ["worker", "--rig", str(rig_path), "--channel", ch.name, "--once",
                                          *scene],
                    env={"NUMBA_NUM_THREADS": "1"})
    procs.start("host", ["host", "--rig", str(rig_path), "--rate", str(args.rate),
                         "--duration", str(args.duration)])
    return _watch(procs, compositor, rig.compositor_address, expected, stop)


def _watch(procs: Processes, compositor: subprocess.Popen, address: str, expected: int,
           stop: dict[str, str | None]) -> tuple[str, int] | None:
    """Show progress until the compositor exits; (name, exit code) of the first process that failed.

    One failed process ends the demo at once: without it the host would wait out its start
    and sync timeouts for a channel that will never answer. A raised stop["why"] (a signal)
    ends the watch within a second.
    """
    # On a terminal the progress line is redrawn every second; in a log, a line every 10 s.
    tty = sys.stdout.isatty()
    last, next_line = "", 0.0
    while compositor.poll() is None and not stop["why"]:
        time.sleep(1.0)
        if stop["why"]:
            break
        failed = procs.failed()
        if failed:
            if tty:
                print()
            return next(iter(failed.items()))
        progress = _progress(address)
        if progress is None:
            continue
        line = (f"  frames complete {progress.frames_complete:5d} / published {progress.frames_published:5d}"
                f" / run {expected}")
        if line != last and (tty or time.monotonic() >= next_line):
            print("\r" + line if tty else line, end="" if tty else "\n", flush=True)
            next_line = time.monotonic() + 10.0
        last = line
    if tty:
        print()
    failed = procs.failed()
    return next(iter(failed.items())) if failed else None
