"""JSBSim as the host's flight model (`--fdm jsbsim:AIRCRAFT`; docs/host-flight-model.md).

JSBSim (the `jsbsim` extra: the wheel bundles its aircraft, engines and systems) runs at its
own rate, 120 Hz, behind the FlightModel interface (base.py). Each step:

1. the cockpit controls go to the aircraft's flight-control system (`fcs/` properties, signs
   below);
2. the terrain elevation under the aircraft (`position/terrain-elevation-asl-ft`) is set from
   our ground at its position, so that the wheels roll on our runway, not on JSBSim's sea-level
   earth;
3. FGFDMExec.Run() advances the aircraft by one step.

The eyepoint is the aircraft's position (geodetic latitude, longitude, height) turned into the
rig's world around its geodetic origin (the rig file's `cigi.origin`), plus the pilot's eye
offset from the centre of gravity (the aircraft file's <eyepoint>, `metrics/eyepoint-*-in`,
less `inertia/cg-*-in`, both in JSBSim's structural frame: x aft, y right, z up, inches);
its attitude (`attitude/psi|theta|phi-rad`, against true north and the local horizontal) is
turned into the world by the tilt between the aircraft's local frame and the origin's, as for
a CIGI ownship (host_sim.cigi.geometry.pose_of_geodetic).

Control signs (JSBSim's conventions are those of its FlightGear interface, FlightGear's
src/FDM/JSBSim/JSBSim.cxx): our pitch +1 is the stick fully aft, JSBSim's
`fcs/elevator-cmd-norm` -1 is nose up, so elevator = -pitch; roll +1 (right) is
`fcs/aileron-cmd-norm` +1 (right wing down); yaw +1 (right pedal) is `fcs/rudder-cmd-norm` -1
(JSBSim's positive rudder yaws the nose left); throttle 0..1, flaps 0..1 and speed brake 0..1
map one to one (throttle to every engine); each wheel brake (`fcs/left|right-brake-cmd-norm`)
is its toe brake, or full while the park brake lever is set.

Steering on the ground: JSBSim's nose-wheel steering follows `fcs/steer-cmd-norm`, but the
c172x's autopilot system (systems/Autopilot.xml, `ap/roll-command-selector-steering`) writes 0
there at every step while its roll autopilot is off, so on that aircraft the pedals steer only
through the rudder, which has little authority below about 20 kt. Pilots of aircraft with a
castering nose wheel steer with differential braking; the toe brakes do that here too.
"""

from __future__ import annotations

import math

import numpy as np

from services.rig.frame import Eyepoint

from ..cigi import geometry
from ..inputs.base import Controls
from .ground import Ground, Plane

#: JSBSim's own rate, steps per simulated second (its default time step is 1/120 s).
STEP_HZ = 120.0
FT_M = 0.3048
IN_M = 0.0254
KT_MPS = 1852.0 / 3600.0
#: The ground of the bundled airfield: the runway and the flattened pad around it lie at world
#: z = 0 (channel_worker/data/build_airfield.py, the bundled terrain's pad).
RUNWAY_Z_M = 0.0
#: Settling before time 0: steps with the brakes set for the gear to come to rest on the runway
#: (JSBSim's initial conditions put the wheels at a guessed height; the struts then oscillate
#: for a second or so).
SETTLE_STEPS = 240

def import_jsbsim():
    """The jsbsim module.

    Raises:
        ValueError: it is not installed; the message names the flag and the extra.
    """
    try:
        import jsbsim
    except ImportError:
        raise ValueError("--fdm jsbsim: the jsbsim package is not installed; "
                         "pip install 'ig-rig[jsbsim]'") from None
    return jsbsim


class JSBSimModel:
    """A JSBSim aircraft on the ground at (x, y) facing heading_deg, engine running (module doc).

    Args:
        aircraft: the aircraft's name among JSBSim's bundled ones (c172x, c310, f16, ...).
        origin: the geodetic (latitude deg, longitude deg, height m) of the world's (0, 0, 0).
        start_xy_m: world (x, y) of the start, metres.
        heading_deg: true heading of the start, degrees.
        ground: world z of the ground under world (x, y), metres (ground.py: the rig's terrain
            through a worker's query service); default: the bundled airfield's runway plane.
            The model closes it.
        step_hz: steps per simulated second.

    Raises:
        ValueError: jsbsim missing, an unknown aircraft, or a bad argument (named).
    """

    def __init__(self, aircraft: str, *, origin: tuple[float, float, float], start_xy_m: tuple[float, float],
                 heading_deg: float = 0.0, ground: Ground | None = None, step_hz: float = STEP_HZ) -> None:
        if not (step_hz > 0 and math.isfinite(step_hz)):
            raise ValueError(f"step_hz: {step_hz} must be a finite number > 0")
        jsbsim = import_jsbsim()
        # Quiet: JSBSim prints its banner and every loaded file at the default debug level.
        jsbsim.FGJSBBase().debug_lvl = 0
        self.aircraft = aircraft
        self.origin = (float(origin[0]), float(origin[1]), float(origin[2]))
        self.ground: Ground = ground or Plane(RUNWAY_Z_M)
        self.step_hz = float(step_hz)
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        if not fdm.load_model(aircraft):
            raise ValueError(f"--fdm jsbsim:{aircraft}: JSBSim has no aircraft {aircraft!r} "
                             f"(see {jsbsim.get_default_root_dir()}/aircraft)")
        # The aircraft files name their own CSV outputs; the host writes no files. (JSBSim
        # still says once as it loads c172x that it cannot open JSBout172B.csv: harmless.)
        fdm.disable_output()
        fdm.set_dt(1.0 / self.step_hz)
        self.fdm = fdm
        self._engines = fdm.get_propulsion().get_num_engines()
        (lat,), (lon,), _ = geometry.geodetic_of_world(np.array([[start_xy_m[0], start_xy_m[1], 0.0]]),
                                                       self.origin)
        fdm["ic/lat-geod-deg"] = float(lat)
        fdm["ic/long-gc-deg"] = float(lon)
        fdm["ic/terrain-elevation-ft"] = self._terrain_ft(float(start_xy_m[0]), float(start_xy_m[1]))
        fdm["ic/psi-true-deg"] = float(heading_deg)
        fdm["ic/vc-kts"] = 0.0
        # JSBSim puts the centre of gravity at ic/h-agl-ft and does not lift the aircraft onto
        # its wheels (at 0 the struts bury and throw it over): a first pass in the air gives
        # the centre of gravity, the second starts with the lowest wheel just touching.
        fdm["ic/h-agl-ft"] = 100.0
        for _ in range(2):
            if not fdm.run_ic():
                raise ValueError(f"--fdm jsbsim:{aircraft}: JSBSim refused the initial conditions")
            fdm["ic/h-agl-ft"] = (fdm["inertia/cg-z-in"] - min(self._gear_z_in())) * IN_M / FT_M
        fdm["propulsion/set-running"] = -1  # every engine, running
        fdm["fcs/mixture-cmd-norm"] = 1.0
        fdm["propulsion/magneto_cmd"] = 3  # both magnetos
        self._apply(Controls(park_brake=1.0))
        for _ in range(SETTLE_STEPS):
            self._run()
        self.eye_offset_m = self._eye_offset()

    def _gear_z_in(self) -> list[float]:
        """Structural z (up, inches) of every wheel (gear units with a z-position property)."""
        units = self.fdm.get_ground_reactions().get_num_gear_units()
        zs = [self.fdm[f"gear/unit[{k}]/z-position"] for k in range(units)
              if self.fdm.get_property_manager().hasNode(f"gear/unit[{k}]/z-position")]
        if not zs:
            raise ValueError(f"--fdm jsbsim:{self.aircraft}: the aircraft has no wheels to start on the runway")
        return zs

    def _terrain_ft(self, x_m: float, y_m: float) -> float:
        """JSBSim's terrain elevation, feet, of our ground under world (x, y)."""
        point = np.array([x_m, y_m, self.ground(x_m, y_m)])
        return geometry.height_of_world(point, self.origin) / FT_M

    def _apply(self, c: Controls) -> None:
        """The controls to the fcs/ properties (signs in the module doc), clamped to their ranges."""
        f = self.fdm
        f["fcs/elevator-cmd-norm"] = -_clamp(c.pitch, -1.0, 1.0)
        f["fcs/aileron-cmd-norm"] = _clamp(c.roll, -1.0, 1.0)
        f["fcs/rudder-cmd-norm"] = -_clamp(c.yaw, -1.0, 1.0)
        throttle = _clamp(c.throttle, 0.0, 1.0)
        for k in range(self._engines):
            f[f"fcs/throttle-cmd-norm[{k}]"] = throttle
        f["fcs/flap-cmd-norm"] = _clamp(c.flaps, 0.0, 1.0)
        f["fcs/speedbrake-cmd-norm"] = _clamp(c.speed_brake, 0.0, 1.0)
        park = 1.0 if _finite(c.park_brake) >= 0.5 else 0.0
        f["fcs/left-brake-cmd-norm"] = max(park, _clamp(c.brake_left, 0.0, 1.0))
        f["fcs/right-brake-cmd-norm"] = max(park, _clamp(c.brake_right, 0.0, 1.0))

    def _run(self) -> None:
        x, y, _ = self.world_cg()
        self.fdm["position/terrain-elevation-asl-ft"] = self._terrain_ft(x, y)
        if not self.fdm.run():
            raise RuntimeError(f"--fdm jsbsim:{self.aircraft}: JSBSim stopped at t={self.fdm.get_sim_time():.3f} s")

    def _eye_offset(self) -> np.ndarray:
        """The eye's offset from the centre of gravity in body axes (forward, right, down), metres."""
        f = self.fdm
        d = [f[f"metrics/eyepoint-{a}-in"] - f[f"inertia/cg-{a}-in"] for a in "xyz"]
        # Structural frame x aft, y right, z up -> body x forward, y right, z down.
        return np.array([-d[0], d[1], -d[2]]) * IN_M

    def world_cg(self) -> np.ndarray:
        """World position of the centre of gravity, metres."""
        f = self.fdm
        return geometry.world_of_geodetic(np.array([f["position/lat-geod-deg"]]), np.array([f["position/long-gc-deg"]]),
                                          np.array([f["position/h-sl-ft"] * FT_M]), self.origin)[0]

    def step(self, controls: Controls) -> None:
        self._apply(controls)
        self._run()

    def eyepoint(self) -> Eyepoint:
        f = self.fdm
        pose = geometry.pose_of_geodetic(f["position/lat-geod-deg"], f["position/long-gc-deg"],
                                         f["position/h-sl-ft"] * FT_M, math.degrees(f["attitude/psi-rad"]),
                                         math.degrees(f["attitude/theta-rad"]), math.degrees(f["attitude/phi-rad"]),
                                         self.origin)
        eye = geometry.world_of_body(pose, self.eye_offset_m)[0]
        return Eyepoint(eye, pose.heading_deg, pose.pitch_deg, pose.roll_deg)

    def speed_mps(self) -> float:
        return float(self.fdm["velocities/vt-fps"]) * FT_M

    def on_ground(self) -> bool:
        # gear/wow: weight on any wheel (contact points of the structure do not count).
        return bool(self.fdm["gear/wow"] > 0.0)

    def close(self) -> None:
        """Release the ground (its channel and thread); the FGFDMExec goes with the object."""
        self.ground.close()


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0  # a non-finite control reads as neutral, as in the point-mass model


def _clamp(v: float, lo: float, hi: float) -> float:
    v = _finite(v)
    return lo if v < lo else hi if v > hi else v
