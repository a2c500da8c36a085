"""The bundled scripted flight: take-off, climb, a banked turn and a shallow descent.

The flight is flown over the bundled airfield (channel_worker/data/airfield.json, built by
channel_worker/data/build_airfield.py): runway 36 runs north along x = 0 from its threshold at
y = -1000 to y = +1000. The scene places objects where this flight carries them across the seams
of the default three-channel rig (+-30 degrees of azimuth from the nose) and across its outer
edges (+-90 degrees); tests/channel_worker/test_bundled_scene.py checks them phase by phase.

Outline (seconds from the start; see PHASES):

- 0 .. 6: take-off roll north on the centreline from y = -900 (100 m past the threshold), eye
  3 m above the runway, accelerating at 4 m/s^2 from a 12 m/s rolling start;
- 6 .. 9: rotation (5 degrees nose up at about 36 m/s), lift-off and transition to an
  8 degree climb;
- 9 .. 11: straight climb;
- 11 .. 18: coordinated left turn at 30 degrees of bank, rolled in and out over 1.5 s each;
  the heading passes through north (0 -> 359.x) at the roll-in and ends near 324;
- 16 .. 24: push-over into a 4 degree descent, wings level from 18 s.

The eye climbs to about 67 m. The path is integrated once, at TABLE_HZ, when the flight is built;
eyepoint_at() interpolates the table linearly (position, pitch, roll) and along the shortest arc
(heading). Every schedule is a smootherstep ramp, so attitude and its rate never jump.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from services.rig.frame import Eyepoint

#: Standard gravity, m/s^2; a coordinated turn has heading rate g tan(bank) / speed.
G_MPS2 = 9.80665
#: Rate of the precomputed table, Hz. At ~60 m/s one step is 0.6 m; linear interpolation between
#: steps of a 6 deg/s turn is off the true arc by well under a millimetre.
TABLE_HZ = 100

DURATION_S = 24.0
START_XY_M = (0.0, -900.0)  # world x, y: runway centreline, 100 m past the threshold
EYE_HEIGHT_M = 3.0  # eye above the runway while the wheels are on it
V0_MPS = 12.0  # rolling start: the script has no time for a standing start
ROLL_ACCEL_MPS2 = 4.0
AIR_ACCEL_MPS2 = 0.5  # once airborne most of the thrust goes into the climb
ALPHA_DEG = 5.0  # nose above the flight path once rotated (angle of attack)
CLIMB_DEG = 8.0
DESCENT_DEG = -4.0
BANK_DEG = -30.0  # negative: left wing down, a left turn

#: The phases of the script, (name, start s, end s); they overlap where one blends into the next.
PHASES: tuple[tuple[str, float, float], ...] = (
    ("take-off roll", 0.0, 6.0),
    ("rotation", 6.0, 9.0),
    ("climb", 9.0, 11.0),
    ("turn", 11.0, 18.0),
    ("descent", 16.0, DURATION_S),
)


@dataclass(frozen=True, eq=False)
class Flight:
    """A scripted flight, held as a table sampled at TABLE_HZ.

    Attributes:
        duration_s: length of the flight, seconds; the table has duration_s * TABLE_HZ + 1 rows.
        position: (N, 3) float64 world eye position, metres (read-only).
        heading_deg: (N,) float64 in [0, 360), clockwise from north (read-only).
        pitch_deg: (N,) float64, nose-up positive (read-only).
        roll_deg: (N,) float64, right-wing-down positive (read-only).
    """

    duration_s: float
    position: np.ndarray
    heading_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray

    def eyepoint_at(self, t_s: float) -> Eyepoint:
        """The eyepoint t_s seconds after the start.

        Times outside [0, duration_s] are clamped to it, so a caller running past the end holds
        the last eyepoint rather than extrapolating.

        Raises:
            ValueError: t_s is NaN.
        """
        u = self._clamped(t_s) * TABLE_HZ
        i = min(int(u), self.position.shape[0] - 2)
        f = u - i  # in [0, 1]
        x, y, z = self.position[i] + f * (self.position[i + 1] - self.position[i])
        h0 = float(self.heading_deg[i])
        dh = (float(self.heading_deg[i + 1]) - h0 + 180.0) % 360.0 - 180.0  # shortest arc
        p = self.pitch_deg[i] + f * (self.pitch_deg[i + 1] - self.pitch_deg[i])
        r = self.roll_deg[i] + f * (self.roll_deg[i + 1] - self.roll_deg[i])
        return Eyepoint.of(x, y, z, _wrap_deg(h0 + f * dh), p, r)

    def phase_at(self, t_s: float) -> str:
        """Name of the last phase of PHASES that has started by t_s (clamped like eyepoint_at).

        Raises:
            ValueError: t_s is NaN.
        """
        t = self._clamped(t_s)
        return [name for name, start, _ in PHASES if start <= t][-1]

    def _clamped(self, t_s: float) -> float:
        t = float(t_s)
        if math.isnan(t):
            raise ValueError("t_s: nan is not a time")
        return min(max(t, 0.0), self.duration_s)


def bundled_flight() -> Flight:
    """The flight that the demo and the benchmark fly over the bundled airfield (module doc)."""
    n = int(round(DURATION_S * TABLE_HZ)) + 1
    t = np.arange(n, dtype=np.float64) / TABLE_HZ
    dt = 1.0 / TABLE_HZ

    # Schedules. Each is a sum of smootherstep ramps between constant phases, so the attitude,
    # its rate and its acceleration are continuous (a step in roll rate reads as a jolt on a
    # motion base and as a jump in the image).
    accel = ROLL_ACCEL_MPS2 + (AIR_ACCEL_MPS2 - ROLL_ACCEL_MPS2) * _ramp(t, 7.0, 10.0)
    gamma = CLIMB_DEG * _ramp(t, 7.0, 9.0) + (DESCENT_DEG - CLIMB_DEG) * _ramp(t, 16.0, 20.0)
    pitch = ALPHA_DEG * _ramp(t, 6.0, 7.5) + gamma
    roll = BANK_DEG * (_ramp(t, 11.0, 12.5) - _ramp(t, 16.5, 18.0))

    # Integrate speed, then heading, then position, each with the trapezoidal rule.
    speed = V0_MPS + _integral(accel, dt)
    turn_rate = np.degrees(G_MPS2 * np.tan(np.radians(roll)) / speed)  # deg/s, + = clockwise
    heading = _integral(turn_rate, dt)
    h, g = np.radians(heading), np.radians(gamma)
    velocity = speed[:, None] * np.stack(
        [np.cos(g) * np.sin(h), np.cos(g) * np.cos(h), np.sin(g)], axis=1)
    position = np.array([START_XY_M[0], START_XY_M[1], EYE_HEIGHT_M]) + np.stack(
        [_integral(velocity[:, k], dt) for k in range(3)], axis=1)

    heading = np.array([_wrap_deg(a) for a in heading])
    for a in (position, heading, pitch, roll):
        a.setflags(write=False)
    return Flight(DURATION_S, position, heading, pitch, roll)


def _ramp(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 before t0, 1 after t1, smootherstep between (continuous to the 2nd derivative)."""
    s = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return s * s * s * (s * (6.0 * s - 15.0) + 10.0)


def _integral(rate: np.ndarray, dt: float) -> np.ndarray:
    """Running trapezoidal integral of samples spaced dt apart; 0 at the first sample."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * dt)])


def _wrap_deg(a: float) -> float:
    """An angle in degrees brought into [0, 360)."""
    w = float(a) % 360.0
    return 0.0 if w >= 360.0 else w  # -1e-17 % 360.0 rounds to 360.0


def _outline() -> None:  # a quick look at the script: python -m host_sim.flight
    flight = bundled_flight()
    for t in np.arange(0.0, flight.duration_s + 1e-9, 1.0):
        e = flight.eyepoint_at(t)
        x, y, z = e.position
        print(f"t={t:5.1f}  x={x:8.1f} y={y:8.1f} z={z:6.1f}  h={e.heading_deg:6.1f} "
              f"p={e.pitch_deg:5.1f} r={e.roll_deg:6.1f}  {flight.phase_at(t)}")


if __name__ == "__main__":
    _outline()
