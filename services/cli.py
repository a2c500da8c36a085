"""The `ig` command: one entry point for every process of the rig."""

from __future__ import annotations

import argparse
import logging
import sys
import threading
from pathlib import Path

EXIT_OK = 0
EXIT_BAD_INPUT = 2


def _rig_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rig", default=None,
                   help="rig file (docs/rig-format.md); default: the bundled three-channel rig on localhost")
    p.add_argument("--verbose", action="store_true", help="log debug messages")


def _load_rig(path):
    from services.rig import RigError, default_rig_path, load_rig
    try:
        return load_rig(path or default_rig_path())
    except RigError as exc:
        print(f"ig: error: {exc}", file=sys.stderr)
        return None


def cmd_render(args) -> int:
    from channel_worker import cli_render
    return cli_render.run(args)


def cmd_host(args) -> int:
    from host_sim.flight import bundled_flight
    from host_sim.publisher import FramePublisher
    from host_sim.server import serve
    from services.grpc_util import configure_logging, stop_on_signals
    from services.rig import bind_address

    configure_logging(args.verbose)
    rig = _load_rig(args.rig)
    if rig is None:
        return EXIT_BAD_INPUT
    flight = bundled_flight()
    duration = flight.duration_s if args.duration is None else args.duration
    try:
        publisher = FramePublisher(source=flight.eyepoint_at, channels=rig.channel_names, rate_hz=args.rate,
                                   duration_s=duration, sync_timeout_s=args.sync_timeout,
                                   observers=args.observers, start_timeout_s=args.start_timeout)
    except ValueError as exc:
        print(f"ig host: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    stop = threading.Event()
    stop_on_signals(stop)
    try:
        serve(publisher, bind_address(rig.host_address, args.bind), stop)
    except OSError as exc:
        print(f"ig host: error: {exc}", file=sys.stderr)
        return 1
    return EXIT_OK


def cmd_worker(args) -> int:
    from channel_worker.pipeline.samples import sample_pattern
    from channel_worker.pipeline.scene import SceneError, bundled_scene_path, load_scene
    from channel_worker.worker import ChannelWorker, serve_worker
    from services.grpc_util import configure_logging, stop_on_signals
    from services.rig import RigError, bind_address

    configure_logging(args.verbose)
    rig = _load_rig(args.rig)
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        channel = rig.channel(args.channel)
        sample_pattern(args.samples)
        database = load_scene(args.scene or bundled_scene_path())
    except (RigError, SceneError, ValueError) as exc:
        print(f"ig worker: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    worker = ChannelWorker(database, channel.spec, host_address=rig.host_address,
                           compositor_address=rig.compositor_address, samples=args.samples, once=args.once)
    stop = threading.Event()
    stop_on_signals(stop)
    logging.getLogger("ig.worker").info("worker %s: compiling kernels", channel.name)
    worker.warm_up()
    try:
        serve_worker(worker, bind_address(channel.address, args.bind), stop)
    except OSError as exc:
        print(f"ig worker: error: {exc}", file=sys.stderr)
        return 1
    return EXIT_OK


def cmd_compositor(args) -> int:
    from services.compositor.server import Compositor, serve
    from services.grpc_util import configure_logging, stop_on_signals
    from services.rig import bind_address

    configure_logging(args.verbose)
    rig = _load_rig(args.rig)
    if rig is None:
        return EXIT_BAD_INPUT
    compositor = Compositor(rig.channel_names, Path(args.out), exr_every=args.exr_every)
    stop = threading.Event()
    stop_on_signals(stop)
    try:
        serve(compositor, bind_address(rig.compositor_address, args.bind), rig.host_address, stop,
              once=args.once, grace_s=args.grace)
    except OSError as exc:
        print(f"ig compositor: error: {exc}", file=sys.stderr)
        return 1
    return EXIT_OK


def cmd_demo(args) -> int:
    from services.demo import run_demo
    return run_demo(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ig", description="Distributed multi-channel image generator for flight simulators.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="run host, three workers and the compositor on the bundled flight",
                       description="Start host, one worker per rig channel and the compositor as separate "
                                   "processes on this machine, fly the bundled flight, print the report.")
    p.add_argument("--rate", type=float, default=15.0, help="host frame rate, Hz (default 15)")
    p.add_argument("--duration", type=float, default=20.0, help="simulated seconds to fly (default 20)")
    p.add_argument("--width", type=int, default=None, help="override every channel's width, pixels")
    p.add_argument("--height", type=int, default=None, help="override every channel's height, pixels")
    p.add_argument("--samples", default="4", help="samples per pixel, count or pattern name (default 4)")
    p.add_argument("--exr-every", type=int, default=30, help="write an EXR every N frames (default 30; 0: never)")
    p.add_argument("--out", default="out/demo", help="output directory (default out/demo)")
    p.add_argument("--scene", default=None, help="scene JSON (default: the bundled airfield)")
    p.add_argument("--rig", default=None, help="rig file; its addresses are replaced by free localhost ports")
    p.add_argument("--verbose", action="store_true", help="show the processes' logs")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("render", help="render one frame of one channel to an image file",
                       description="Render one frame of one channel: .exr holds linear RGB and Z (range, "
                                   "metres), .png holds sRGB 8-bit.")
    from channel_worker import cli_render
    cli_render.add_arguments(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("host", help="publish the eyepoints of the bundled flight, frame-locked to the rig",
                       description="Serve HostService: publish frames at a fixed rate, waiting for every "
                                   "channel to acknowledge each frame (docs/frame-lock.md).")
    _rig_argument(p)
    p.add_argument("--rate", type=float, default=60.0, help="frame rate, Hz (default 60)")
    p.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the whole flight)")
    p.add_argument("--sync-timeout", type=float, default=10.0,
                   help="longest wait for every channel's acknowledgement of a frame, seconds (default 10)")
    p.add_argument("--start-timeout", type=float, default=120.0,
                   help="longest wait for every channel and observer to subscribe, seconds (default 120)")
    p.add_argument("--observers", type=int, default=1,
                   help="observers (the compositor) to wait for before the first frame (default 1)")
    p.add_argument("--bind", default=None, help="listen on this interface instead of the rig address (e.g. 0.0.0.0)")
    p.set_defaults(func=cmd_host)

    p = sub.add_parser("worker", help="render one channel of the rig",
                       description="Render one rig channel: subscribe to the host, render the newest frame, "
                                   "submit it to the compositor, acknowledge it to the host.")
    _rig_argument(p)
    p.add_argument("--channel", required=True, help="name of the rig channel to render")
    p.add_argument("--scene", default=None, help="scene JSON (default: the bundled airfield)")
    p.add_argument("--samples", default="4", help="samples per pixel, count or pattern name (default 4)")
    p.add_argument("--once", action="store_true", help="exit when the host's run ends")
    p.add_argument("--bind", default=None, help="listen on this interface instead of the rig address")
    p.set_defaults(func=cmd_worker)

    p = sub.add_parser("compositor", help="gather, check and stitch the channels' images",
                       description="Serve CompositorService: stitch frames every channel delivered with the "
                                   "host's eyepoint, count the rest by cause, write report.json.")
    _rig_argument(p)
    p.add_argument("--out", default="out/compositor", help="output directory (frames/ and report.json)")
    p.add_argument("--exr-every", type=int, default=30, help="write an EXR every N frames (default 30; 0: never)")
    p.add_argument("--once", action="store_true", help="finish and exit when the host's run ends")
    p.add_argument("--grace", type=float, default=5.0,
                   help="at the end of the run, wait this long for open frames, seconds (default 5)")
    p.add_argument("--bind", default=None, help="listen on this interface instead of the rig address")
    p.set_defaults(func=cmd_compositor)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
