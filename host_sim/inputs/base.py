"""The ControlSource interface and the bookkeeping every backend shares (docs/host-inputs.md).

A backend turns bytes or CAN frames into (signal, value) pairs and hands each one to
`ControlSource._accept`, or names why it refused it with `_reject`. The base class keeps the
last good value of every signal (a refused or missing input never changes it), counts the
refusals by cause, and flags the source as stale when nothing good arrived for `stale_after_s`.
Every method is safe to call from the publisher thread and the gRPC status thread at once.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field

log = logging.getLogger("ig.host.inputs")

#: Why an input was refused. Each is a key of SourceStatus.rejected (and of GetHostStatus).
CAUSES = (
    "bad_length",          # CAN DLC or serial payload length does not fit the data type / record size
    "unknown_identifier",  # identifier not in the control table (or a 29-bit identifier)
    "wrong_data_type",     # CANaerospace data type is not the table's for that identifier
    "not_finite",          # NaN or infinity
    "out_of_range",        # finite but outside the signal's range
    "bad_crc",             # serial frame whose CRC-16 does not match
    "bad_frame",           # serial bytes outside any frame, CAN remote/error frames, unparsable log records
    "stale",               # the source went silent for longer than stale_after_s (counted once per silence)
    "device_error",        # the device or log failed to read (unplugged adapter, I/O error)
)

#: Default silence after which a source is flagged stale, seconds. Panels and CANaerospace
#: nodes send their controls at 20 Hz or more (a serial panel sends an empty heartbeat frame
#: when nothing changes), so half a second is ten missed updates.
STALE_AFTER_S = 0.5

#: Refusals logged per source before the log goes quiet (the counters keep counting).
_LOGGED_REJECTIONS = 20


class Rejected(ValueError):
    """An input refused for one of CAUSES; detail names the field and value."""

    def __init__(self, cause: str, detail: str) -> None:
        assert cause in CAUSES, cause
        super().__init__(f"{cause}: {detail}")
        self.cause = cause
        self.detail = detail


@dataclass(frozen=True)
class Controls:
    """Cockpit control positions, as the flight model reads them.

    Attributes:
        pitch: -1 (stick fully forward) .. +1 (fully aft).
        roll: -1 (full left) .. +1 (full right).
        yaw: -1 (full left pedal) .. +1 (full right pedal).
        throttle: 0 (idle) .. 1 (full), the mean of the throttle levers received so far.
        flaps: 0 (retracted) .. 1 (fully extended) flaps lever.
        speed_brake: 0 (retracted) .. 1 (fully extended) speed brake lever.
        park_brake: 0 released, 1 set.
        brake_left, brake_right: 0 (released) .. 1 (fully pressed) toe brakes on the rudder
            pedals: pressed apart, they turn the aircraft on the ground (differential braking).
    """

    pitch: float = 0.0
    roll: float = 0.0
    yaw: float = 0.0
    throttle: float = 0.0
    flaps: float = 0.0
    speed_brake: float = 0.0
    park_brake: float = 0.0
    brake_left: float = 0.0
    brake_right: float = 0.0


#: Signal name (see canaerospace.CONTROLS) -> Controls field; the throttle levers are averaged.
SIGNAL_FIELDS = {
    "pitch_control_position": "pitch",
    "roll_control_position": "roll",
    "yaw_control_position": "yaw",
    "throttle_1_lever_position": "throttle",
    "throttle_2_lever_position": "throttle",
    "throttle_3_lever_position": "throttle",
    "throttle_4_lever_position": "throttle",
    "flaps_lever_position": "flaps",
    "speed_brake_lever_position": "speed_brake",
    "park_brake_lever_position": "park_brake",
    "left_brake_pedal_position": "brake_left",
    "right_brake_pedal_position": "brake_right",
}


def controls_of(values: dict[str, float]) -> Controls:
    """Controls from last good values by signal name; signals never received keep the defaults."""
    fields: dict[str, float] = {}
    levers = [v for name, v in sorted(values.items()) if SIGNAL_FIELDS.get(name) == "throttle"]
    if levers:
        fields["throttle"] = sum(levers) / len(levers)
    for name, value in values.items():
        target = SIGNAL_FIELDS.get(name)
        if target and target != "throttle":
            fields[target] = value
    return Controls(**fields)


@dataclass
class SourceStatus:
    """Counters of one control source (mirrors ig.v1.InputSourceStatus).

    Attributes:
        name: the URL the source was opened with.
        accepted: inputs accepted (one per signal value).
        rejected: refused inputs by cause (every cause of CAUSES is present).
        stale: True while no good input arrived for stale_after_s (and before the first one).
        last_input_age_s: seconds since the last accepted input, -1 if none yet.
        last_rejection: the last refusal, "cause: detail".
        counters: other counts of the backend (frames read, sequence gaps, ...).
        values: last good value of every signal received.
    """

    name: str
    accepted: int = 0
    rejected: dict[str, int] = field(default_factory=lambda: dict.fromkeys(CAUSES, 0))
    stale: bool = True
    last_input_age_s: float = -1.0
    last_rejection: str = ""
    counters: dict[str, int] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)


class ControlSource(ABC):
    """A cockpit input device or recording, opened by URL (host_sim.inputs.open_source).

    Use: `poll(now)` often (the host calls it before every flight-model step), then
    `latest()` for the controls to fly with; `status()` at any time; `close()` at the end
    (or use the source as a context manager).

    Args:
        name: the URL, for status and logs.
        stale_after_s: silence after which the source is flagged stale, seconds.
        clock: monotonic clock for staleness, seconds; recordings replace it by the time
            passed to poll() so that a replay does not depend on the wall clock.
    """

    def __init__(self, name: str, *, stale_after_s: float = STALE_AFTER_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not (stale_after_s > 0 and math.isfinite(stale_after_s)):
            raise ValueError(f"stale_after: {stale_after_s} must be a finite number of seconds > 0")
        self.name = name
        self.stale_after_s = float(stale_after_s)
        self.clock = clock
        self._lock = threading.Lock()
        self._status = SourceStatus(name)
        self._values: dict[str, float] = {}
        self._updated: dict[str, float] = {}  # signal -> time of its last good value (this clock)
        self._last_good: float | None = None
        self._logged = 0
        self._failing = False  # the last read raised

    # --- the interface -----------------------------------------------------------------------

    def poll(self, now_s: float | None = None) -> int:
        """Read every input that is due, then update the stale flag; returns the inputs accepted.

        now_s is the time of the caller's step in seconds (simulation time). Live devices read
        what has arrived and ignore it; recordings deliver the records due by now_s.
        A device error leaves the values held (the source goes stale); it is counted
        (`device_error`) and logged once per failure, however many polls fail until a read
        succeeds again.
        """
        with self._lock:
            before = self._status.accepted
        try:
            self._read(now_s)
        except Exception as exc:
            if not self._failing:
                self._failing = True
                self._reject(Rejected("device_error", f"{type(exc).__name__}: {exc}"))
        else:
            if self._failing:
                self._failing = False
                log.info("%s: the device reads again", self.name)
        self._update_stale(self._now(now_s))
        with self._lock:
            return self._status.accepted - before

    def latest(self) -> Controls:
        """The last good value of every control (defaults for signals never received)."""
        with self._lock:
            return controls_of(self._values)

    def updated(self) -> dict[str, tuple[float, float]]:
        """Signal -> (last good value, time it arrived); for merging several sources."""
        with self._lock:
            return {k: (v, self._updated[k]) for k, v in self._values.items()}

    def status(self) -> SourceStatus:
        """A copy of the counters."""
        with self._lock:
            s = self._status
            age = -1.0 if self._last_good is None else max(0.0, self._now(None) - self._last_good)
            return SourceStatus(s.name, s.accepted, dict(s.rejected), s.stale, age, s.last_rejection,
                                dict(s.counters), dict(self._values))

    def close(self) -> None:  # noqa: B027  (a default for sources that hold nothing to release)
        """Release the device or file."""

    def __enter__(self) -> ControlSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- for the backends --------------------------------------------------------------------

    @abstractmethod
    def _read(self, now_s: float | None) -> None:
        """Read what is due and call _accept / _reject for each input."""

    def _now(self, now_s: float | None) -> float:
        return self.clock()

    def _accept(self, signal: str, value: float, now_s: float | None = None) -> None:
        t = self._now(now_s)
        with self._lock:
            self._values[signal] = float(value)
            self._updated[signal] = t
            self._last_good = t
            self._status.accepted += 1
            recovered = self._status.stale and self._status.rejected["stale"] > 0
            self._status.stale = False
        if recovered:
            log.info("%s: good inputs again after being stale", self.name)

    def _heartbeat(self, now_s: float | None = None) -> None:
        """The device says it is alive and its controls are unchanged (no value to accept)."""
        t = self._now(now_s)
        with self._lock:
            self._last_good = t
            self._status.stale = False

    def _reject(self, rejection: Rejected) -> None:
        with self._lock:
            self._status.rejected[rejection.cause] += 1
            self._status.last_rejection = str(rejection)
            self._logged += 1
            logged = self._logged
        if logged <= _LOGGED_REJECTIONS:
            log.warning("%s: input refused: %s%s", self.name, rejection,
                        " (further refusals are only counted)" if logged == _LOGGED_REJECTIONS else "")

    def _count(self, counter: str, n: int = 1) -> None:
        with self._lock:
            self._status.counters[counter] = self._status.counters.get(counter, 0) + n

    def _update_stale(self, now: float) -> None:
        with self._lock:
            if self._last_good is None or self._status.stale:
                return
            silence = now - self._last_good
            if silence <= self.stale_after_s:
                return
            self._status.stale = True
        self._reject(Rejected("stale", f"no good input for {silence:.2f} s (stale after "
                                       f"{self.stale_after_s:g} s); holding the last values"))
