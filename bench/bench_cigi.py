"""The CIGI path (host_sim/cigi, docs/cigi.md): what a host's datagram costs the IG, and what
periodic height-of-terrain requests cost a frame.

    python bench/bench_cigi.py            # the full run (about a minute)
    python bench/bench_cigi.py --quick    # smoke run; not a measurement
    python bench/bench_cigi.py --replot   # redraw cigi.png from the JSON

- decode: a typical host datagram (IG Control, Entity Control, 10 HAT/HOT requests), decoded.
- datagram: one host datagram (IG Control, Entity Control of the ownship, one HOT request)
  taken, applied (the ownship converted from WGS-84 to the world), its query answered through
  ig.v1.QueryService over loopback gRPC by a service holding the bundled scene in a process of
  its own (as a worker is), and the Start of Frame with the response encoded: the whole work of
  the IG for a host message, end to end. Also without the RPC (the host service's own share).
- periodic HOT: N periodic HOT requests (update period 1) at random points of the terrain,
  answered every frame: the frame's session work, the RPC and the response encoding. The
  queries run on the host's query thread, beside the frame, so the budget they must keep is
  the frame period (16.7 ms at 60 Hz).

The host side runs pinned to one CPU, the query service to another (as host and worker are
separate processes), numba on one thread. Writes bench/results/cigi.json and cigi.png.
"""

from __future__ import annotations

import argparse
import datetime as dt
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, pin_to_one_cpu, replot  # bench/ is on the path as a script

NAME = "cigi"
REPEATS = 200
COUNTS = (1, 10, 100, 300)
BUDGET_MS = 1000.0 / 60.0


def main(argv: list[str] | None = None) -> int:
    parser = bench_parser(__doc__ or "", NAME, f"default {REPEATS}", "20 repeats")
    parser.add_argument("--serve", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve is not None:
        return _serve(args.serve)
    if replot(args, NAME, print_report, plot):
        return 0
    cpu = pin_to_one_cpu(args.cpu)
    import numba
    numba.set_num_threads(1)
    from bench_render import machine

    from services.rig.rigfile import CigiSpec

    repeats = 20 if args.quick else (args.repeats or REPEATS)
    origin = CigiSpec().origin
    with tempfile.TemporaryDirectory() as tmp:
        port_file = Path(tmp) / "port"
        service = subprocess.Popen([sys.executable, __file__, "--serve", str(port_file)])
        try:
            while not port_file.exists() or not port_file.read_text().strip():
                if service.poll() is not None:
                    raise RuntimeError("the query service did not start")
                time.sleep(0.1)
            port = int(port_file.read_text())
            record = _measure(args, cpu, repeats, origin, port, machine, numba.get_num_threads())
        finally:
            service.terminate()
            service.wait()
    finish(record, args.out, NAME, print_report, plot)
    return 0


def _serve(port_file: Path) -> int:
    """The query service over the bundled scene, on another CPU than the bench (as a worker)."""
    import os
    from concurrent import futures

    cpus = os.cpu_count() or 1
    if hasattr(os, "sched_setaffinity") and cpus > 1:
        os.sched_setaffinity(0, {cpus - 1})  # the bench itself is pinned to the lowest CPU
    import grpc
    import numba
    numba.set_num_threads(1)

    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from channel_worker.query.service import add_query_service

    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    add_query_service(server, load_scene(demo_scene_path()))
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    port_file.write_text(str(port))
    server.wait_for_termination()  # until the bench's SIGTERM ends the process
    return 0


def _measure(args, cpu, repeats, origin, port, machine, threads) -> dict[str, Any]:
    from channel_worker.pipeline.scene.load import demo_scene_path
    from host_sim.cigi import packets as pk
    from host_sim.cigi.codec import V3_3, decode, encode
    from host_sim.cigi.endpoint import QueryClient
    from host_sim.cigi.geometry import geodetic_of_world
    from host_sim.cigi.session import CigiSession
    from services.rig.frame import ChannelSpec

    client = QueryClient(f"127.0.0.1:{port}", origin=origin, timeout_s=5.0)
    channels = {0: ChannelSpec.symmetric("centre", 64, 48, 60.0)}

    rng = np.random.default_rng(7)
    world = np.c_[rng.uniform(-8000, 8000, max(COUNTS)), rng.uniform(-8000, 8000, max(COUNTS)),
                  np.zeros(max(COUNTS))]
    lat, lon, _ = geodetic_of_world(world, origin)
    ownship = pk.EntityControl(entity_id=0, entity_state=1, lat_x=origin[0], lon_y=origin[1], alt_z=origin[2] + 300,
                               yaw=10.0, pitch=2.0, roll=3.0)

    def hot(i: int, period: int = 0) -> pk.HatHotRequest:
        return pk.HatHotRequest(request_id=i, request_type=1, update_period=period, lat_x=float(lat[i]),
                                lon_y=float(lon[i]), alt_z=0.0)

    # decode
    typical = encode([pk.IGControl(ig_mode=1, host_frame=1), ownship, *[hot(i) for i in range(10)]], V3_3, "<")
    decode_s = _timed(lambda: decode(typical), repeats * 10)

    # one datagram, end to end
    session = CigiSession(origin=origin, channels=channels)
    frame = [0]

    def one_datagram(with_rpc: bool) -> None:
        frame[0] += 1
        session.receive(encode([pk.IGControl(ig_mode=1, host_frame=frame[0]), ownship, hot(frame[0] % 100)],
                               V3_3, "<"), ("127.0.0.1", 8001))
        _, jobs = session.begin_frame()
        answers = client.answer(jobs)[0] if with_rpc else []
        session.start_of_frame(answers)

    datagram_s = _timed(lambda: one_datagram(True), repeats)
    local_s = _timed(lambda: one_datagram(False), repeats)

    # periodic HOT every frame
    periodic: dict[int, list[float]] = {}
    for n in COUNTS:
        s = CigiSession(origin=origin, channels=channels)
        s.receive(encode([pk.IGControl(ig_mode=1, host_frame=1), ownship, *[hot(i, 1) for i in range(n)]], V3_3, "<"),
                  ("127.0.0.1", 8001))
        s.begin_frame()

        def frame_of(s: CigiSession = s) -> None:
            _, jobs = s.begin_frame()
            s.start_of_frame(client.answer(jobs)[0])

        periodic[n] = _timed(frame_of, max(10, repeats // 4))
    client.close()

    def summary(v: list[float]) -> dict[str, Any]:
        return {"median": 1e3 * statistics.median(v), "p95": 1e3 * float(np.percentile(v, 95)),
                "max": 1e3 * max(v), "all": [1e3 * t for t in v]}

    record: dict[str, Any] = {
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "settings": {"cpu": cpu, "numba_threads": threads, "repeats": repeats,
                     "quick": bool(args.quick), "scene": demo_scene_path().name, "origin": list(origin),
                     "typical_datagram_bytes": len(typical)},
        "decode_ms": summary(decode_s),
        "datagram_ms": summary(datagram_s),
        "datagram_without_rpc_ms": summary(local_s),
        "periodic_hot_ms": {str(n): summary(v) for n, v in periodic.items()},
        "budget_ms": BUDGET_MS,
    }
    return record


def _timed(fn, n: int) -> list[float]:
    fn()  # warm-up: kernels loaded, connection made
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def print_report(record: dict) -> None:
    print(f"CIGI on {record['settings']['scene']} ({record['machine'].get('cpu', '?')})")
    print()
    print("| work | median ms | p95 ms | max ms | target |")
    print("|---|---|---|---|---|")
    rows = [("decode a typical datagram (IG Control, Entity Control, 10 HOT)", record["decode_ms"], "< 1 ms"),
            ("one datagram decoded and answered (query over gRPC)", record["datagram_ms"], "< 1 ms"),
            ("the same without the query RPC", record["datagram_without_rpc_ms"], "")]
    rows += [(f"{n} periodic HOT answered in a frame", v, f"< {record['budget_ms']:.1f} ms")
             for n, v in record["periodic_hot_ms"].items()]
    for name, v, target in rows:
        print(f"| {name} | {v['median']:.3f} | {v['p95']:.3f} | {v['max']:.3f} | {target} |")


def plot(record: dict, path: Path) -> bool:
    """Frame cost against periodic HOT requests, with the single datagram's cost and the budget."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    counts = [int(n) for n in record["periodic_hot_ms"]]
    med = [record["periodic_hot_ms"][str(n)]["median"] for n in counts]
    p95 = [record["periodic_hot_ms"][str(n)]["p95"] for n in counts]
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    ax.plot(counts, med, "o-", label="periodic HOT per frame, median")
    ax.plot(counts, p95, "s--", label="p95")
    ax.axhline(record["budget_ms"], color="r", lw=1, label="frame budget (60 Hz)")
    ax.axhline(1.0, color="k", lw=0.8, ls=":", label="1 ms (one datagram)")
    ax.scatter([1], [record["datagram_ms"]["median"]], marker="x", color="k",
               label="one datagram decoded and answered")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("HOT requests answered per frame")
    ax.set_ylabel("ms")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


if __name__ == "__main__":
    sys.exit(main())
