"""The `ig` command: one entry point for every process of the rig.

Each subcommand's options and behaviour live in its own module (`add_arguments(parser)` and
`run(args) -> int`); this module only routes.

Exit codes: 0 ok, 1 the command ran but failed, 2 bad input (options, rig file, scene).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

#: Subcommand -> (module with add_arguments and run, one-line help, description).
COMMANDS = {
    "demo": ("services.demo", "run host, one worker per channel and the compositor on this machine",
             "Start host, one worker per rig channel and the compositor as separate processes on this "
             "machine, fly the bundled flight (or a flight log: --replay) on the bundled scene, show progress, "
             "print the report and the time to the first stitched frame. Every process started is stopped on "
             "exit, on error and on Ctrl-C."),
    "latency": ("services.latency", "measure the rig's transport delay: pitch steps on a CAN bus to the composite",
                "Start the rig as ig demo does, with the host flown by CANaerospace controls on an slcan CAN "
                "adapter played by this command; step the pitch control, find the first composite whose "
                "picture shows each response, and report control-to-composite delay (p50/p95/p99/max), its "
                "hops along the frame's way, and the FAA 14 CFR Part 60 transport-delay limits "
                "(docs/latency.md)."),
    "render": ("channel_worker.cli_render", "render one frame of one channel to an image file",
               "Render one frame of one channel of a scene (by default the demo's world, the airfield on the "
               "bundled terrain; --scene airfield for the flat airfield alone): .exr holds linear RGB and Z "
               "(range, metres), .png holds sRGB 8-bit."),
    "host": ("host_sim.cli_host", "publish eyepoints frame-locked to the rig: the bundled flight, a flight model "
             "flown by CAN/serial controls, or a replayed flight log",
             "Serve HostService: publish frames at a fixed rate, or paced by the rig (--pace acks), waiting for "
             "every channel to acknowledge each frame (docs/frame-lock.md). Serves gRPC health; SIGTERM stops "
             "it cleanly."),
    "status": ("host_sim.cli_status", "print a running host's status as JSON",
               "Ask the rig's host for its status (GetHostStatus): frames published, acknowledgements, the "
               "eyepoint source and, following a CIGI host, its version, messages, packets used and unused, "
               "queries, staleness and restarts (docs/cigi.md)."),
    "cigi-host": ("host_sim.cli_cigi_host", "play a scripted CIGI 3.3 host over UDP against an IG",
                  "Send IG Control and ownship Entity Control once per Start of Frame (or on a clock with "
                  "--async-rate), with HAT/HOT and LOS requests at scripted frames; report what the IG sent."),
    "worker": ("channel_worker.cli_worker", "render one channel of the rig",
               "Render one rig channel: compile the kernels, subscribe to the host, render the newest frame, "
               "submit it to the compositor, acknowledge it to the host. Serves gRPC health and "
               "ChannelWorkerService status at its rig address; SIGTERM stops it cleanly."),
    "compositor": ("services.compositor.cli", "gather, check and stitch the channels' images",
                   "Serve CompositorService: stitch the frames every channel delivered with the host's "
                   "eyepoint, count the rest by cause, write frames/ and report.json. Serves gRPC health; "
                   "SIGTERM finalises open frames, writes the report and stops."),
    "compile": ("channel_worker.cli_compile", "compile the render kernels once for every worker of this machine",
                "Render one tiny frame of the scene with the workers' options, so that the kernels are compiled "
                "into the cache every worker of this machine loads them from (channel_worker/pipeline/"
                "kernel_cache.py); ig demo runs it before the rig starts."),
    "certs": ("services.rig.cli_certs", "make a test CA and one TLS certificate per service of a rig",
              "Make a certificate authority and, for the host, the compositor and each channel of the rig, a "
              "certificate (server and client) whose subjectAltName covers its rig address, into --out; print "
              "the rig file's [tls] table (docs/security.md). Existing files are kept unless --force."),
    "terrain": ("channel_worker.cli_terrain", "build a voxel terrain database offline, or describe one",
                "Build the voxel terrain database of the ground (levels averaged 2 x 2, pages of voxels, a "
                "page table per level; docs/terrain-database.md) from an elevation source, or describe a "
                "built one."),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The `ig` parser: every subcommand listed, and the options of `command` (of every
    subcommand when None). Only that subcommand's module is imported, so `ig host` does not
    load the renderer (numba) it never uses."""
    parser = argparse.ArgumentParser(
        prog="ig", description="Distributed multi-channel image generator for flight simulators. "
                               "Exit codes: 0 ok, 1 failed, 2 bad input.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (module_name, help_, description) in COMMANDS.items():
        p = sub.add_parser(name, help=help_, description=description)
        if command is None or name == command:
            module = importlib.import_module(module_name)
            module.add_arguments(p)
            p.set_defaults(run=module.run)
    return parser


#: Exit code when the output's reader has gone (128 + SIGPIPE, as shells report it).
EXIT_BROKEN_PIPE = 141


def main(argv: list[str] | None = None) -> int:
    """Parse argv (default sys.argv[1:]) and run the subcommand; returns its exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    args = build_parser(command if command in COMMANDS else None).parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except BrokenPipeError:
        # The reader of the output went away (`ig host --replay LOG --report | head`): what is
        # left to print has nowhere to go, which is no error of the command's. stdout goes to
        # /dev/null so that Python's flush at exit does not raise again (the Python
        # documentation's recipe for SIGPIPE); 141 is what a shell reports for SIGPIPE.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
