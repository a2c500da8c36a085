"""`ig worker`: render one channel of the rig for the host, deliver it to the compositor."""

from __future__ import annotations

import argparse
import logging
import threading

from services.rig.cli_common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    add_metrics_arguments,
    add_rig_arguments,
    add_wire_arguments,
    error,
    load_rig_or_report,
    wire_of,
)
from services.rig.options import add_render_arguments, from_arguments

from .data import SCENES, bundled_or_path

log = logging.getLogger("ig.worker")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig worker`."""
    add_rig_arguments(parser)
    add_metrics_arguments(parser, rig_key="channel's metrics_port")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--channel", help="name of the rig channel to render")
    which.add_argument("--channel-index", type=int, metavar="N",
                       help="render the rig's N-th channel, counting from 0 in the file's order (a Kubernetes "
                            "StatefulSet passes its pod's ordinal)")
    parser.add_argument("--scene", default=None,
                        help="scene JSON (docs/scene-format.md), or a bundled scene's name "
                             f"({', '.join(SCENES)}); default: the rig file's [scene] path, else the "
                             "bundled airfield")
    add_render_arguments(parser)
    add_wire_arguments(parser, compositor=False)
    parser.add_argument("--once", action="store_true",
                        help="exit when the host's run ends (default: wait for the next run)")


def run(args: argparse.Namespace) -> int:
    """Load, warm up, serve and render until the run ends (--once) or SIGTERM.

    Returns 0 ok, 1 cannot listen, 2 bad input (rig, channel, scene, samples, or a host that
    does not know the channel).
    """
    from services.rig.cli_common import metrics_address_of, security_of
    from services.rig.grpc_util import configure_logging, stop_on_signals
    from services.rig.rigfile import RigError, bind_address, scene_path
    from services.rig.threads import size_thread_pool

    configure_logging(args.verbose)
    rig = load_rig_or_report(args.rig, "worker")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        # The thread count before the pipeline is imported: numba sizes its pool once, at its
        # first parallel kernel, from NUMBA_NUM_THREADS (services/rig/threads.py).
        options = from_arguments(args, base=rig.render)
        size_thread_pool(options.threads, setting="--threads" if args.threads is not None else "[render] threads")
    except ValueError as exc:
        error("worker", exc)
        return EXIT_BAD_INPUT
    from channel_worker.pipeline.scene.load import SceneError, bundled_scene_path, load_scene

    from .worker import ChannelWorker, serve_worker

    try:
        if args.channel_index is not None:
            if not 0 <= args.channel_index < len(rig.channels):
                raise RigError(f"--channel-index: {args.channel_index} is not in [0, {len(rig.channels) - 1}] "
                               f"(the rig has {len(rig.channels)} channels)")
            channel = rig.channels[args.channel_index]
        else:
            channel = rig.channel(args.channel)
        # SceneError names the JSON path and value, e.g. "scene.json: sky.colour: '#zzzzzz' ...".
        # --scene over the rig file's [scene] (which host, workers and query service share).
        database = load_scene(scene_path(bundled_or_path(args.scene), rig, bundled_scene_path()))
        security = security_of(rig)
        wire = wire_of(args, rig)
    except (RigError, SceneError, ValueError) as exc:
        error("worker", exc)
        return EXIT_BAD_INPUT
    # Signals first: a SIGTERM during the warm-up stops the worker right after it.
    stop = threading.Event()
    stop_on_signals(stop)
    try:
        worker = ChannelWorker(database, channel.spec, host_address=rig.host_address,
                               compositor_address=rig.compositor_address, options=options, once=args.once,
                               security=security, cigi=rig.cigi.configured, wire=wire)
        serve_worker(worker, bind_address(channel.address, args.bind), stop, security=security,
                     metrics_address=metrics_address_of(args, channel.metrics_port))
    except OSError as exc:
        error("worker", exc)
        return EXIT_FAILED
    if worker.refused:
        error("worker", f"the host refused channel {channel.name!r}: {worker.refused} "
                        f"(do host and worker read the same rig file?)")
        return EXIT_BAD_INPUT
    return EXIT_OK
