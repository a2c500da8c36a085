"""Other simulators' pose streams as the rig's eyepoint, opened by URL (docs/sim-hosts.md).

One module per protocol, listed in BACKENDS and imported when its URL is opened; the help
text and errors are read from the same table. stream.py turns the poses into eyepoints at the
rig's frame rate; receiver.py owns the socket and the reader thread.

    from host_sim.simhost import open_simhost

    with open_simhost("fgfs://127.0.0.1:0", origin=(36.6, -84.2, 349.0)) as source:
        port = source.address[1]            # point the simulator here
        source.stream.wait_for(10, timeout_s=5.0)
        pose = source.stream.latest_pose()  # as decoded: lat, lon, alt, heading, pitch, roll
        frame = source.frame_input()        # FrameInput: the eyepoint, its sample time
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from typing import TYPE_CHECKING
from urllib.parse import parse_qsl, urlsplit

if TYPE_CHECKING:  # the package itself stays light: `ig host --help` reads BACKENDS
    from .receiver import UdpPoseSource

#: URL scheme -> (module, class, what the URL means) for --help, errors and docs/sim-hosts.md.
BACKENDS = {
    "fgfs": ("fgfs_native", "FgNetFdmSource",
             "fgfs://HOST:PORT: FlightGear --native-fdm or JSBSim FLIGHTGEAR output (FGNetFDM v24/v25) "
             "arriving at HOST:PORT"),
    "fgfs-generic": ("fgfs_generic", "FgGenericSource",
                     "fgfs-generic://HOST:PORT: FlightGear --generic=...,ig (deploy/flightgear/ig.xml) arriving "
                     "at HOST:PORT"),
    "xplane": ("xplane", "XPlaneSource",
               "xplane://XPHOST:49000[?listen=HOST:PORT&rate=HZ&request=rpos|none]: RPOS requested from "
               "X-Plane, RPOS or DATA rows 17 and 20 read at listen (default any free port)"),
}

#: Options of an xplane:// URL.
_XPLANE_OPTIONS = ("listen", "rate", "request")


def open_simhost(url: str, *, origin: tuple[float, float, float],
                 eye_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 timing: str = "interpolate", delay_s: float = 0.0, max_extrapolate_s: float = 0.1,
                 stale_after_s: float = 1.0, rate_hz: float = 60.0, clock: Callable[[], float] = time.monotonic,
                 wall: Callable[[], float] = time.time) -> UdpPoseSource:
    """Bind the pose stream a URL names (not started: `start()` or a `with` block reads it).

    Args:
        url: a scheme of BACKENDS and its address (module docs, docs/sim-hosts.md).
        origin: the world's (0, 0, 0): latitude, longitude (degrees), height (metres).
        eye_offset_m: the eye from the simulator's reference point, x forward, y right, z down, m.
        timing, delay_s, max_extrapolate_s, stale_after_s: PoseStream's.
        rate_hz: datagrams a second asked of a simulator that takes requests (X-Plane), unless
            the URL's `rate` says otherwise.
        clock, wall: monotonic and UNIX clocks, seconds (tests inject them).

    Raises:
        ValueError: unknown scheme, bad address or option (named, with the URL).
        OSError: the socket cannot be bound.
    """
    from .receiver import parse_address
    from .stream import PoseStream

    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme not in BACKENDS:
        raise ValueError(f"--simhost: {url!r}: unknown scheme {scheme!r} (known: "
                         + "; ".join(what for _, _, what in BACKENDS.values()) + ")")
    if parts.path not in ("", "/"):
        raise ValueError(f"--simhost: {url!r}: a path is not part of a {scheme}:// URL")
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    known = _XPLANE_OPTIONS if scheme == "xplane" else ()
    for key in options:
        if key not in known:
            raise ValueError(f"--simhost: {url!r}: option {key!r} is not one of a {scheme}:// URL"
                             + (f" ({', '.join(known)})" if known else " (it takes none)"))
    address = parse_address(parts.netloc, f"--simhost {url!r}",
                            default_port=49000 if scheme == "xplane" else None)
    stream = PoseStream(url, origin=origin, eye_offset_m=eye_offset_m, timing=timing, delay_s=delay_s,
                        max_extrapolate_s=max_extrapolate_s, stale_after_s=stale_after_s, clock=clock, wall=wall)
    module_name, class_name, _ = BACKENDS[scheme]
    cls = getattr(importlib.import_module(f"{__name__}.{module_name}"), class_name)
    if scheme != "xplane":
        return cls(address, stream)
    listen = parse_address(options.get("listen", "0.0.0.0:0"), f"--simhost {url!r} listen")
    try:
        rate = float(options.get("rate", rate_hz))
    except ValueError:
        rate = -1.0
    if not 1.0 <= rate <= 1000.0:
        raise ValueError(f"--simhost: {url!r}: rate {options.get('rate', rate_hz)!r} is not a number in [1, 1000]")
    request = options.get("request", "rpos")
    if request not in ("rpos", "none"):
        raise ValueError(f"--simhost: {url!r}: request {request!r} is not 'rpos' or 'none'")
    return cls(listen, stream, xplane=address if request == "rpos" else None, rate_hz=rate)
