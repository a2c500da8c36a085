"""The flight model flown by cockpit control sources: an eyepoint source for the publisher.

The model advances at a fixed step (STEP_HZ) whatever the frame rate: eyepoint_at(t) runs
every step due by t, polling the control sources with the step's simulation time just before
it, and interpolates the eyepoint between the two steps around t. The control inputs therefore
act on the model at step times, never at frame times, so one input log gives the same states
at every frame rate (tests/host_sim/test_controlled.py).

Several sources can be flown at once (a CAN bus for the primary controls, a serial panel for
the levers): for each control the first source in the given order that has delivered it and
is not stale wins; if all that delivered it are stale, the first of them holds its last value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from services.rig.frame import Eyepoint

from . import flight_model
from .flight import EYE_HEIGHT_M, START_XY_M
from .inputs.base import Controls, ControlSource, SourceStatus, controls_of

#: Flight-model steps per simulated second.
STEP_HZ = 100


@dataclass(frozen=True)
class ModelStatus:
    """What the host reports about the flown model."""

    steps: int
    speed_mps: float
    on_ground: bool


class ControlledFlight:
    """Eyepoints of the flight model flown by control sources (module doc).

    Args:
        sources: the control sources, by priority.
        aircraft: model parameters.
        initial: the state at time 0; default: at rest on the bundled airfield's runway
            where the bundled flight starts, facing north.
        step_hz: model steps per simulated second.
    """

    def __init__(self, sources: Sequence[ControlSource], *, aircraft: flight_model.Aircraft | None = None,
                 initial: flight_model.State | None = None, step_hz: float = STEP_HZ) -> None:
        if not (step_hz > 0 and math.isfinite(step_hz)):
            raise ValueError(f"step_hz: {step_hz} must be a finite number > 0")
        self.sources = list(sources)
        self.aircraft = aircraft or flight_model.Aircraft(eye_height_m=EYE_HEIGHT_M)
        self.step_hz = float(step_hz)
        start = initial or flight_model.on_runway(START_XY_M[0], START_XY_M[1], 0.0, self.aircraft)
        self._k = 0  # steps taken: the state is at time k / step_hz
        self._prev = start  # the state one step before _state (the same at the start)
        self._state = start

    @property
    def state(self) -> flight_model.State:
        """The model's latest state (at time steps / step_hz)."""
        return self._state

    def controls(self) -> Controls:
        """The controls flown now, merged from the sources by priority (module doc)."""
        merged: dict[str, float] = {}
        fresh: set[str] = set()
        for source in self.sources:
            stale = source.status().stale
            for name, (value, _) in source.updated().items():
                if name not in merged or (name not in fresh and not stale):
                    merged[name] = value
                    if not stale:
                        fresh.add(name)
        return controls_of(merged)

    def eyepoint_at(self, t_s: float) -> Eyepoint:
        """The eyepoint at simulation time t_s, after running the model up to it.

        Time only goes forward: a t_s earlier than the last one returns the latest state.

        Raises:
            ValueError: t_s is NaN.
        """
        t = float(t_s)
        if math.isnan(t):
            raise ValueError("t_s: nan is not a time")
        dt = 1.0 / self.step_hz
        # Step k -> k + 1 uses the inputs due at k / step_hz <= t, so the state after t is known.
        while self._k / self.step_hz <= t and math.isfinite(t):
            now = self._k / self.step_hz
            for source in self.sources:
                source.poll(now)
            self._prev = self._state
            self._state = flight_model.step(self._state, self.controls(), dt, self.aircraft)
            self._k += 1
        f = min(max((t - (self._k - 1) / self.step_hz) * self.step_hz, 0.0), 1.0) if self._k else 1.0
        return _blend(self._prev, self._state, f, self.aircraft)

    def status(self) -> tuple[list[SourceStatus], ModelStatus]:
        """Counters of every source, and the model's step count, speed and ground contact."""
        s = self._state
        return [src.status() for src in self.sources], ModelStatus(self._k, s.speed_mps, s.on_ground)

    def close(self) -> None:
        """Close every source."""
        for source in self.sources:
            source.close()


def _blend(a: flight_model.State, b: flight_model.State, f: float, aircraft: flight_model.Aircraft) -> Eyepoint:
    """The eyepoint a fraction f of the way from state a to state b (heading on the short arc)."""
    ha, pa, ra = a.attitude_deg(aircraft)
    hb, pb, rb = b.attitude_deg(aircraft)
    dh = (hb - ha + 180.0) % 360.0 - 180.0
    h = (ha + f * dh) % 360.0
    return Eyepoint.of(a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m), a.z_m + f * (b.z_m - a.z_m),
                       0.0 if h >= 360.0 else h, pa + f * (pb - pa), ra + f * (rb - ra))
