"""`ig host`: publish eyepoints frame-locked to the rig's channels.

The eyepoints come from one of:
- the bundled scripted flight (default);
- the flight model flown by cockpit controls (`--controls URL`, repeatable; docs/host-inputs.md),
  the point-mass model or JSBSim (`--fdm jsbsim:AIRCRAFT`; docs/host-flight-model.md);
- a scripted take-off from the bundled airfield's runway (`--fdm` without --controls);
- a flight log (`--replay FILE`; docs/replay-formats.md);
- an external simulation host speaking CIGI (`--cigi udp://HOST:PORT`; docs/cigi.md);
- another simulator's pose stream: FlightGear, JSBSim or X-Plane (`--simhost URL`;
  docs/sim-hosts.md).
"""

from __future__ import annotations

import argparse
import errno
import logging
import math
import socket
import threading

from services.rig.cli_common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    add_metrics_arguments,
    add_rig_arguments,
    error,
    geodetic_point,
    load_rig_or_report,
    non_negative,
    positive,
)
from services.rig.rigfile import PACES, SIMHOST_TIMINGS

log = logging.getLogger("ig.host")

#: Simulated seconds of a run that has no natural end (controls, a looping replay) when no
#: --duration is given: it runs until SIGTERM.
UNTIL_STOPPED_S = 1e9


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig host`."""
    add_rig_arguments(parser)
    add_metrics_arguments(parser, rig_key="[host] metrics_port")
    parser.add_argument("--rate", type=positive, default=60.0,
                        help="frame rate, Hz, with --pace ticks; the most frames a second with --pace acks "
                             "(default 60)")
    parser.add_argument("--pace", choices=list(PACES), default=None,
                        help="how frames are paced (default: the rig file's sync.pace, ticks unless set): "
                             + "; ".join(f"{name}: {what}" for name, what in PACES.items())
                             + " (docs/frame-lock.md)")
    parser.add_argument("--duration", type=non_negative, default=None,
                        help="simulated seconds to publish (default: the whole bundled flight or replay; "
                             "until stopped with --controls or --loop)")
    parser.add_argument("--sync-timeout", type=positive, default=None,
                        help="the swap barrier: longest wait for every channel's acknowledgement of a frame, "
                             "seconds (default: the rig file's sync.frame_timeout_s, 5 unless set)")
    parser.add_argument("--start-timeout", type=non_negative, default=120.0,
                        help="before the first frame, give up on a channel that has neither subscribed nor "
                             "said it is starting for this long, seconds (default 120; a worker whose health "
                             "says NOT_SERVING while it compiles its kernels is waited for)")
    parser.add_argument("--observers", type=int, default=1,
                        help="observers (the compositor) to wait for before the first frame (default 1)")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--controls", action="append", metavar="URL", default=None,
                        help="fly the flight model with this control source; repeat for several, first has "
                             "priority (can://socketcan/can0, can://slcan/dev/ttyACM0@115200, "
                             "serial:///dev/ttyUSB0?baud=115200, canlog:///path/log.asc; docs/host-inputs.md)")
    source.add_argument("--replay", metavar="FILE", default=None,
                        help="replay a flight log (.csv, .igc, .fdr, .ulg; docs/replay-formats.md)")
    source.add_argument("--cigi", metavar="URL", nargs="?", const="", default=None,
                        help="be a CIGI image generator: follow the simulation host whose datagrams arrive "
                             "at udp://HOST:PORT (default: the rig file's cigi.listen, 127.0.0.1:8000 unless "
                             "set); replies go to the host's address on --cigi-host-port (docs/cigi.md)")
    from host_sim.simhost import BACKENDS

    source.add_argument("--simhost", metavar="URL", nargs="?", const="", default=None,
                        help="follow another simulator's pose stream (default: the rig file's simhost.url): "
                             + "; ".join(what for _, _, what in BACKENDS.values()) + " (docs/sim-hosts.md)")
    parser.add_argument("--simhost-timing", choices=list(SIMHOST_TIMINGS), default=None,
                        help="with --simhost, the pose between datagrams (default: the rig file's simhost.timing, "
                             "interpolate unless set): "
                             + "; ".join(f"{name}: {what}" for name, what in SIMHOST_TIMINGS.items()))
    parser.add_argument("--cigi-host-port", type=int, default=None, metavar="PORT",
                        help="with --cigi: the host's UDP port for replies (default: the rig file's "
                             "cigi.host_port, 8001 unless set)")
    parser.add_argument("--cigi-mode", choices=["sync", "async"], default=None,
                        help="with --cigi: synchronous (the IG is the clock) or asynchronous frames (default: "
                             "the rig file's cigi.mode, sync unless set)")
    parser.add_argument("--replay-format", choices=["auto", "csv", "igc", "fdr", "ulog"], default="auto",
                        help="format of --replay (default: from the file name)")
    parser.add_argument("--speed", type=positive, default=1.0,
                        help="replay speed, log seconds per simulated second (default 1)")
    parser.add_argument("--start", type=non_negative, default=0.0,
                        help="replay from this many seconds after the log's first record (default 0)")
    parser.add_argument("--loop", action="store_true", help="replay again from --start after the end of the log")
    parser.add_argument("--replay-origin", type=geodetic_point, default=None, metavar="LAT,LON,H",
                        help="geodetic reference point of the world frame for a geodetic log, degrees and "
                             "metres (default: the log's first fix)")
    parser.add_argument("--report", nargs="?", const="", default=None, metavar="PNG",
                        help="with --replay: print what the replay makes of the log (records read, used, "
                             "interpolated, dropped by cause; coverage per column; attitude source per "
                             "segment; time span; largest gap), plot the replayed track and attitude against "
                             "the log's own values into PNG (default out/replay/<log name>.png) and exit "
                             "without serving")
    parser.add_argument("--fdm", default=None, metavar="MODEL",
                        help="the flight model, flown by --controls, or without them by a scripted take-off "
                             "from the bundled runway: " + "; ".join(_fdm_help()) + " (docs/host-flight-model.md)")
    parser.add_argument("--end-after-silence", type=positive, default=None, metavar="S",
                        help="with --cigi: end the run once the CIGI host, having sent at least one message, "
                             "has sent nothing for S seconds (default: run until SIGTERM or --duration)")
    parser.add_argument("--stale-after", type=positive, default=None, metavar="S",
                        help="flag a control source stale after this many seconds without good input "
                             "(default 0.5; a URL's stale_after= overrides it)")


def end_when_silent(session, silence_s: float, stop: threading.Event, poll_s: float = 0.1) -> None:
    """Set stop once session.silent_for() (seconds since the CIGI host's last message; None
    before its first) exceeds silence_s; return when stop is set either way."""
    while not stop.wait(poll_s):
        silent = session.silent_for()
        if silent is not None and silent > silence_s:
            log.info("the CIGI host has sent nothing for %.1f s (--end-after-silence %g): ending the run",
                     silent, silence_s)
            stop.set()
            return


def _fdm_help() -> list[str]:
    from host_sim.fdm import FDMS
    return list(FDMS.values())


def run(args: argparse.Namespace) -> int:
    """Serve HostService until the run ends or SIGTERM; 0 ok, 1 cannot listen (a port taken), 2 bad
    input (a --cigi or --simhost address that does not resolve or is not this machine's)."""
    from host_sim.publisher import FramePublisher
    from host_sim.server import serve
    from services.rig.cli_common import metrics_address_of, security_of
    from services.rig.grpc_util import configure_logging, stop_on_signals
    from services.rig.rigfile import bind_address

    configure_logging(args.verbose)
    if args.report is not None:
        return _report(args)
    rig = load_rig_or_report(args.rig, "host")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        security = security_of(rig)
    except ValueError as exc:
        error("host", exc)
        return EXIT_BAD_INPUT
    for needs, given, flags in (("--replay", args.replay is not None, (
            ("--replay-format", args.replay_format != "auto"), ("--speed", args.speed != 1.0),
            ("--start", args.start != 0.0), ("--loop", args.loop), ("--replay-origin", args.replay_origin))),
            ("--controls", bool(args.controls), (("--stale-after", args.stale_after is not None),)),
            ("--cigi", args.cigi is not None, (("--cigi-host-port", args.cigi_host_port is not None),
                                               ("--cigi-mode", args.cigi_mode is not None),
                                               ("--end-after-silence", args.end_after_silence is not None))),
            ("--simhost", args.simhost is not None, (("--simhost-timing", args.simhost_timing is not None),))):
        misplaced = [flag for flag, used in flags if used]
        if misplaced and not given:
            error("host", f"{', '.join(misplaced)} only apply with {needs}")
            return EXIT_BAD_INPUT
    if args.fdm is not None and (args.replay is not None or args.cigi is not None):
        error("host", "--fdm only applies with --controls or alone (a scripted take-off)")
        return EXIT_BAD_INPUT
    try:
        if args.cigi is not None:
            eyepoints, source, natural_s = _cigi_source(args, rig, security)
        elif args.simhost is not None:
            eyepoints, source, natural_s = _simhost_source(args, rig)
        else:
            eyepoints, source, natural_s = _eyepoint_source(args, rig, security)
    except ValueError as exc:
        error("host", exc)
        return EXIT_BAD_INPUT
    except OSError as exc:
        flag, url = (("--cigi", args.cigi or rig.cigi.listen) if args.cigi is not None else
                     ("--simhost", args.simhost or rig.simhost.url))
        if isinstance(exc, socket.gaierror) or exc.errno == errno.EADDRNOTAVAIL:
            # A name that does not resolve, or an address that is not this machine's, is a
            # mistyped URL (bad input); a port already taken is the machine's state (failed).
            error("host", f"{flag}: {url!r}: cannot listen there: "
                          f"{'no such host' if isinstance(exc, socket.gaierror) else 'not an address of this machine'}"
                          f" ({exc.strerror or exc})")
            return EXIT_BAD_INPUT
        error("host", f"{flag}: cannot listen: {exc}")
        return EXIT_FAILED
    duration = args.duration if args.duration is not None else (natural_s if math.isfinite(natural_s)
                                                                  else UNTIL_STOPPED_S)
    try:
        try:
            publisher = FramePublisher(source=source, channels=rig.channel_names, rate_hz=args.rate,
                                       duration_s=duration,
                                       sync_timeout_s=args.sync_timeout or rig.sync.frame_timeout_s,
                                       observers=args.observers, start_timeout_s=args.start_timeout,
                                       starting=_worker_starting(rig, security),
                                       pace=args.pace or rig.sync.pace)
        except ValueError as exc:
            error("host", exc)
            return EXIT_BAD_INPUT
        stop = threading.Event()
        stop_on_signals(stop)
        if args.end_after_silence is not None:
            # In sync mode the CIGI host drives every frame: once it has gone, --duration is never
            # reached and the run would wait for SIGTERM.
            threading.Thread(target=end_when_silent, args=(eyepoints.session, args.end_after_silence, stop),
                             name="cigi-silence", daemon=True).start()
        try:
            serve(publisher, bind_address(rig.host_address, args.bind), stop, eyepoints=eyepoints,
                  security=security, metrics_address=metrics_address_of(args, rig.host_metrics_port))
        except OSError as exc:
            error("host", exc)
            return EXIT_FAILED
        _log_summary(eyepoints)
        return EXIT_OK
    finally:
        if hasattr(eyepoints, "close"):
            eyepoints.close()


def _eyepoint_source(args: argparse.Namespace, rig, security):
    """(what the eyepoints come from, eyepoint_at, its natural length in simulated seconds).

    JSBSim flies around the rig file's cigi.origin, on the ground the rig's query channel (the
    CIGI one: [cigi] query_channel, else the first channel) answers (host_sim.fdm.ground).

    Raises:
        ValueError: a control source or log that cannot be opened, a bad --fdm or a missing
            extra (the message names it).
    """
    if args.controls or args.fdm is not None:
        from host_sim.controlled import ControlledFlight
        from host_sim.fdm import RUNWAY_HEADING_DEG, RUNWAY_START_XY_M, open_model, parse_fdm
        from host_sim.fdm.takeoff import ScriptedTakeoff
        from host_sim.inputs import open_source

        spec = parse_fdm(args.fdm or "point-mass")
        ground = None
        if spec.name == "jsbsim":
            from host_sim.fdm.ground import QueryGround
            from host_sim.fdm.jsbsim_model import import_jsbsim

            import_jsbsim()  # a missing extra is said before the ground waits for a worker

            query = rig.channel(rig.cigi.query_channel) if rig.cigi.query_channel else rig.channels[0]
            ground = QueryGround(query.address, start_xy_m=RUNWAY_START_XY_M, security=security,
                                 timeout_s=rig.cigi.query_timeout_s)
        model = open_model(spec, origin=rig.cigi.origin, ground=ground)
        sources = []
        try:
            for url in args.controls or []:
                sources.append(open_source(url, stale_after_s=args.stale_after))
        except ValueError:
            for s in sources:
                s.close()
            model.close()
            raise
        if not sources:
            sources.append(ScriptedTakeoff(model, runway_heading_deg=RUNWAY_HEADING_DEG,
                                           centreline_xy_m=RUNWAY_START_XY_M))
        flight = ControlledFlight(sources, model=model)
        return flight, flight.eyepoint_at, math.inf
    if args.replay is not None:
        from host_sim.replay import Replay, load_track

        track, fmt = load_track(args.replay, format=args.replay_format, origin=args.replay_origin)
        replay = Replay(track, speed=args.speed, start_s=args.start, loop=args.loop, path=args.replay, format=fmt)
        return replay, replay.eyepoint_at, replay.duration_s
    from host_sim.flight import bundled_flight

    scripted = bundled_flight()
    return None, scripted.eyepoint_at, scripted.duration_s


def _cigi_source(args: argparse.Namespace, rig, security):
    """(the CIGI endpoint, its frame_input, no natural end).

    Raises:
        ValueError: a bad --cigi URL or port (named).
        OSError: the UDP port cannot be bound.
    """
    from host_sim.cigi.endpoint import CigiEndpoint, QueryClient, parse_udp_url
    from host_sim.cigi.session import CigiSession
    from services.rig.solar import sun_direction

    spec = rig.cigi
    listen = parse_udp_url(args.cigi or spec.listen)
    host_port = spec.host_port if args.cigi_host_port is None else args.cigi_host_port
    if not 1 <= host_port <= 65535:
        raise ValueError(f"--cigi-host-port: {host_port} is not a port in [1, 65535]")
    query = rig.channel(spec.query_channel) if spec.query_channel else rig.channels[0]
    session = CigiSession(origin=spec.origin, channels={ch.view_id: ch.spec for ch in rig.channels},
                          mode=args.cigi_mode or spec.mode, stale_after_s=spec.stale_after_s, solar=sun_direction,
                          announce=bool(spec.host), initial_pose=spec.start_pose)
    client = QueryClient(query.address, origin=spec.origin, timeout_s=spec.query_timeout_s, security=security)
    endpoint = CigiEndpoint(session, listen, host_port=host_port, queries=client, host=spec.host)
    return endpoint, endpoint.frame_input, math.inf


def _simhost_source(args: argparse.Namespace, rig):
    """(the pose stream's receiver, started; its frame_input; no natural end).

    Raises:
        ValueError: no URL, or a bad URL (named).
        OSError: the UDP port cannot be bound.
    """
    from host_sim.simhost import open_simhost

    spec = rig.simhost
    url = args.simhost or spec.url
    if not url:
        raise ValueError("--simhost: no URL given and the rig file has no simhost.url")
    receiver = open_simhost(url, origin=spec.origin or rig.cigi.origin, eye_offset_m=spec.eye_offset_m,
                            timing=args.simhost_timing or spec.timing, delay_s=spec.delay_s,
                            max_extrapolate_s=spec.max_extrapolate_s, stale_after_s=spec.stale_after_s,
                            rate_hz=args.rate)
    return receiver.start(), receiver.frame_input, math.inf


def _report(args: argparse.Namespace) -> int:
    """`--report`: the replay report and its plot; 0 ok, 1 the plot cannot be written, 2 bad input."""
    from pathlib import Path

    from host_sim.replay import load_track
    from host_sim.replay.report import format_report, plot_replay, replay_report

    if args.replay is None:
        error("host", "--report only applies with --replay")
        return EXIT_BAD_INPUT
    if not args.verbose:
        # The report lists the problems itself; the log would say each twice.
        logging.getLogger("ig.host.replay").setLevel(logging.ERROR)
    try:
        track, fmt = load_track(args.replay, format=args.replay_format, origin=args.replay_origin)
    except ValueError as exc:
        error("host", exc)
        return EXIT_BAD_INPUT
    print(format_report(replay_report(track, path=args.replay, format=fmt)))
    png = Path(args.report or Path("out") / "replay" / f"{Path(args.replay).name}.png")
    try:
        plot_replay(track, png, title=Path(args.replay).name)
    except OSError as exc:
        error("host", f"report plot {png}: {exc}")
        return EXIT_FAILED
    print(f"  plot: {png}")
    return EXIT_OK


def _log_summary(eyepoints) -> None:
    from host_sim.controlled import ControlledFlight
    from host_sim.replay import Replay

    if isinstance(eyepoints, ControlledFlight):
        inputs, model = eyepoints.status()
        for s in inputs:
            refused = {k: v for k, v in s.rejected.items() if v}
            log.info("controls %s: %d accepted, refused %s%s", s.name, s.accepted, refused or "none",
                     ", stale at the end" if s.stale else "")
        log.info("flight model: %d steps, %.1f m/s, %s", model.steps, model.speed_mps,
                 "on the ground" if model.on_ground else "airborne")
    elif isinstance(eyepoints, Replay):
        r = eyepoints.status()
        log.info("replay %s: ended at log time %.2f s after %d loop(s)", r.path, r.log_time_s, r.loops)
    elif eyepoints is not None and hasattr(eyepoints, "session"):
        s = eyepoints.session.status()
        log.info("CIGI host %s (%s %s): %d messages, %d IG frames, refused %s, unused %s, queries %d "
                 "(%d invalid, %d failed), restarts %d", s["host_address"] or "never heard", s["version"],
                 s["byte_order"], s["messages"], s["ig_frames"], s["refused"] or "none", s["unused"] or "none",
                 s["queries_answered"], s["queries_invalid"], s["queries_failed"], s["restarts"])
    elif eyepoints is not None and hasattr(eyepoints, "stream"):
        p = eyepoints.status()
        log.info("simulator %s: %d poses, refused %s, unused %d, frames late %d, extrapolated %d, held %d, "
                 "stale %d time(s)", p.name, p.accepted, p.refused or "none", p.unused, p.late, p.extrapolated,
                 p.held, p.stale_events)


def _worker_starting(rig, security):
    """starting(channel) for FramePublisher: whether the channel's worker answers its health
    service NOT_SERVING (compiling its kernels, rendering its warm-up frame)."""
    import grpc

    from services.rig.grpc_util import check_health

    addresses = {ch.name: ch.address for ch in rig.channels}

    def starting(channel: str) -> bool:
        try:
            return check_health(addresses[channel], timeout_s=0.5, security=security) == "NOT_SERVING"
        except (grpc.RpcError, OSError):
            return False
    return starting

