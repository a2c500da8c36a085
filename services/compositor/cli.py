"""`ig compositor`: gather, check and stitch the channels' images; write frames and report.json."""

from __future__ import annotations

import argparse
import ipaddress
import logging
import re
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from services.rig.cli_common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    add_metrics_arguments,
    add_rig_arguments,
    add_wire_arguments,
    error,
    load_rig_or_report,
    non_negative,
    port_or_off,
    positive,
    wire_of,
)
from services.rig.rigfile import Rig

if TYPE_CHECKING:
    from .liveview.endpoint import ViewSpec

log = logging.getLogger("ig.compositor")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig compositor`."""
    add_rig_arguments(parser)
    add_metrics_arguments(parser, rig_key="[compositor] metrics_port")
    parser.add_argument("--out", default="out/compositor",
                        help="output directory: runs/<run id>/frames/frame_NNNNNN.png (and .exr) and "
                             "runs/<run id>/report.json for every run of the host, latest -> the newest run "
                             "(default out/compositor)")
    parser.add_argument("--record-every", type=every, default=1,
                        help="write the stitched frame as PNG every N frames (default 1; 0: never). Recording "
                             "never holds the rig up: a frame due while the writer is behind is left out and "
                             "counted (frames_not_recorded in report.json)")
    parser.add_argument("--record-per-s", type=non_negative, default=0.0, metavar="HZ",
                        help="instead of --record-every: write a PNG of the first frame of every 1/HZ "
                             "simulated seconds (for a rig whose frame rate is not known in advance, such "
                             "as one paced by its frame lock; default 0: by --record-every)")
    parser.add_argument("--exr-every", type=every, default=30,
                        help="also write a linear half-float EXR every N frames (default 30; 0: never); from srgb8 "
                             "channels it holds their 8-bit levels decoded to linear (quantised: --wire half on "
                             "the workers for accurate EXRs)")
    parser.add_argument("--pending-timeout", type=positive, default=None,
                        help="a frame still missing images this many seconds after it was published is "
                             "finalised as incomplete (default: the rig file's sync.pending_timeout_s, 10 unless "
                             "set; keep it above the host's swap-barrier timeout)")
    add_wire_arguments(parser, compositor=True)
    add_view_arguments(parser)
    parser.add_argument("--once", action="store_true",
                        help="finish, write the run's report.json and exit when the host's run ends (default: "
                             "follow run after run until SIGTERM)")
    parser.add_argument("--grace", type=non_negative, default=5.0,
                        help="at the end of the run, wait this long for images of open frames, seconds "
                             "(default 5)")


def add_view_arguments(parser: argparse.ArgumentParser) -> None:
    """--view-port and --view-bind: where the compositor serves its live view (docs/live-view.md)."""
    parser.add_argument("--view-port", type=port_or_off, default=None, metavar="PORT",
                        help="serve the live view, the stitched panorama and the rig's state in a browser, at "
                             "http://ADDR:PORT/ (https under the rig file's [tls]; docs/live-view.md); default: "
                             "the rig file's [compositor] view_port, none unless set; 0: none")
    parser.add_argument("--view-bind", type=interface, default=None, metavar="ADDR",
                        help="the interface the live view listens on (default 127.0.0.1, this machine only; "
                             "another needs the rig file's [tls] table or tls.allow_plaintext)")


def interface(text: str) -> str:
    """argparse type: an interface to listen on, an IP address or a host name."""
    try:
        ipaddress.ip_address(text.strip("[]"))
        return text.strip("[]")
    except ValueError:
        pass
    if not _HOST_NAME.fullmatch(text):
        raise argparse.ArgumentTypeError(f"{text!r} is not an IP address or a host name")
    return text


#: A host name (RFC 1123): dot-separated labels of letters, digits and inner hyphens.
_HOST_NAME = re.compile(r"(?=.{1,253}$)([A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}"
                        r"[A-Za-z0-9])?)*")


def view_of(args: argparse.Namespace, rig: Rig) -> ViewSpec | None:
    """Where the live view listens: --view-port over the rig file's [compositor] view_port, on
    --view-bind (127.0.0.1 by default), over HTTPS with the rig's certificate under its [tls]
    table; None when neither gives a port."""
    from .liveview.endpoint import ViewSpec, view_address

    address = view_address(rig.compositor_view_port if args.view_port is None else args.view_port, args.view_bind)
    if address is None:
        return None
    certificate = (rig.tls.cert, rig.tls.key) if rig.tls.cert else None
    return ViewSpec(address, certificate, rig.tls.allow_plaintext)


def every(text: str) -> int:
    """argparse type: a period in frames, a whole number >= 0 (0: never)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number of frames") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text} is not >= 0 (0: never)")
    return value


def run(args: argparse.Namespace) -> int:
    """Serve CompositorService until the run ends (--once) or SIGTERM; 0 ok, 1 failed, 2 bad input."""
    from services.rig.cli_common import metrics_address_of, security_of
    from services.rig.grpc_util import configure_logging, stop_on_signals
    from services.rig.memory import return_freed_memory
    from services.rig.rigfile import bind_address

    from .blend import blend_plan, write_masks
    from .server import Compositor, serve

    configure_logging(args.verbose)
    rig = load_rig_or_report(args.rig, "compositor")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        security = security_of(rig)
    except ValueError as exc:
        error("compositor", exc)
        return EXIT_BAD_INPUT
    # Frames of a dead channel's rig come and go by the megabyte: hand freed images back to the
    # system at once, so the compositor's memory comes down when the channel is back.
    return_freed_memory()
    specs = [ch.spec for ch in rig.channels]
    plan = blend_plan(specs, rig.blend)
    # The seam check (docs/edge-blending.md): how every pair of adjacent channels meets, from the
    # rig file alone; a misaligned seam is reported at start and in every run's report.
    seams = plan.report()
    for seam in plan.seams:
        if not seam.ok:
            log.warning("seam %s | %s is misaligned beyond %g degrees: %s", seam.left, seam.right,
                        rig.blend.tolerance_deg, seam.as_dict())
    if plan.blends:
        try:
            write_masks(plan, Path(args.out) / "masks")
        except OSError as exc:
            error("compositor", f"--out: {exc}")
            return EXIT_FAILED
    compositor = Compositor(rig.channel_names, Path(args.out), record_every=args.record_every,
                            exr_every=args.exr_every, record_per_s=args.record_per_s,
                            pending_timeout_s=args.pending_timeout or rig.sync.pending_timeout_s,
                            sizes={s.name: (s.width, s.height) for s in specs},
                            max_pending_frames=rig.sync.max_pending_frames,
                            max_pending_bytes=int(rig.sync.max_pending_mib * 2**20),
                            plan=plan if plan.blends else None, seams=seams, wire=wire_of(args, rig))
    stop = threading.Event()
    stop_on_signals(stop)
    # The largest message: the largest channel image (half-float RGB) and the request's fields.
    largest = max(s.width * s.height * 6 for s in specs) + 64 * 1024
    try:
        serve(compositor, bind_address(rig.compositor_address, args.bind), rig.host_address, stop,
              once=args.once, grace_s=args.grace, security=security, max_receive_bytes=largest,
              metrics_address=metrics_address_of(args, rig.compositor_metrics_port), view=view_of(args, rig))
    except OSError as exc:
        error("compositor", exc)
        return EXIT_FAILED
    return EXIT_OK
