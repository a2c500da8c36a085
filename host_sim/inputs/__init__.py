"""Cockpit control inputs, opened by URL: one ControlSource interface, one backend per module.

    can://INTERFACE/CHANNEL    CANaerospace over any python-can interface      can_bus.py
    slcan://DEVICE             short for can://slcan/DEVICE                    can_bus.py
    canlog://PATH              a recorded .asc/.blf/.trc log at recorded timing can_log.py
    serial://DEVICE            panel frames from a serial device               serial_panel.py
    serial+PYSERIAL_URL        panel frames from any pyserial URL (loop://)    serial_panel.py

Every URL takes `stale_after=SECONDS`. The backends import python-can and pyserial (the
`devices` extra) only when a URL of theirs is opened. docs/host-inputs.md has the details.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from urllib.parse import parse_qsl, urlencode, urlsplit

from .base import CAUSES, STALE_AFTER_S, Controls, ControlSource, Rejected, SourceStatus

__all__ = [
    "CAUSES",
    "SCHEMES",
    "STALE_AFTER_S",
    "ControlSource",
    "Controls",
    "Rejected",
    "SourceStatus",
    "open_source",
]

#: URL scheme -> what it opens (for messages and --help).
SCHEMES = {
    "can": "can://INTERFACE/CHANNEL (python-can: socketcan, slcan, udp_multicast between processes, "
           "virtual within one process only, ...)",
    "slcan": "slcan://DEVICE (CAN over serial; same as can://slcan/DEVICE)",
    "canlog": "canlog://PATH (.asc, .blf, .trc replayed at recorded timing)",
    "serial": "serial://DEVICE?baud=N (panel frames, docs/serial-protocol.md)",
    "serial+": "serial+PYSERIAL_URL (panel frames over loop://, socket://, rfc2217://, ...)",
}


def open_source(url: str, *, stale_after_s: float | None = None,
                clock: Callable[[], float] = time.monotonic) -> ControlSource:
    """Open the control source a URL names.

    Args:
        url: see the module doc and docs/host-inputs.md.
        stale_after_s: default silence before the source is flagged stale, seconds; the
            URL's `stale_after` option overrides it.
        clock: monotonic clock of live devices, seconds (tests pass a fake one).

    Raises:
        ValueError: unknown scheme, malformed URL, unknown or bad option, or a device that
            cannot be opened; the message names the URL and what is wrong.
    """
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    stale = options.pop("stale_after", None)
    try:
        stale_s = float(stale) if stale is not None else (stale_after_s or STALE_AFTER_S)
    except ValueError:
        raise ValueError(f"{url}: stale_after={stale!r} is not a number of seconds") from None
    kw = {"stale_after_s": stale_s}
    try:
        if scheme in ("can", "slcan"):
            from .can_bus import CanSource, bus_options
            if scheme == "slcan":
                interface, channel = "slcan", _device(parts.netloc + parts.path)
            else:
                interface, channel = parts.netloc, _channel(parts.path)
            if not interface or not channel:
                raise ValueError("expected can://INTERFACE/CHANNEL")
            return CanSource(url, interface=interface, channel=channel, options=bus_options(options),
                             clock=clock, **kw)
        if scheme == "canlog":
            from .can_log import CanLogSource
            _no_options(options, "stale_after")
            path = parts.netloc + parts.path
            if not path:
                raise ValueError("expected canlog://PATH")
            return CanLogSource(url, path=path, **kw)
        if scheme == "serial" or scheme.startswith("serial+"):
            from .serial_panel import DEFAULT_BAUD, SerialPanelSource
            baud_text = options.pop("baud", str(DEFAULT_BAUD))
            try:
                baud = int(baud_text)
            except ValueError:
                raise ValueError(f"baud={baud_text!r} is not a whole number") from None
            if scheme == "serial":
                _no_options(options, "baud, stale_after")
                port_url = _device(parts.netloc + parts.path)
                if not port_url:
                    raise ValueError("expected serial://DEVICE")
            else:
                # The rest is pyserial's URL, with its own options (ours removed).
                port_url = url[len("serial+"):].split("?", 1)[0]
                if options:
                    port_url += "?" + urlencode(options)
            return SerialPanelSource(url, port_url=port_url, baud=baud, clock=clock, **kw)
    except ValueError as exc:
        message = str(exc)
        raise ValueError(message if message.startswith(url) else f"{url}: {message}") from None
    raise ValueError(f"{url}: unknown control source scheme {parts.scheme!r}; expected one of: "
                     + "; ".join(SCHEMES.values()))


def _channel(path: str) -> str:
    """A python-can channel from a URL path: `/can0` -> `can0`, `/dev/ttyACM0@115200` -> itself,
    `/loop://` -> `loop://`."""
    rest = path[1:] if path.startswith("/") else path
    return "/" + rest if "/" in rest and "://" not in rest else rest


def _device(path: str) -> str:
    """A serial device from a URL's netloc + path: `/dev/ttyUSB0` stays, `/COM3` -> `COM3`."""
    return path[1:] if re.fullmatch(r"/COM\d+", path, re.IGNORECASE) else path


def _no_options(options: dict[str, str], accepted: str) -> None:
    if options:
        raise ValueError(f"unknown option(s) {', '.join(sorted(options))} (accepted: {accepted})")
