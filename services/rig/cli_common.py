"""What the `ig` service subcommands share: exit codes, the rig options, logging."""

from __future__ import annotations

import argparse
import math
import sys

from .frame import MAX_CHANNEL_PIXELS
from .grpc_util import Security
from .rigfile import WIRE_FORMATS, Rig, RigError, WireSpec, default_rig_path, load_rig

#: Exit codes of every `ig` subcommand.
EXIT_OK = 0
EXIT_FAILED = 1  # the service ran but could not do its job (address in use, frames lost)
EXIT_BAD_INPUT = 2  # bad option, rig file or scene: nothing was started


def add_rig_arguments(parser: argparse.ArgumentParser, *, bind: bool = True) -> None:
    """--rig, --verbose and (for services that listen) --bind."""
    parser.add_argument("--rig", default=None,
                        help="rig file (docs/rig-format.md); default: the bundled three-channel rig on "
                             "127.0.0.1 (services/rig/data/default_rig.toml)")
    if bind:
        parser.add_argument("--bind", default=None, metavar="ADDR",
                            help="listen on this interface (e.g. 0.0.0.0) at the port of the rig address, "
                                 "instead of the rig address itself")
    parser.add_argument("--verbose", action="store_true", help="log debug messages")


def add_metrics_arguments(parser: argparse.ArgumentParser, *, rig_key: str) -> None:
    """--metrics-port and --metrics-bind: where the process serves its Prometheus metrics
    (docs/metrics.md); rig_key names the rig file's key the port defaults to."""
    parser.add_argument("--metrics-port", type=port_or_off, default=None, metavar="PORT",
                        help=f"serve Prometheus metrics at http://ADDR:PORT/metrics (docs/metrics.md); default: the "
                             f"rig file's {rig_key}, none unless set; 0: none")
    parser.add_argument("--metrics-bind", default=None, metavar="ADDR",
                        help="the interface the metrics listen on (default 127.0.0.1, this machine only; e.g. "
                             "0.0.0.0 for a Prometheus on another machine or container: plain HTTP, counters only)")


def metrics_address_of(args: argparse.Namespace, rig_port: int) -> str | None:
    """host:port of the process's metrics endpoint: --metrics-port over the rig file's port, on
    --metrics-bind (127.0.0.1 by default); None when neither gives a port."""
    from .metrics import metrics_address

    return metrics_address(rig_port if args.metrics_port is None else args.metrics_port, args.metrics_bind)


def port_or_off(text: str) -> int:
    """argparse type: a TCP port in [1, 65535], or 0 for none."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port in [1, 65535], or 0 for none")
    return value


def load_rig_or_report(path: str | None, command: str) -> Rig | None:
    """The rig of --rig (or the default rig); None after printing why it cannot be used."""
    try:
        return load_rig(path or default_rig_path())
    except RigError as exc:
        error(command, exc)
        return None


def security_of(rig: Rig) -> Security:
    """The rig's [tls] table read into a Security (the certificates' bytes).

    Raises:
        ValueError: a certificate file that cannot be read; the message names it.
    """
    return Security.from_files(rig.tls.ca, rig.tls.cert, rig.tls.key, allow_plaintext=rig.tls.allow_plaintext)


def add_wire_arguments(parser: argparse.ArgumentParser, *, compositor: bool) -> None:
    """--wire and --shared-memory / --no-shared-memory, over the rig file's [compositor] wire
    and shared_memory keys (docs/rig-format.md), for a worker or for the compositor."""
    parser.add_argument(
        "--wire", choices=WIRE_FORMATS, default=None,
        help=("the format a frame is stitched in when its channels sent different ones" if compositor else
              "pixel format of the images sent to the compositor: srgb8 (display-ready sRGB bytes, as the PNGs) "
              "or half (linear half floats, for accurate EXR recording)")
        + "; default: the rig file's compositor.wire, srgb8 unless set")
    parser.add_argument(
        "--shared-memory", action=argparse.BooleanOptionalAction, default=None,
        help=("take images from workers on this machine in shared memory (--no-shared-memory: refuse them, the "
              "workers send inline)" if compositor else
              "hand the images to a compositor on this machine in shared memory")
        + "; default: the rig file's compositor.shared_memory, on unless set")


def wire_of(args: argparse.Namespace, rig: Rig) -> WireSpec:
    """The rig file's WireSpec under the command line's --wire and --shared-memory."""
    shared = rig.wire.shared_memory if args.shared_memory is None else args.shared_memory
    return WireSpec(args.wire or rig.wire.format, shared)


def error(command: str, message: object) -> None:
    """Print an error the way every subcommand does: `ig COMMAND: error: ...` on stderr."""
    print(f"ig {command}: error: {message}", file=sys.stderr)


def positive(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = float(text)
    if not (value > 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number > 0")
    return value


def non_negative(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = float(text)
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number >= 0")
    return value


def whole_number(text: str, lo: int, hi: int, unit: str) -> int:
    """What an argparse type of whole numbers does: text as an int in [lo, hi] of unit.

    Raises:
        argparse.ArgumentTypeError: not a whole number, or out of range; the message says which.
    """
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number of {unit}") from None
    if not lo <= value <= hi:
        raise argparse.ArgumentTypeError(f"{text} is not in [{lo}, {hi}] {unit}")
    return value


def pixels(text: str) -> int:
    """argparse type: a whole number of pixels in [1, 16384] (frame.MAX_CHANNEL_PIXELS)."""
    return whole_number(text, 1, MAX_CHANNEL_PIXELS, "pixels")


def field_of_view(text: str) -> float:
    """argparse type: a field of view in degrees, in (0, 178]: a channel's frustum edges stay
    within 89 degrees of its axis (frame.check_channel)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text} is not a number of degrees") from None
    if not 0 < value <= 178:  # also refuses nan
        raise argparse.ArgumentTypeError(f"{text} is not in (0, 178] degrees")
    return value


def geodetic_point(text: str) -> tuple[float, float, float]:
    """argparse type: LAT,LON,H in degrees and metres (WGS-84 latitude within +-90, longitude
    within +-180, a finite height)."""
    try:
        lat, lon, h = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not LAT,LON,H") from None
    if not (abs(lat) <= 90 and abs(lon) <= 180 and math.isfinite(h)):
        raise argparse.ArgumentTypeError(f"{text!r}: latitude must be within +-90, longitude +-180, "
                                         "and the height finite")
    return lat, lon, h

