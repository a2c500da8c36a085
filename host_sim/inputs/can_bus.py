"""CANaerospace controls from a live CAN bus, through any python-can interface.

URL: `can://INTERFACE/CHANNEL[?option=value&...]`, for example

    can://virtual/rig                        python-can's in-process bus: senders in this
                                             process only (tests, one-process demos)
    can://socketcan/can0                     Linux SocketCAN
    can://slcan/dev/ttyACM0@115200           CAN over serial (LAWICEL/slcan adapters)
    can://udp_multicast/239.74.163.2         CAN over UDP multicast between processes and
                                             machines (needs msgpack: the devices extra)

CHANNEL is the URL path without its leading slash, except that a device path keeps it
(`dev/ttyACM0` -> `/dev/ttyACM0`); a pyserial URL works as an slcan channel
(`can://slcan/loop://`). `slcan:///dev/ttyACM0?tty_baudrate=115200` is short for the slcan form.
Options go to python-can's Bus (OPTIONS lists those accepted) plus `stale_after` (seconds).
"""

from __future__ import annotations

import logging
from typing import Any

from . import canaerospace
from .base import ControlSource, Rejected

log = logging.getLogger("ig.host.inputs")

#: python-can Bus options a URL may set, with their types. Anything else is refused by name,
#: since python-can itself silently ignores options an interface does not know.
OPTIONS: dict[str, type] = {
    "bitrate": int, "data_bitrate": int, "fd": bool, "tty_baudrate": int, "rtscts": bool,
    "listen_only": bool, "sleep_after_open": float, "receive_own_messages": bool, "port": int,
    "hop_limit": int, "preserve_timestamps": bool,
}

#: Most frames one poll() reads: a babbling node must not starve the simulation step.
MAX_FRAMES_PER_POLL = 10_000


def bus_options(options: dict[str, str]) -> dict[str, Any]:
    """python-can keyword arguments from URL query options (already stripped of stale_after).

    Raises:
        ValueError: an option is not in OPTIONS or its value is not of its type.
    """
    out: dict[str, Any] = {}
    for key, text in options.items():
        kind = OPTIONS.get(key)
        if kind is None:
            raise ValueError(f"option {key!r} is not a CAN bus option ({', '.join(sorted(OPTIONS))})")
        try:
            if kind is bool:
                if text.lower() not in ("1", "0", "true", "false", "yes", "no"):
                    raise ValueError(text)
                out[key] = text.lower() in ("1", "true", "yes")
            else:
                out[key] = kind(text)
        except ValueError:
            raise ValueError(f"option {key}: {text!r} is not a {kind.__name__}") from None
    return out


def frame_value(msg: Any) -> tuple[canaerospace.Signal, float]:
    """The control signal and value of one python-can Message.

    Raises:
        Rejected: bad_frame for error and remote frames, else as canaerospace.decode.
    """
    if msg.is_error_frame or msg.is_remote_frame:
        kind = "error" if msg.is_error_frame else "remote"
        raise Rejected("bad_frame", f"{kind} frame with identifier {msg.arbitration_id}")
    return canaerospace.decode(msg.arbitration_id, bytes(msg.data), extended=msg.is_extended_id)


class CanSource(ControlSource):
    """Reads CANaerospace control frames from a python-can bus (module doc for the URL).

    Args:
        name: the URL.
        interface: python-can interface name (socketcan, slcan, virtual, udp_multicast, ...).
        channel: the interface's channel.
        options: further python-can Bus keyword arguments.
        **kw: ControlSource arguments (stale_after_s, clock).

    Raises:
        ValueError: python-can does not know the interface, or the bus cannot be opened
            (the message names both).
    """

    def __init__(self, name: str, *, interface: str, channel: str, options: dict[str, Any] | None = None,
                 **kw: Any) -> None:
        super().__init__(name, **kw)
        import can  # optional dependency (the `devices` extra), imported only when used

        options = dict(options or {})
        if interface == "slcan":
            # python-can's slcan reads the adapter a byte at a time and, when nothing is waiting,
            # blocks for its serial timeout (1 ms by default): 1 ms of every flight-model step,
            # 7 ms of a frame at 15 Hz, on the way from the controls to the picture. The host
            # polls, so it never needs to wait.
            options.setdefault("timeout", 0.0)
        try:
            self.bus = can.Bus(interface=interface, channel=channel, **options)
        except (can.CanError, ValueError, OSError, ImportError, NotImplementedError) as exc:
            raise ValueError(f"{name}: cannot open CAN interface {interface!r} channel {channel!r}: {exc}") from exc
        self._can = can

    def _read(self, now_s: float | None) -> None:
        for _ in range(MAX_FRAMES_PER_POLL):
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            self.handle(msg, now_s)

    def handle(self, msg: Any, now_s: float | None = None) -> None:
        """Check one python-can Message and accept its value or count why not."""
        self._count("frames")
        try:
            signal, value = frame_value(msg)
        except Rejected as rejection:
            self._reject(rejection)
            return
        self._accept(signal.name, value, now_s)

    def close(self) -> None:
        self.bus.shutdown()
