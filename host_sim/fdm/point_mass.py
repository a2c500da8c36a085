"""The point-mass model of host_sim.flight_model behind the FlightModel interface (base.py)."""

from __future__ import annotations

from services.rig.frame import Eyepoint

from .. import flight_model
from ..flight import EYE_HEIGHT_M, START_XY_M
from ..inputs.base import Controls

#: Flight-model steps per simulated second.
STEP_HZ = 100


class PointMass:
    """The point-mass model (docs/host-flight-model.md), stepped at step_hz.

    Args:
        aircraft: model parameters.
        initial: the state at time 0; default: at rest on the bundled airfield's runway
            where the bundled flight starts, facing north.
        step_hz: model steps per simulated second.

    Raises:
        ValueError: step_hz is not a finite number > 0.
    """

    def __init__(self, *, aircraft: flight_model.Aircraft | None = None,
                 initial: flight_model.State | None = None, step_hz: float = STEP_HZ) -> None:
        if not (step_hz > 0 and step_hz < float("inf")):
            raise ValueError(f"step_hz: {step_hz} must be a finite number > 0")
        self.step_hz = float(step_hz)
        self.aircraft = aircraft or flight_model.Aircraft(eye_height_m=EYE_HEIGHT_M)
        self.state = initial or flight_model.on_runway(START_XY_M[0], START_XY_M[1], 0.0, self.aircraft)

    def step(self, controls: Controls) -> None:
        self.state = flight_model.step(self.state, controls, 1.0 / self.step_hz, self.aircraft)

    def eyepoint(self) -> Eyepoint:
        s = self.state
        return Eyepoint.of(s.x_m, s.y_m, s.z_m, *s.attitude_deg(self.aircraft))

    def speed_mps(self) -> float:
        return self.state.speed_mps

    def on_ground(self) -> bool:
        return self.state.on_ground

    def close(self) -> None:
        """Nothing to release."""
