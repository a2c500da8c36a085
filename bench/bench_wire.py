"""The worker -> compositor hop (docs/latency.md): a 1024 x 768 channel image from the end of its
render to the compositor holding its pixels, per wire format and way.

    python bench/bench_wire.py              # 400 frames per variant after 40 of warm-up
    python bench/bench_wire.py --repeats 1000
    python bench/bench_wire.py --quick      # 60 frames per variant; not a measurement

Each variant runs a real compositor (services/compositor/server.py's Compositor and servicer,
recording nothing) in a process of its own, and the worker's real submit path
(channel_worker/submit.py's ImageSender over a gRPC channel) in this one, on localhost; where
there are two CPUs or more the two processes are pinned to different ones, as a worker and the
compositor are different processes. The image is a fixed linear float32 frame (noise: the bytes
of no two pixels alike, though nothing here compresses). Per frame the bench stamps the render
end and submits; the compositor stamps the image received once it has the pixels. Kept per
image, after the warm-up: the hop (render end -> received), its parts encode (render end ->
submit: the sRGB or half-float encoding, into the shared-memory slot or the sender's buffer)
and transfer (submit -> received: the RPC, the bytes, the copy out of the slot), as the
compositor's report.json records them, and the round trip the worker sees (encode, RPC,
answer). Variants: half inline, srgb8 inline, srgb8 shared memory, half shared memory.
Writes bench/results/wire.json.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import RESULTS, bench_parser, finish, pin_to_one_cpu, replot

NAME = "wire"
FRAMES = 400
WARM_UP = 40
WIDTH, HEIGHT = 1024, 768
#: (wire format, shared memory) of each variant, in the table's order.
VARIANTS = (("half", False), ("srgb8", False), ("srgb8", True), ("half", True))
#: Issue 29's targets for the hop's p99 on one machine, milliseconds.
TARGET_MS, AIM_MS = 5.0, 2.0


def main(argv: list[str] | None = None) -> int:
    parser = bench_parser(__doc__ or "", NAME, f"frames per variant, default {FRAMES}",
                          "60 frames per variant; not a measurement")
    parser.add_argument("--serve", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--shared-memory", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve is not None:
        return _serve(args.serve, args.repeats, bool(args.shared_memory))
    if replot(args, NAME, print_report, lambda record, path: False):
        return 0
    cpu = pin_to_one_cpu(args.cpu)
    from bench_render import machine

    frames = 60 if args.quick else (args.repeats or FRAMES)
    warm_up = 10 if args.quick else WARM_UP
    rgb = np.random.default_rng(29).random((HEIGHT, WIDTH, 3), dtype=np.float32)
    record: dict[str, Any] = {
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"), "machine": machine(),
        "git": _git(), "size": [WIDTH, HEIGHT], "frames": frames, "warm_up": warm_up, "quick": args.quick,
        "bench_cpu": cpu, "targets_p99_ms": {"required": TARGET_MS, "aim": AIM_MS}, "rows": []}
    for wire, shared in VARIANTS:
        record["rows"].append(_variant(wire, shared, rgb, frames + warm_up, warm_up))
    finish(record, args.out, NAME, print_report, lambda record, path: False)
    return 0


def _variant(wire: str, shared: bool, rgb: np.ndarray, total: int, warm_up: int) -> dict[str, Any]:
    """One variant: a compositor process, total frames submitted one after the other."""
    import grpc

    from channel_worker.submit import ImageSender, SubmitStub
    from ig.v1 import compositor_pb2, frame_pb2
    from services.rig.frame import ChannelSpec
    from services.rig.rigfile import WireSpec

    with tempfile.TemporaryDirectory() as tmp:
        port_file = Path(tmp) / "port"
        server = subprocess.Popen([sys.executable, __file__, "--serve", str(port_file), "--repeats", str(total),
                                   "--shared-memory", str(int(shared))])
        try:
            while not port_file.exists() or not port_file.read_text().strip():
                if server.poll() is not None:
                    raise RuntimeError("the compositor did not start")
                time.sleep(0.05)
            address = f"127.0.0.1:{port_file.read_text().strip()}"
            sender = ImageSender(ChannelSpec.symmetric("centre", WIDTH, HEIGHT, 60.0), compositor_address=address,
                                 wire=WireSpec(wire, shared))
            round_trip = []
            with grpc.insecure_channel(address, options=[("grpc.max_send_message_length", 64 * 2**20)]) as channel:
                stub = SubmitStub(channel)
                for n in range(total):
                    render_end = time.time()
                    head = compositor_pb2.SubmitChannelImageRequest(
                        frame_number=n, channel_name="centre", width=WIDTH, height=HEIGHT,
                        eyepoint=frame_pb2.Eyepoint(x=float(n)), run_id="bench", render_time_s=0.01,
                        control_sample_time_unix_s=render_end, frame_received_unix_s=render_end,
                        render_start_unix_s=render_end, render_end_unix_s=render_end)
                    t0 = time.perf_counter()
                    sender.submit(stub, head, rgb)
                    round_trip.append(time.perf_counter() - t0)
            used_shared = sender.shared
            sender.close()
            server.wait(timeout=60)
            figures = json.loads((Path(tmp) / "figures.json").read_text())
        finally:
            if server.poll() is None:
                server.terminate()
                server.wait()
    row: dict[str, Any] = {"wire": wire, "shared_memory": used_shared,
                           "bytes_per_image": figures["bytes_per_image"]}
    for key, values in figures["hops"].items():
        row[key] = _ms(values[warm_up:])
    row["round_trip"] = _ms(round_trip[warm_up:])
    row["rejected"] = figures["rejected"]
    return row


def _ms(seconds: list[float]) -> dict[str, float]:
    a = np.asarray(seconds) * 1000.0
    p50, p95, p99 = np.percentile(a, [50, 95, 99])
    return {"p50_ms": round(float(p50), 3), "p95_ms": round(float(p95), 3), "p99_ms": round(float(p99), 3),
            "max_ms": round(float(a.max()), 3), "count": int(a.size)}


def _serve(port_file: Path, total: int, shared: bool) -> int:
    """A compositor of one channel, on another CPU than the bench; it publishes each frame two
    ahead of the last composite (as the host's frames come before the images), and writes the
    per-image figures of its gatherer once frame total - 1 is stitched."""
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if len(cpus) > 1:
        os.sched_setaffinity(0, {cpus[-1]})  # the bench itself is pinned to the lowest CPU
    from ig.v1 import compositor_pb2, frame_pb2
    from services.compositor.server import Compositor, CompositorServicer
    from services.rig.grpc_util import add_service, make_server
    from services.rig.rigfile import WireSpec

    out = port_file.parent / "compositor"
    compositor = Compositor(["centre"], out, record_every=0, exr_every=0, sizes={"centre": (WIDTH, HEIGHT)},
                            wire=WireSpec("srgb8", shared))

    def publish(n: int) -> None:
        compositor.on_published(frame_pb2.Frame(frame_number=n, eyepoint=frame_pb2.Eyepoint(x=float(n)),
                                                run_id="bench", channels=["centre"], publish_time_unix_s=time.time(),
                                                control_sample_time_unix_s=time.time()))

    watch = compositor.watchers.add("bench", [])
    done = threading.Event()

    def follow() -> None:
        while not done.is_set():
            composite = watch.get(0.5)
            if composite is None:
                continue
            n = composite.frame.frame_number
            if n + 2 < total:
                publish(n + 2)
            if n == total - 1:
                done.set()

    publish(0)
    publish(1)
    threading.Thread(target=follow, daemon=True).start()
    server = make_server(max_receive_bytes=64 * 2**20)
    add_service(server, CompositorServicer(compositor),
                compositor_pb2.DESCRIPTOR.services_by_name["CompositorService"], refused=compositor.refuse)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    port_file.write_text(str(port))
    done.wait(600)
    g = compositor.gatherer
    report = compositor.report()
    (port_file.parent / "figures.json").write_text(json.dumps({
        "hops": {k: list(v) for k, v in g.wire_hops.items()},
        "bytes_per_image": report["wire"]["channels"]["centre"]["bytes_per_image"],
        "rejected": report["rejected_submissions"]}))
    server.stop(0)
    compositor.finish(grace_s=0.0)
    return 0


def _git() -> str:
    try:
        return subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True,
                              cwd=RESULTS.parent, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def print_report(record: dict) -> None:
    m = record["machine"]
    print(f"worker -> compositor hop, {record['size'][0]} x {record['size'][1]}, {record['frames']} frames per "
          f"variant after {record['warm_up']} of warm-up; {m['cpu']}, {m['logical_cpus']} logical CPUs, "
          f"load {m['load_average_1min']:.2f}")
    print(f"{'wire':>6} {'way':>7} {'MB':>5}  {'hop p50':>8} {'p95':>6} {'p99':>6} {'max':>6}  "
          f"{'encode p50':>10} {'p99':>6}  {'transfer p50':>12} {'p99':>6}  {'round trip p50':>14} {'p99':>6}")
    for r in record["rows"]:
        hop, enc, tr, rt = (r[k] for k in ("render_end_to_compositor_receive", "encode", "transfer", "round_trip"))
        print(f"{r['wire']:>6} {'shared' if r['shared_memory'] else 'inline':>7} {r['bytes_per_image'] / 1e6:5.2f}  "
              f"{hop['p50_ms']:8.2f} {hop['p95_ms']:6.2f} {hop['p99_ms']:6.2f} {hop['max_ms']:6.2f}  "
              f"{enc['p50_ms']:10.2f} {enc['p99_ms']:6.2f}  {tr['p50_ms']:12.2f} {tr['p99_ms']:6.2f}  "
              f"{rt['p50_ms']:14.2f} {rt['p99_ms']:6.2f}")
    t = record["targets_p99_ms"]
    print(f"(milliseconds; target: hop p99 <= {t['required']:g} ms, aim <= {t['aim']:g} ms)")


if __name__ == "__main__":
    sys.exit(main())
