"""`ig demo`: the whole rig as separate processes on this machine, on the bundled flight."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import grpc

from ig.v1 import compositor_pb2, compositor_pb2_grpc
from services.grpc_util import RPC_DEADLINE_S, make_channel
from services.rig import Rig, RigError, default_rig_path, load_rig


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rig_toml(rig: Rig) -> str:
    """A rig file for rig (the inverse of services.rig.parse_rig)."""
    lines = [f'[host]\naddress = "{rig.host_address}"\n', f'[compositor]\naddress = "{rig.compositor_address}"\n']
    for ch in rig.channels:
        s = ch.spec
        lines.append(
            f'[[channels]]\nname = "{s.name}"\naddress = "{ch.address}"\n'
            f"yaw_deg = {s.yaw_deg!r}\npitch_deg = {s.pitch_deg!r}\nroll_deg = {s.roll_deg!r}\n"
            f"left_deg = {s.left_deg!r}\nright_deg = {s.right_deg!r}\n"
            f"bottom_deg = {s.bottom_deg!r}\ntop_deg = {s.top_deg!r}\n"
            f"width = {s.width}\nheight = {s.height}\n")
    return "\n".join(lines)


def local_rig(rig: Rig) -> Rig:
    """The rig with every service on a free localhost port (so a demo never collides)."""
    chans = tuple(replace(ch, address=f"127.0.0.1:{free_port()}") for ch in rig.channels)
    return replace(rig, host_address=f"127.0.0.1:{free_port()}",
                   compositor_address=f"127.0.0.1:{free_port()}", channels=chans)


class Processes:
    """The processes a demo started; every one is stopped on exit, whatever happens."""

    def __init__(self, log_dir: Path, verbose: bool) -> None:
        self.log_dir = log_dir
        self.verbose = verbose
        self.procs: dict[str, subprocess.Popen] = {}
        self._logs = []

    def start(self, name: str, argv: list[str], env: dict[str, str] | None = None) -> subprocess.Popen:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        out = None if self.verbose else open(self.log_dir / f"{name}.log", "w")
        if out is not None:
            self._logs.append(out)
        # A new session: Ctrl-C in the terminal reaches the demo only, which then stops the
        # processes in order instead of having them all die at once mid-frame.
        proc = subprocess.Popen([sys.executable, "-m", "services.cli", *argv], stdout=out,
                                stderr=subprocess.STDOUT, env={**os.environ, **(env or {})},
                                start_new_session=True)
        self.procs[name] = proc
        return proc

    def stop_all(self, timeout_s: float = 5.0) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        for f in self._logs:
            f.close()


def _report(address: str) -> dict | None:
    try:
        with make_channel(address) as ch:
            resp = compositor_pb2_grpc.CompositorServiceStub(ch).GetCompositorReport(
                compositor_pb2.GetCompositorReportRequest(), timeout=RPC_DEADLINE_S)
            return json.loads(resp.report_json)
    except grpc.RpcError:
        return None


def format_report(doc: dict) -> str:
    """The report as a text table."""
    rows = [("frames published", doc["frames_published"]), ("frames complete", doc["frames_complete"])]
    rows += [(f"incomplete: {k}", v) for k, v in doc["frames_incomplete"].items()]
    rows += [("late images", doc["late_images"])]
    rows += [(f"rejected: {k}", v) for k, v in doc["rejected_submissions"].items()]
    rows += [(f"skipped frames: {k}", v) for k, v in doc["frames_skipped"].items()]
    host = doc.get("host") or {}
    rows += [(f"host ack timeouts: {k}", v) for k, v in host.get("ack_timeouts", {}).items()]
    if "eyepoints_rejected" in host:
        rows.append(("host eyepoints rejected", host["eyepoints_rejected"]))
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


def run_demo(args) -> int:
    """Run the rig; 0 when every frame was complete, 1 otherwise, 2 on bad input, 130 on Ctrl-C."""
    try:
        rig = load_rig(args.rig or default_rig_path())
    except RigError as exc:
        print(f"ig demo: error: {exc}", file=sys.stderr)
        return 2
    if args.width or args.height:
        first = rig.channels[0].spec
        rig = rig.with_size(args.width or first.width, args.height or first.height)
    rig = local_rig(rig)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for old in (out / "frames").glob("frame_*"):
        old.unlink()
    rig_path = out / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    expected = int(round(args.duration * args.rate)) + 1
    procs = Processes(out / "logs", args.verbose)
    print(f"ig demo: {len(rig.channels)} channels ({', '.join(rig.channel_names)}), "
          f"{expected} frames at {args.rate:g} Hz; logs in {out / 'logs'}")
    scene = ["--scene", args.scene] if args.scene else []
    try:
        compositor = procs.start("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out),
                                                "--exr-every", str(args.exr_every), "--once"])
        # One numba thread per worker: the workers already run in parallel with each other.
        for ch in rig.channels:
            procs.start(f"worker-{ch.name}", ["worker", "--rig", str(rig_path), "--channel", ch.name,
                                              "--samples", str(args.samples), "--once", *scene],
                        env={"NUMBA_NUM_THREADS": "1"})
        procs.start("host", ["host", "--rig", str(rig_path), "--rate", str(args.rate),
                             "--duration", str(args.duration)])
        last = ""
        # On a terminal the progress line is redrawn every second; in a log, a line every 10 s.
        tty = sys.stdout.isatty()
        next_line = 0.0
        while compositor.poll() is None:
            time.sleep(1.0)
            doc = _report(rig.compositor_address)
            if doc is not None:
                line = (f"  frames complete {doc['frames_complete']:5d} / published {doc['frames_published']:5d}"
                        f" / run {expected}")
                if tty and line != last:
                    print("\r" + line, end="", flush=True)
                elif not tty and line != last and time.monotonic() >= next_line:
                    print(line, flush=True)
                    next_line = time.monotonic() + 10.0
                last = line
            dead = [n for n, p in procs.procs.items() if p.poll() not in (None, 0) and n != "compositor"]
            if dead and len(dead) == len(procs.procs) - 1:
                print(f"\nig demo: every other process has exited ({', '.join(dead)}); see the logs",
                      file=sys.stderr)
                break
        print()
    except KeyboardInterrupt:
        print("\nig demo: interrupted; stopping every process", file=sys.stderr)
        procs.stop_all()
        return 130
    finally:
        procs.stop_all()
    report_path = out / "report.json"
    if not report_path.exists():
        print(f"ig demo: no report was written; see {out / 'logs'}", file=sys.stderr)
        return 1
    doc = json.loads(report_path.read_text())
    print(format_report(doc))
    print(f"\nframes: {doc['frames_dir']}  report: {report_path}")
    ok = doc["frames_complete"] > 0 and not any(doc["frames_incomplete"].values())
    return 0 if ok else 1
