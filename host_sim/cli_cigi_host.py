"""`ig cigi-host`: play a scripted CIGI 3.3 host over UDP against an IG (host_sim/cigi/scripted_host.py).

Exit codes: 0 it ran (synchronous mode: at least one Start of Frame arrived), 1 no SOF arrived,
2 bad input.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from services.rig.cli_common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    add_rig_arguments,
    error,
    geodetic_point,
    load_rig_or_report,
    positive,
    whole_number,
)

log = logging.getLogger("ig.cigi_host")


def _address(text: str) -> tuple[str, int]:
    """argparse type: HOST:PORT of a UDP socket."""
    from host_sim.cigi.endpoint import parse_udp_url

    if ":" not in text:
        raise argparse.ArgumentTypeError(f"address {text!r} is not HOST:PORT")
    try:
        return parse_udp_url(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"address {text!r} is not HOST:PORT") from None


def _frames(text: str) -> int:
    return whole_number(text, 1, 2**31 - 1, "frames")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig cigi-host`."""
    add_rig_arguments(parser, bind=False)
    parser.add_argument("--ig", type=_address, default=None,
                        help="the IG's CIGI address HOST:PORT (default: the rig file's cigi.listen, "
                             "127.0.0.1:8000 unless set)")
    parser.add_argument("--bind", type=_address, default=None,
                        help="this host's address HOST:PORT (default: 127.0.0.1 and the rig file's "
                             "cigi.host_port, 8001 unless set)")
    parser.add_argument("--script", default=None, metavar="FILE",
                        help="JSON script: path keyframes and queries (default: 2 km straight and level at "
                             "300 m above --origin, HOT every 10 frames, LOS straight down)")
    parser.add_argument("--origin", type=geodetic_point, default=None,
                        help="origin of the built-in script LAT,LON,H (degrees, metres; default: the rig "
                             "file's cigi.origin, the bundled airfield unless set)")
    parser.add_argument("--frames", type=_frames, default=600, help="host frames to send (default 600)")
    parser.add_argument("--byte-order", choices=["little", "big"], default="little",
                        help="byte order of what the host sends (default little, as x86 CCL hosts)")
    parser.add_argument("--async-rate", type=positive, default=None, metavar="HZ",
                        help="send on the host's own clock at HZ (asynchronous mode) instead of one message per SOF")
    parser.add_argument("--sof-timeout", type=positive, default=5.0,
                        help="synchronous mode: stop when no SOF arrives for this long, seconds (default 5)")
    parser.add_argument("--start-timeout", type=positive, default=300.0,
                        help="synchronous mode: wait this long for the first SOF, seconds, sending the first "
                             "message again every half second (default 300: workers compile before the "
                             "first frame)")
    parser.add_argument("--report", default=None, metavar="FILE",
                        help="write what the host received as JSON (SOF count, responses by kind, last IG frame)")


def run(args: argparse.Namespace) -> int:
    """Run the scripted host; see the module docstring for exit codes."""
    from host_sim.cigi.endpoint import parse_udp_url
    from host_sim.cigi.scripted_host import Script, ScriptedHost, default_script

    rig = load_rig_or_report(args.rig, "cigi-host")
    if rig is None:
        return EXIT_BAD_INPUT
    args.ig = args.ig or parse_udp_url(rig.cigi.listen)
    args.bind = args.bind or ("127.0.0.1", rig.cigi.host_port)
    args.origin = args.origin or rig.cigi.origin
    try:
        script = (Script.from_json(Path(args.script).read_text()) if args.script
                  else default_script(args.origin))
    except (OSError, ValueError) as exc:
        error("cigi-host", f"--script {args.script}: {exc}")
        return EXIT_BAD_INPUT
    try:
        host = ScriptedHost(script, ig_address=args.ig, bind=args.bind,
                            byte_order="<" if args.byte_order == "little" else ">", async_rate_hz=args.async_rate)
    except OSError as exc:
        error("cigi-host", f"--bind {args.bind[0]}:{args.bind[1]}: {exc}")
        return EXIT_BAD_INPUT
    with host:
        host.run(frames=args.frames, sof_timeout_s=args.sof_timeout, start_timeout_s=args.start_timeout)
        report = host.report()
    text = json.dumps(report, indent=1)
    if args.report:
        Path(args.report).write_text(text + "\n")
    print(text)
    if args.async_rate is None and report["sof_count"] == 0:
        error("cigi-host", f"no Start of Frame from {args.ig[0]}:{args.ig[1]} within {args.start_timeout} s")
        return EXIT_FAILED
    return EXIT_OK
