"""The host's flight models, chosen by `--fdm NAME[:AIRCRAFT]` (docs/host-flight-model.md).

    point-mass         the built-in point-mass model (default)          point_mass.py
    jsbsim:AIRCRAFT    JSBSim with one of its aircraft (the jsbsim extra) jsbsim_model.py

Both sit behind one interface (base.FlightModel); a model's module is imported only when it is
chosen, so JSBSim stays optional.
"""

from __future__ import annotations

from dataclasses import dataclass

from .base import FlightModel
from .ground import Ground

#: Model name -> its form and what it is (for messages and --help).
FDMS = {
    "point-mass": "point-mass: the built-in point-mass model (default)",
    "jsbsim": "jsbsim:AIRCRAFT: JSBSim at 120 Hz with one of its bundled aircraft (c172x if none named; "
              "pip install 'ig-rig[jsbsim]')",
}
#: JSBSim's aircraft when `--fdm jsbsim` names none.
JSBSIM_DEFAULT_AIRCRAFT = "c172x"
#: Where a JSBSim take-off starts on the bundled airfield: runway 36's centreline 50 m past the
#: threshold (y = -1000, channel_worker/data/build_airfield.py), facing north.
RUNWAY_START_XY_M = (0.0, -950.0)
RUNWAY_HEADING_DEG = 0.0


@dataclass(frozen=True)
class FdmSpec:
    """A parsed --fdm: the model's name and, for JSBSim, the aircraft."""

    name: str
    aircraft: str = ""


def parse_fdm(text: str) -> FdmSpec:
    """`point-mass`, `jsbsim` or `jsbsim:AIRCRAFT` as an FdmSpec.

    Raises:
        ValueError: an unknown model, or an aircraft where none applies (the message names --fdm).
    """
    name, sep, aircraft = text.strip().partition(":")
    if name not in FDMS:
        raise ValueError(f"--fdm: {text!r} is not one of " + "; ".join(FDMS.values()))
    if name == "point-mass":
        if sep:
            raise ValueError(f"--fdm: {text!r}: the point-mass model takes no aircraft")
        return FdmSpec(name)
    if sep and not aircraft.replace("_", "").replace("-", "").isalnum():
        raise ValueError(f"--fdm: {text!r}: the aircraft {aircraft!r} is not a JSBSim aircraft name")
    return FdmSpec(name, aircraft or JSBSIM_DEFAULT_AIRCRAFT)


def open_model(spec: FdmSpec, *, origin: tuple[float, float, float], ground: Ground | None = None) -> FlightModel:
    """The model spec names, at rest on the bundled airfield's runway 36 (JSBSim: engine running,
    brakes set, RUNWAY_START_XY_M; the point-mass model where the bundled flight starts).

    Args:
        origin: the world's geodetic origin (latitude deg, longitude deg, height m).
        ground: the ground under JSBSim's wheels (ground.py), closed with the model or here
            when the model cannot be made; default: the bundled runway's plane. The point-mass
            model has its own runway plane and closes it at once.

    Raises:
        ValueError: jsbsim is not installed (the message says how to install it), or JSBSim
            cannot load the aircraft.
    """
    if spec.name == "jsbsim":
        from .jsbsim_model import JSBSimModel
        try:
            return JSBSimModel(spec.aircraft, origin=origin, start_xy_m=RUNWAY_START_XY_M,
                               heading_deg=RUNWAY_HEADING_DEG, ground=ground)
        except BaseException:
            if ground is not None:
                ground.close()
            raise
    if ground is not None:
        ground.close()
    from .point_mass import PointMass
    return PointMass()
