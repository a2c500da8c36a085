"""A scripted take-off: the controls of a pilot taking off from the runway, without a cockpit.

`ig host --fdm ...` with no --controls, and `ig demo --fdm jsbsim`, fly this. It is a control
source like a cockpit (host_sim.inputs.base.ControlSource), polled before every model step, but
it watches the model it flies (its eyepoint and airspeed), as a pilot does:

- brakes set for BRAKES_S, then released while the throttle comes up to full over
  THROTTLE_UP_S (smoothly, as a pilot does: at low speed the rudder has little authority
  against the propeller's swing);
- on the runway: the pedals hold the runway heading and steer back to the centreline, the
  stick neutral, the ailerons hold the wings level; below BRAKE_STEER_MPS, where the rudder has
  little authority, a toe brake on the side of the turn helps (differential braking: JSBSim's
  c172x does not steer its nose wheel from the pedals);
- at the rotation speed (vr_mps): the stick comes aft to hold the climb pitch; once airborne
  the same pitch hold climbs at full throttle, the ailerons bank (at most BANK_MAX_DEG) to
  turn back onto the runway heading and centreline, the pedals neutral.

Every loop is proportional with limits, so the script flies any reasonable light aircraft
(the JSBSim c172x, the point-mass model) without tuning per aircraft.
"""

from __future__ import annotations

import math

from ..inputs.base import ControlSource
from .base import FlightModel

#: Seconds from the start with the brakes set.
BRAKES_S = 1.0
#: Seconds from the brakes' release over which the throttle comes up to full.
THROTTLE_UP_S = 6.0
#: Steepest bank the airborne heading hold asks for, degrees; bank per degree of heading error.
BANK_MAX_DEG = 15.0
K_BANK = 1.0
#: Default rotation speed, m/s (55 kt: a Cessna 172's Vr).
VR_MPS = 55.0 * 1852.0 / 3600.0
#: Pitch held from rotation on, degrees (a light aircraft's climb at full power).
CLIMB_PITCH_DEG = 8.0
#: Gains: stick per degree of pitch error, pedal per degree of heading error, wheel per degree
#: of bank, degrees of heading per metre off the centreline (at most CENTRELINE_MAX_DEG).
K_PITCH = 0.08
K_HEADING = 0.15
K_ROLL = 0.05
K_CENTRELINE = 0.5
CENTRELINE_MAX_DEG = 10.0
#: Differential braking on the runway: toe brake per degree of heading error, at most
#: BRAKE_STEER_MAX, only below BRAKE_STEER_MPS (above it the rudder steers and a brake would
#: only lengthen the roll).
K_BRAKE = 0.1
BRAKE_STEER_MAX = 0.6
BRAKE_STEER_MPS = 20.0
#: The script delivers every control at every step: it is never stale.
STALE_NEVER_S = 1e9


class ScriptedTakeoff(ControlSource):
    """The take-off pilot (module doc).

    Args:
        model: the model it flies (read, never stepped).
        runway_heading_deg: true heading of the runway, degrees.
        centreline_xy_m: a world (x, y) on the runway centreline.
        vr_mps: rotation speed, m/s.
        climb_pitch_deg: pitch held from rotation on, degrees.
    """

    def __init__(self, model: FlightModel, *, runway_heading_deg: float, centreline_xy_m: tuple[float, float],
                 vr_mps: float = VR_MPS, climb_pitch_deg: float = CLIMB_PITCH_DEG) -> None:
        super().__init__("scripted take-off", stale_after_s=STALE_NEVER_S)
        self.model = model
        self.heading_deg = float(runway_heading_deg)
        self.centreline = (float(centreline_xy_m[0]), float(centreline_xy_m[1]))
        self.vr_mps = float(vr_mps)
        self.climb_pitch_deg = float(climb_pitch_deg)
        self.rotated = False

    def _now(self, now_s: float | None) -> float:
        return 0.0 if now_s is None else now_s

    def _read(self, now_s: float | None) -> None:
        t = 0.0 if now_s is None else now_s
        eye = self.model.eyepoint()
        h = math.radians(self.heading_deg)
        dx, dy = eye.position[0] - self.centreline[0], eye.position[1] - self.centreline[1]
        right_of_centreline = dx * math.cos(h) - dy * math.sin(h)  # metres to the right of the centreline
        target = self.heading_deg - _clamp(K_CENTRELINE * right_of_centreline, -CENTRELINE_MAX_DEG,
                                           CENTRELINE_MAX_DEG)
        heading_error = (eye.heading_deg - target + 180.0) % 360.0 - 180.0  # nose right of the target: > 0
        self.rotated = self.rotated or self.model.speed_mps() >= self.vr_mps
        pitch = _clamp(K_PITCH * (self.climb_pitch_deg - eye.pitch_deg), -1.0, 1.0) if self.rotated else 0.0
        left = right = 0.0
        if self.model.on_ground():
            yaw, bank = _clamp(-K_HEADING * heading_error, -1.0, 1.0), 0.0
            if t >= BRAKES_S and self.model.speed_mps() < BRAKE_STEER_MPS:
                brake = _clamp(K_BRAKE * abs(heading_error), 0.0, BRAKE_STEER_MAX)
                left, right = (brake, 0.0) if heading_error > 0.0 else (0.0, brake)
        else:
            yaw, bank = 0.0, _clamp(-K_BANK * heading_error, -BANK_MAX_DEG, BANK_MAX_DEG)
        values = {
            "throttle_1_lever_position": _clamp((t - BRAKES_S) / THROTTLE_UP_S, 0.0, 1.0),
            "park_brake_lever_position": 1.0 if t < BRAKES_S else 0.0,
            "yaw_control_position": yaw,
            "roll_control_position": _clamp(K_ROLL * (bank - eye.roll_deg), -1.0, 1.0),
            "pitch_control_position": pitch,
            "left_brake_pedal_position": left,
            "right_brake_pedal_position": right,
        }
        for signal, value in values.items():
            self._accept(signal, value, now_s)


def _clamp(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v
