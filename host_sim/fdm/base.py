"""The interface between the controlled host and a flight model (docs/host-flight-model.md).

host_sim.controlled.ControlledFlight steps a FlightModel at the model's own rate and blends
the eyepoints of the two steps around each frame; a model only has to advance by one step with
the controls it is given and say where the eye is. The point-mass model (point_mass.py) and
JSBSim (jsbsim_model.py) sit behind it.
"""

from __future__ import annotations

from typing import Protocol

from services.rig.frame import Eyepoint

from ..inputs.base import Controls


class FlightModel(Protocol):
    """A flight model stepped at a fixed rate.

    Attributes:
        step_hz: model steps per simulated second.
    """

    step_hz: float

    def step(self, controls: Controls) -> None:
        """Advance the model by one step (1 / step_hz seconds) flown with the given controls."""

    def eyepoint(self) -> Eyepoint:
        """The pilot's eyepoint in the world frame after the latest step."""

    def speed_mps(self) -> float:
        """Airspeed (true), metres per second."""

    def on_ground(self) -> bool:
        """Whether a wheel touches the ground."""

    def close(self) -> None:
        """Release what the model holds."""
