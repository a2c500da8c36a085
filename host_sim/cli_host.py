"""`ig host`: publish the bundled flight's eyepoints, frame-locked to the rig's channels."""

from __future__ import annotations

import argparse
import threading

from services.cli_common import (EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, add_rig_arguments, error,
                                 load_rig_or_report, non_negative, positive)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig host`."""
    add_rig_arguments(parser)
    parser.add_argument("--rate", type=positive, default=60.0, help="frame rate, Hz (default 60)")
    parser.add_argument("--duration", type=non_negative, default=None,
                        help="simulated seconds to publish (default: the whole bundled flight)")
    parser.add_argument("--sync-timeout", type=positive, default=10.0,
                        help="longest wait for every channel's acknowledgement of a frame, seconds (default 10)")
    parser.add_argument("--start-timeout", type=non_negative, default=120.0,
                        help="longest wait for every channel and observer to subscribe before the first "
                             "frame, seconds (default 120)")
    parser.add_argument("--observers", type=int, default=1,
                        help="observers (the compositor) to wait for before the first frame (default 1)")


def run(args: argparse.Namespace) -> int:
    """Serve HostService until the run ends or SIGTERM; 0 ok, 1 cannot listen, 2 bad input."""
    from host_sim.flight import bundled_flight
    from host_sim.publisher import FramePublisher
    from host_sim.server import serve
    from services.grpc_util import configure_logging, stop_on_signals
    from services.rig import bind_address

    configure_logging(args.verbose)
    rig = load_rig_or_report(args.rig, "host")
    if rig is None:
        return EXIT_BAD_INPUT
    flight = bundled_flight()
    duration = flight.duration_s if args.duration is None else args.duration
    try:
        publisher = FramePublisher(source=flight.eyepoint_at, channels=rig.channel_names, rate_hz=args.rate,
                                   duration_s=duration, sync_timeout_s=args.sync_timeout,
                                   observers=args.observers, start_timeout_s=args.start_timeout)
    except ValueError as exc:
        error("host", exc)
        return EXIT_BAD_INPUT
    stop = threading.Event()
    stop_on_signals(stop)
    try:
        serve(publisher, bind_address(rig.host_address, args.bind), stop)
    except OSError as exc:
        error("host", exc)
        return EXIT_FAILED
    return EXIT_OK
