"""`ig demo`: the whole rig as separate processes on this machine, on the bundled flight, a
scripted take-off (`--fdm`) or a flight log (`--replay`: a bundled sample flight by name, or a
log file, placed around the rig's database origin).

The host is paced by the rig (`--rate auto`, the default): it publishes each frame as soon as
every channel has acknowledged the previous one (at most AUTO_RATE_MAX_HZ), samples the controls
just before, and takes simulation time from the wall clock, so the flight plays in real time
at whatever rate the rig renders (docs/frame-lock.md, `ig host --pace acks`). Workers,
compositor and host start together once the kernels are compiled: the host's first frame waits
only for every channel to subscribe, and the compositor records about _RECORDED_PER_S PNGs a
simulated second by the frames' time stamps (`--record-every auto`), so nothing needs the rate
in advance. (A calibration run of ten unthrottled frames used to measure it first, to space the
recording by frame numbers: it cost the first stitched frame 10-15 s on the 2-core development
machine.) A fixed `--rate HZ` publishes at that rate instead (`--pace ticks`): above what the
rig sustains it slows the simulation (frame lock).

The building blocks (the processes, the kernels compiled once, the workers) serve `ig latency`
too (services/latency.py).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO

import grpc

from channel_worker.data import DEFAULT_SCENE, SCENES, resolve_scene, scene_names_help
from host_sim.replay import samples as sample_flights
from ig.v1 import compositor_pb2, compositor_pb2_grpc
from services.compositor.cli import every
from services.compositor.timing import HOPS
from services.rig.cli_common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    error,
    load_rig_or_report,
    non_negative,
    pixels,
    port_or_off,
    positive,
)
from services.rig.grpc_util import RPC_DEADLINE_S, make_channel
from services.rig.rigfile import Rig, TlsSpec, rig_toml
from services.rig.threads import check_threads, share_of_cores

#: Exit code after Ctrl-C (128 + SIGINT), as shells report it.
EXIT_INTERRUPTED = 130

#: The fastest rate --rate auto chooses, Hz (a display's refresh: faster frames would not be shown).
AUTO_RATE_MAX_HZ = 60.0
#: Simulated seconds `ig demo` flies by default: the bundled flight's take-off and climb-out,
#: and a scripted take-off of a flight model (--fdm), which lifts off at about 27 s (JSBSim's
#: c172x, docs/host-flight-model.md) and is then shown climbing.
FLIGHT_S = 20.0
TAKEOFF_S = 40.0
#: PNGs per simulated second of the demo with --record-every auto. A 3072 x 768 PNG takes
#: 0.2 s of a core to encode: recording every frame at 3 Hz would take a quarter of a 2-core
#: machine from the renderers (the recorder never holds the rig up, but it shares the CPU).
_RECORDED_PER_S = 1.0


def rate_or_auto(text: str) -> float | None:
    """argparse type: `auto` (None: what the rig sustains) or a finite rate > 0, Hz."""
    return None if text == "auto" else positive(text)


def host_pace_args(rate_hz: float | None) -> list[str]:
    """`ig host` options for --rate: auto (None) paces the host by the rig's acknowledgements,
    at most AUTO_RATE_MAX_HZ; a rate, Hz, is a fixed rate (docs/frame-lock.md)."""
    if rate_hz is None:
        return ["--pace", "acks", "--rate", repr(AUTO_RATE_MAX_HZ)]
    return ["--pace", "ticks", "--rate", repr(rate_hz)]


def every_or_auto(text: str) -> int | None:
    """argparse type: `auto` (None) or a period in frames, a whole number >= 0 (0: never)."""
    if text == "auto":
        return None
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither auto nor a whole number of frames") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text} is not >= 0 (0: never)")
    return value


def add_rig_options(parser: argparse.ArgumentParser, *, out: str) -> None:
    """The options `ig demo` and `ig latency` share: the rig, its size and render options, the scene."""
    parser.add_argument("--width", type=pixels, default=None, help="override every channel's width, pixels")
    parser.add_argument("--height", type=pixels, default=None, help="override every channel's height, pixels")
    parser.add_argument("--samples", default="4", help="samples per pixel, a count or a pattern name (default 4)")
    parser.add_argument("--filter", default="box",
                        help="pixel reconstruction filter: box, tent, gaussian (default box)")
    parser.add_argument("--threads", type=int, default=None,
                        help="render threads of each worker (default: the rig file's [render] threads, or "
                             "where that is 0, this machine's cores divided among the workers)")
    parser.add_argument("--scene", default=None,
                        help="a scene JSON file or a bundled scene's name: " + scene_names_help()
                             + f" (default: the rig file's [scene] path, else {DEFAULT_SCENE})")
    parser.add_argument("--rig", default=None,
                        help="rig file (default: the bundled three-channel rig); its addresses are replaced "
                             "by free ports on 127.0.0.1")
    parser.add_argument("--verbose", action="store_true",
                        help=f"show the processes' logs instead of writing them to {out}/logs")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig demo`."""
    parser.add_argument("--rate", type=rate_or_auto, default=None,
                        help="auto (default): the host paced by the rig, each frame as soon as every channel "
                             f"acknowledged the last (at most {AUTO_RATE_MAX_HZ:g} Hz), the flight in real time; "
                             "or a fixed host frame rate, Hz, frame-locked: a rate above what the rig renders "
                             "slows the simulation")
    parser.add_argument("--duration", type=non_negative, default=None,
                        help=f"simulated seconds to fly (default {FLIGHT_S:g} of the bundled flight; "
                             f"{TAKEOFF_S:g} with --fdm: the scripted take-off lifts off at about 27 s, then climbs; "
                             "the whole log with --replay)")
    parser.add_argument("--fdm", default=None, metavar="MODEL",
                        help="instead of the bundled flight, a scripted take-off from the runway flown by this "
                             "flight model: jsbsim (JSBSim's c172x), jsbsim:AIRCRAFT or point-mass "
                             "(docs/host-flight-model.md; JSBSim needs pip install 'ig-rig[jsbsim]')")
    parser.add_argument("--replay", default=None, metavar="NAME|FILE",
                        help="instead of the bundled flight, fly a flight log: a bundled sample, "
                             + "; ".join(f"{name} ({what})" for name, (_, what) in sample_flights.SAMPLES.items())
                             + "; or a log file (.csv, .igc, .fdr, .ulg; docs/replay-formats.md), its geodetic "
                               "positions placed around the rig's database origin ([cigi] origin: the bundled "
                               "airfield's). --duration defaults to the whole log")
    parser.add_argument("--record-every", type=every_or_auto, default=None,
                        help=f"write the stitched frame as PNG every N frames, or auto (default): "
                             f"{_RECORDED_PER_S:g} per simulated second, by the frames' time stamps. Recording "
                             "never holds the rig up: a frame due while the writer is behind is left out and "
                             "counted (each PNG costs CPU time, though: 0.2 s of a core at the default size)")
    parser.add_argument("--exr-every", type=every, default=30,
                        help="also write a linear EXR every N frames (default 30; 0: never)")
    parser.add_argument("--out", default="out/demo",
                        help="output directory: runs/<run id>/frames/ and report.json (latest -> this run), "
                             "rig.toml, logs/ (default out/demo)")
    parser.add_argument("--view-port", type=port_or_off, default=None, metavar="PORT",
                        help="serve the compositor's live view, the stitched panorama and the rig's state in a "
                             "browser, at http://127.0.0.1:PORT/ while the flight lasts (docs/live-view.md); "
                             "default: the rig file's [compositor] view_port, moved to a free port, none unless "
                             "set; 0: none")
    add_rig_options(parser, out="OUT")


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def local_rig(rig: Rig) -> Rig:
    """The rig with every service on a free 127.0.0.1 port, so a demo never collides with a rig
    already running on the fixed ports, and so do the metrics and live-view ports the rig file sets;
    plaintext, as everything stays on the loopback (a rig file's [tls] table is for its
    machines)."""
    def moved(port: int) -> int:
        return free_port() if port else 0

    chans = tuple(replace(ch, address=f"127.0.0.1:{free_port()}", metrics_port=moved(ch.metrics_port))
                  for ch in rig.channels)
    return replace(rig, host_address=f"127.0.0.1:{free_port()}",
                   compositor_address=f"127.0.0.1:{free_port()}", channels=chans, tls=TlsSpec(),
                   host_metrics_port=moved(rig.host_metrics_port),
                   compositor_metrics_port=moved(rig.compositor_metrics_port),
                   compositor_view_port=moved(rig.compositor_view_port))


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

    def start(self, name: str, argv: list[str], env: dict[str, str] | None = None, *,
              show: bool = False) -> subprocess.Popen:
        """Start `python -m services.cli ARGV` as name; its output goes to LOG_DIR/name.log, or
        to the terminal with show (a process whose progress the user waits on)."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        # Kept open for the process's life, closed by stop_all.
        out = None if self.verbose or show else open(self.log_dir / f"{name}.log", "w")  # noqa: SIM115
        if out is not None:
            self._logs.append(out)
        # Shown, its errors stay on the terminal's error stream.
        err = None if show and not self.verbose else subprocess.STDOUT
        proc = subprocess.Popen([sys.executable, "-m", "services.cli", *argv], stdout=out, stderr=err,
                                env={**os.environ, **(env or {})}, start_new_session=True)
        self.procs[name] = proc
        return proc

    def terminate(self, name: str) -> None:
        """SIGTERM one process (its group) if it is still running."""
        proc = self.procs.get(name)
        if proc is not None and proc.poll() is None:
            _signal_group(proc, signal.SIGTERM)

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
    rows += [("frames written", doc["frames_written"]),
             ("frames not recorded (writer behind)", doc.get("frames_not_recorded", 0)),
             ("write errors", doc["write_errors"])]
    rate = doc.get("composite_rate_hz")
    rows.append(("composites per second (median)", f"{rate:.2f}" if rate else "-"))
    wire = doc.get("wire") or {}
    for c, n in wire.get("channels", {}).items():
        formats = ", ".join(f"{n[k]} {k}" for k in ("srgb8", "half") if n[k]) or "none"
        rows.append((f"wire {c}", f"{formats}; {n['shared_memory']} in shared memory, {n['inline']} inline; "
                                  f"{n['bytes_per_image'] / 1e6:.2f} MB an image"))
    figures = [(f"render {c}", p) for c, p in doc["render_time"].items()]
    figures.append(("control-to-composite latency", doc["control_to_composite_latency"]))
    chain = doc.get("latency_chain") or {}
    figures += [(f"  {key}", chain[key]) for key, _ in HOPS if key in chain]
    if wire.get("render_end_to_compositor_receive"):
        figures += [("worker -> compositor, every image", wire["render_end_to_compositor_receive"]),
                    ("  encode (render end -> submit)", wire["encode"]),
                    ("  transfer (submit -> received)", wire["transfer"])]
    width = max(len(r[0]) for r in rows + figures)
    lines = [f"  {k:<{width}}  {v}" for k, v in rows]
    lines.append("")
    lines.append(f"  {'milliseconds':<{width}}  {'p50':>9} {'p95':>9} {'p99':>9} {'max':>9}")
    if chain:
        critical = ", ".join(f"{c} {n}" for c, n in (doc.get("critical_channel") or {}).items())
        lines.append(f"  (the chain below the latency follows the channel the composite waited for: {critical})")
    for name, p in figures:
        lines.append(f"  {name:<{width}}  {milliseconds_cells(p)}")
    return "\n".join(lines)


def milliseconds_cells(p: dict) -> str:
    """p50, p95, p99 and max of a percentiles() dict as right-aligned cells ("-" without data)."""
    return " ".join(f"{p[k]:9.1f}" if p.get(k) is not None else f"{'-':>9}"
                    for k in ("p50_ms", "p95_ms", "p99_ms", "max_ms"))


class StopFlag:
    """Set by SIGINT and SIGTERM while installed (see stop_flag); read by every wait loop.

    The handlers only raise the flag: an exception raised from a handler can land inside a
    gRPC call of a progress poll and be lost there.
    """

    def __init__(self) -> None:
        self.why: str | None = None


@contextlib.contextmanager
def stop_flag() -> Iterator[StopFlag]:
    """A StopFlag that Ctrl-C and SIGTERM raise while the context lasts."""
    flag = StopFlag()

    def on_signal(signum, frame):
        flag.why = "interrupted" if signum == signal.SIGINT else "terminated"

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def prepare_rig(command: str, args: argparse.Namespace) -> tuple[Rig, str] | int:
    """The rig of args with its render options, size and free local ports, and the scene path
    (a bundled terrain built once here); or the exit code after printing why not.

    Checks everything before anything is written or started.
    """
    rig = load_rig_or_report(args.rig, command)
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        # The flags over the rig's [render] table, written into the run's rig file, which
        # `ig compile` and every worker read: they cannot render with different options.
        rig = replace(rig, render=rig.render.replace(samples=args.samples, filter=args.filter))
        rig = replace(rig, render=rig.render.replace(threads=worker_threads(rig, args.threads)))
    except ValueError as exc:
        error(command, exc)
        return EXIT_BAD_INPUT
    # The scene: --scene (a bundled scene's name or a file), else the rig file's [scene] path,
    # else the demo's terrain scene.
    from channel_worker.pipeline.scene.load import SceneError, load_scene

    if args.scene in SCENES or not (args.scene or rig.scene):
        scene_path = str(resolve_scene(args.scene))
        # Build the bundled terrain once here (a few seconds on first use) instead of in every
        # worker at once. A scene of the user's is checked by the workers, whose errors end
        # the run with their message.
        try:
            load_scene(scene_path)
        except SceneError as exc:
            error(command, exc)
            return EXIT_FAILED
    else:
        scene_path, where = (args.scene, "--scene") if args.scene else (rig.scene, "[scene] path")
        if not Path(scene_path).is_file():
            what = f"neither a bundled scene ({', '.join(SCENES)}) nor a file" if args.scene else "not a file"
            error(command, f"{where}: {scene_path!r} is {what}")
            return EXIT_BAD_INPUT
    if args.width or args.height:
        first = rig.channels[0].spec
        rig = rig.with_size(args.width or first.width, args.height or first.height)
    return local_rig(rig), scene_path


def worker_threads(rig: Rig, flag: int | None) -> int:
    """Render threads of each worker of a rig started on this machine: --threads, else the rig
    file's [render] threads, else (0) the usable cores shared among the workers.

    Raises:
        ValueError: a count this machine cannot give every worker, naming where it came from.
    """
    setting, threads = ("--threads", flag) if flag is not None else ("[render] threads", rig.render.threads)
    check_threads(threads, setting)
    return threads or share_of_cores(len(rig.channels))


Failure = tuple[str, int]
"""A process that exited with an error: its name and exit code."""


def compile_kernels(procs: Processes, command: str, rig_path: Path, scene: list[str],
                    stop: StopFlag) -> Failure | None:
    """Compile the kernels once, into the cache every worker then loads them from: three
    workers compiling at once on a small machine would take minutes while the host waits."""
    t0 = time.monotonic()
    print(f"ig {command}: compiling the render kernels once for every worker (about two minutes on two "
          "cores the first time for these sources, a second once cached)", flush=True)
    # Its progress (groups done, the kernel each process compiles) straight to the terminal.
    compiler = procs.start("compile", ["compile", "--rig", str(rig_path), *scene], show=True)
    while compiler.poll() is None and not stop.why:
        time.sleep(0.2)
    print(f"ig {command}: kernels ready in {time.monotonic() - t0:.0f} s", flush=True)
    return ("compile", compiler.returncode) if compiler.returncode not in (None, 0) else None


def start_workers(procs: Processes, rig: Rig, rig_path: Path, scene: list[str]) -> None:
    """One worker per channel, each with the rig file's [render] threads (worker_threads: the
    cores shared among them by default), which the worker sizes its pool to before numba
    starts. They serve every run of the host at the rig's address until stopped (stop_all)."""
    for ch in rig.channels:
        procs.start(f"worker-{ch.name}", ["worker", "--rig", str(rig_path), "--channel", ch.name, *scene])


def wait_for_exit(procs: Processes, proc: subprocess.Popen, stop: StopFlag, *,
                  timeout_s: float = math.inf) -> Failure | None:
    """Wait until proc exits (at most timeout_s seconds); (name, code) of the first process that
    failed meanwhile, if any."""
    deadline = time.monotonic() + timeout_s
    while proc.poll() is None and not stop.why and time.monotonic() < deadline:
        failed = procs.failed()
        if failed:
            return next(iter(failed.items()))
        time.sleep(0.2)
    failed = procs.failed()
    return next(iter(failed.items())) if failed else None


def process_start_time() -> float:
    """Wall-clock time (UNIX seconds) at which this process started: from /proc on Linux, so
    that the interpreter's start and the imports count; elsewhere the time of this call."""
    try:
        # Field 22 of /proc/self/stat, starttime in clock ticks after boot; the fields after
        # the command name (which may hold spaces, in parentheses) start at field 3.
        ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime_s = float(Path("/proc/uptime").read_text().split()[0])
        return time.time() - (uptime_s - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return time.time()


@dataclass
class Timeline:
    """Where a demo's wall-clock time went before its flight.

    Attributes:
        started: UNIX time the `ig demo` process started.
        compile_s: seconds of `ig compile`.
        rig_started: UNIX time the workers, compositor and host were started (0: never).
    """

    started: float
    compile_s: float = 0.0
    rig_started: float = 0.0


def demo_times(timeline: Timeline, doc: dict, *, ended: float, simulated_s: float) -> dict:
    """The demo's own numbers for its report and closing lines: the time from the program's
    start to the flight's first stitched frame (after the compile, from the rig's start), and the
    flight apart from them, from the compositor's first and last composite (report.json).

    Args:
        timeline: the demo's start and its rig's (UNIX seconds), the seconds its compile took.
        doc: the compositor's report of the flight (first_composite_time, last_composite_time,
            frames_complete).
        ended: UNIX time the demo ended (every process stopped).
        simulated_s: simulated seconds the host flew.

    Returns:
        first_frame_s (None without a composite), total_s, compile_s, rig_start_s (from the
        rig's start to its first stitched frame: the processes' start, the channels'
        subscriptions and the first frame; None without a composite),
        flight_wall_s and flight_rate_hz (the flight's composites over its wall-clock time,
        None with fewer than two), flight_frames, flight_simulated_s.
    """
    first, last = doc.get("first_composite_time"), doc.get("last_composite_time")
    frames = int(doc.get("frames_complete") or 0)
    flight_s = last - first if first is not None and last is not None else None
    return {
        "first_frame_s": round(first - timeline.started, 3) if first is not None else None,
        "total_s": round(ended - timeline.started, 3),
        "compile_s": round(timeline.compile_s, 3),
        "rig_start_s": (round(first - timeline.rig_started, 3)
                        if first is not None and timeline.rig_started else None),
        "flight_wall_s": round(flight_s, 3) if flight_s is not None else None,
        "flight_frames": frames,
        "flight_rate_hz": round((frames - 1) / flight_s, 3) if flight_s and frames > 1 else None,
        "flight_simulated_s": simulated_s,
    }


def format_times(times: dict) -> str:
    """The demo's closing lines on its own time (demo_times)."""
    first = times["first_frame_s"]
    lines = [f"first stitched frame {first:.1f} s after ig demo started (kernels {times['compile_s']:.1f} s, "
             f"then the rig's start to its first frame {times['rig_start_s']:.1f} s)"
             if first is not None and times["rig_start_s"] is not None else "no stitched frame"]
    if times["flight_wall_s"] is not None:
        rate = times["flight_rate_hz"]
        lines.append(f"the flight: {times['flight_frames']} stitched frames in {times['flight_wall_s']:.1f} s "
                     f"wall-clock" + (f" ({rate:.2f} Hz)" if rate else "") +
                     f" for {times['flight_simulated_s']:g} simulated seconds")
    lines.append(f"{times['total_s']:.0f} s in all")
    return "\n".join(lines)


def _write_demo_times(report_path: Path, times: dict) -> None:
    """Add the demo's numbers to the run's report.json, under "demo" (written whole, then
    renamed: a reader never sees half a file)."""
    doc = json.loads(report_path.read_text())
    doc["demo"] = times
    tmp = report_path.with_name(report_path.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    os.replace(tmp, report_path)


def replay_host_args(text: str, rig: Rig) -> tuple[list[str], float]:
    """`ig host` options that fly the log of `ig demo --replay` over the rig's world, and the
    log's length, simulated seconds.

    Args:
        text: a bundled sample's name (host_sim.replay.samples) or a log file.
        rig: the rig; its database origin ([cigi] origin) is the replay's geodetic origin, so
            that the bundled samples fly over the bundled airfield, and a log recorded there does.

    Raises:
        ValueError: neither a sample's name nor a file, or a log the replay refuses (the message
            names --replay, the file and the problem).
    """
    from host_sim.replay import load_track

    path = sample_flights.resolve_log(text, setting="--replay")
    origin = rig.cigi.origin
    try:
        # Read here, before anything starts: a log the host would refuse is said in one line.
        track, _ = load_track(path, origin=origin)
    except ValueError as exc:
        raise ValueError(f"--replay: {exc}") from exc
    return (["--replay", str(path), "--replay-origin", ",".join(repr(float(v)) for v in origin)],
            track.duration_s)


def run(args: argparse.Namespace) -> int:
    """Run the rig; 0 when every frame was complete, 1 otherwise, 2 on bad input, 130 on Ctrl-C."""
    timeline = Timeline(started=process_start_time())
    if args.replay is not None and args.fdm is not None:
        error("demo", f"--replay {args.replay!r} and --fdm {args.fdm!r} are two sources of the flight; give one")
        return EXIT_BAD_INPUT
    if args.fdm is not None:
        from host_sim.fdm import parse_fdm
        from host_sim.fdm.jsbsim_model import import_jsbsim
        try:
            if parse_fdm(args.fdm).name == "jsbsim":
                import_jsbsim()  # before any process starts: one line, not a failed host's log
        except ValueError as exc:
            error("demo", exc)
            return EXIT_BAD_INPUT
    prepared = prepare_rig("demo", args)
    if isinstance(prepared, int):
        return prepared
    rig, scene_path = prepared
    source: list[str] = ["--fdm", args.fdm] if args.fdm is not None else []
    flown = "the scripted take-off" if args.fdm is not None else "the bundled flight"
    natural_s = FLIGHT_S if args.fdm is None else TAKEOFF_S
    if args.replay is not None:
        try:
            source, natural_s = replay_host_args(args.replay, rig)
        except ValueError as exc:
            error("demo", exc)
            return EXIT_BAD_INPUT
        flown = Path(source[1]).name
    if args.duration is None:
        args.duration = natural_s
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        # The compositor gives every run its own runs/<run id>/ and points latest at it: a
        # previous demo's frames stay where they are, and never mix with this one's.
        (out / "latest").unlink(missing_ok=True)
        rig_path = out / "rig.toml"
        rig_path.write_text(rig_toml(rig))
    except OSError as exc:
        error("demo", f"--out: {exc}")
        return EXIT_BAD_INPUT
    procs = Processes(out / "logs", args.verbose)
    print(f"ig demo: {len(rig.channels)} channels ({', '.join(rig.channel_names)}), "
          f"{rig.channels[0].spec.width} x {rig.channels[0].spec.height} each, {rig.render.threads} render "
          f"thread(s) per worker, {args.duration:g} simulated "
          f"seconds of {flown}; logs in {out / 'logs'}", flush=True)
    scene = ["--scene", scene_path]
    failure, rate = None, 0.0
    with stop_flag() as stop:
        try:
            t0 = time.time()
            failure = compile_kernels(procs, "demo", rig_path, scene, stop)
            timeline.compile_s = time.time() - t0
            if not failure and not stop.why:
                failure, rate = _run_rig(procs, rig, rig_path, out, args, scene, source, stop, timeline)
            if stop.why:
                print(f"\nig demo: {stop.why}; stopping every process", file=sys.stderr)
                procs.stop_all()
                return EXIT_INTERRUPTED if stop.why == "interrupted" else EXIT_FAILED
        finally:
            procs.stop_all()
    if failure:
        name, code = failure
        print(f"ig demo: {name} exited with code {code}; every process was stopped", file=sys.stderr)
        tail = procs.log_tail(name)
        if tail:
            print(f"--- last lines of {out / 'logs' / (name + '.log')} ---\n{tail}", file=sys.stderr)
        return EXIT_BAD_INPUT if code == EXIT_BAD_INPUT else EXIT_FAILED
    report_path = out / "latest" / "report.json"
    if not report_path.exists():
        print(f"ig demo: no report was written; see {out / 'logs'}", file=sys.stderr)
        return EXIT_FAILED
    doc = json.loads(report_path.read_text())
    frames_dir = Path(doc.get("frames_dir") or out / "latest" / "frames")
    times = demo_times(timeline, doc, ended=time.time(), simulated_s=args.duration)
    try:
        _write_demo_times(report_path, times)
    except OSError as exc:
        error("demo", f"cannot add the demo's times to {report_path}: {exc}")
    print(format_report(doc))
    print("\n" + format_times(times))
    achieved = doc.get("composite_rate_hz")
    if achieved and args.rate is None:
        print(f"composites came at {achieved:.2f} Hz (median), the host paced by the rig: the flight ran in "
              "real time")
    elif achieved:
        print(f"composites came at {achieved:.2f} Hz (median) for a host rate of {rate:g} Hz" +
              (f": the rig was slower, so the flight ran at {achieved / rate:.0%} of real time"
               if achieved < 0.95 * rate else ""))
    if doc.get("frames_not_recorded"):
        print(f"{doc['frames_not_recorded']} frames due for recording were left out: the writer was behind "
              "(record fewer with --record-every)")
    print(f"frames: {frames_dir}/frame_NNNNNN.png\nreport: {report_path}")
    ok = doc["frames_complete"] > 0 and not any(doc["frames_incomplete"].values())
    return EXIT_OK if ok else EXIT_FAILED


def _run_rig(procs: Processes, rig: Rig, rig_path: Path, out: Path, args: argparse.Namespace,
             scene: list[str], source: list[str], stop: StopFlag, timeline: Timeline) -> tuple[Failure | None, float]:
    """Start a worker per channel, the compositor and the host (flying source: its `ig host`
    options, none for the bundled flight) at once; watch until the run is over. Returns the
    first failure, and the fixed rate, Hz (0 with --rate auto: the host is paced by the rig).
    The time the rig started goes into timeline."""
    timeline.rig_started = time.time()
    start_workers(procs, rig, rig_path, scene)
    rate = args.rate
    if args.record_every is not None:
        record, recording = ["--record-every", str(args.record_every)], f"PNG every {args.record_every} frame(s)"
    else:
        record = ["--record-per-s", repr(_RECORDED_PER_S)]
        recording = f"{_RECORDED_PER_S:g} PNG(s) a simulated second"
    expected = None if rate is None else int(round(args.duration * rate)) + 1
    pace = (f"the host paced by the rig (at most {AUTO_RATE_MAX_HZ:g} Hz)" if rate is None
            else f"{expected} frames at {rate:g} Hz")
    print(f"ig demo: {pace}, {recording}, EXR every {args.exr_every}", flush=True)
    view_port = rig.compositor_view_port if args.view_port is None else args.view_port
    compositor = procs.start("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), *record,
                                            "--exr-every", str(args.exr_every), "--view-port", str(view_port),
                                            "--once"])
    if view_port:
        print(f"ig demo: live view at http://127.0.0.1:{view_port}/ while the flight lasts", flush=True)
    procs.start("host", ["host", "--rig", str(rig_path), *host_pace_args(rate),
                         "--duration", str(args.duration), *source])
    return _watch(procs, compositor, rig.compositor_address, expected, stop), rate or 0.0


def _watch(procs: Processes, compositor: subprocess.Popen, address: str, expected: int | None,
           stop: StopFlag) -> Failure | None:
    """Show progress until the compositor exits; (name, exit code) of the first process that failed.

    expected is the run's frame count at a fixed rate (None: the host is paced by the rig).

    One failed process ends the demo at once: without it the host would wait out its start
    and sync timeouts for a channel that will never answer. A raised stop flag (a signal)
    ends the watch within a second.
    """
    # On a terminal the progress line is redrawn every second; in a log, a line every 10 s.
    tty = sys.stdout.isatty()
    last, next_line = "", 0.0
    while compositor.poll() is None and not stop.why:
        time.sleep(1.0)
        if stop.why:
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
                + (f" / run {expected}" if expected else ""))
        if line != last and (tty or time.monotonic() >= next_line):
            print("\r" + line if tty else line, end="" if tty else "\n", flush=True)
            next_line = time.monotonic() + 10.0
        last = line
    if tty:
        print()
    failed = procs.failed()
    return next(iter(failed.items())) if failed else None
