"""The flight model flown by cockpit control sources: an eyepoint source for the publisher.

The model is the point-mass model (default) or any other FlightModel (host_sim/fdm/base.py:
JSBSim with `--fdm jsbsim:AIRCRAFT`). It advances at its fixed step (STEP_HZ for the point-mass
model, 120 Hz for JSBSim) whatever the frame rate: eyepoint_at(t) runs
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
from .fdm.base import FlightModel
from .fdm.point_mass import STEP_HZ, PointMass
from .inputs.base import Controls, ControlSource, SourceStatus, controls_of

__all__ = ["STEP_HZ", "ControlledFlight", "ModelStatus"]


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
        aircraft, initial, step_hz: the point-mass model's parameters (host_sim.fdm.point_mass),
            when no model is given.
        model: the flight model to fly; default: the point-mass model.

    Raises:
        ValueError: a bad step_hz, or a model given together with point-mass parameters.
    """

    def __init__(self, sources: Sequence[ControlSource], *, aircraft: flight_model.Aircraft | None = None,
                 initial: flight_model.State | None = None, step_hz: float = STEP_HZ,
                 model: FlightModel | None = None) -> None:
        if model is not None and (aircraft is not None or initial is not None or step_hz != STEP_HZ):
            raise ValueError("model: aircraft, initial and step_hz are the point-mass model's; give one or the other")
        self.sources = list(sources)
        self.model: FlightModel = model or PointMass(aircraft=aircraft, initial=initial, step_hz=step_hz)
        self.step_hz = self.model.step_hz
        self._k = 0  # steps taken: the model is at time k / step_hz
        self._prev = self._eye = self.model.eyepoint()  # eyepoints one step apart (the same at the start)

    @property
    def aircraft(self) -> flight_model.Aircraft:
        """The point-mass model's parameters (AttributeError for another model)."""
        return self._point_mass().aircraft

    @property
    def state(self) -> flight_model.State:
        """The point-mass model's latest state, at time steps / step_hz (AttributeError for
        another model)."""
        return self._point_mass().state

    def _point_mass(self) -> PointMass:
        if not isinstance(self.model, PointMass):
            raise AttributeError(f"model: {type(self.model).__name__} is not the point-mass model")
        return self.model

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
        # Step k -> k + 1 uses the inputs due at k / step_hz <= t, so the state after t is known.
        while self._k / self.step_hz <= t and math.isfinite(t):
            now = self._k / self.step_hz
            for source in self.sources:
                source.poll(now)
            self.model.step(self.controls())
            self._prev, self._eye = self._eye, self.model.eyepoint()
            self._k += 1
        f = min(max((t - (self._k - 1) / self.step_hz) * self.step_hz, 0.0), 1.0) if self._k else 1.0
        return _blend(self._prev, self._eye, f)

    def status(self) -> tuple[list[SourceStatus], ModelStatus]:
        """Counters of every source, and the model's step count, speed and ground contact."""
        return ([src.status() for src in self.sources],
                ModelStatus(self._k, self.model.speed_mps(), self.model.on_ground()))

    def close(self) -> None:
        """Close every source, then the model."""
        for source in self.sources:
            source.close()
        self.model.close()


def _blend(a: Eyepoint, b: Eyepoint, f: float) -> Eyepoint:
    """The eyepoint a fraction f of the way from a to b (heading and roll on the short arc)."""
    dh = (b.heading_deg - a.heading_deg + 180.0) % 360.0 - 180.0
    h = (a.heading_deg + f * dh) % 360.0
    dr = (b.roll_deg - a.roll_deg + 180.0) % 360.0 - 180.0
    p = a.position + f * (b.position - a.position)
    return Eyepoint.of(float(p[0]), float(p[1]), float(p[2]), 0.0 if h >= 360.0 else h,
                       a.pitch_deg + f * (b.pitch_deg - a.pitch_deg), a.roll_deg + f * dr)
