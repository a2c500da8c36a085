"""Build the bundled sample flight logs, host_sim/data/flights/ (host_sim/replay/samples.py).

    python -m host_sim.replay.build_samples            # rewrite the logs
    python -m host_sim.replay.build_samples --check    # exit 1 if one is out of date

Three short flights over the bundled airfield, whose runway 36 runs along world x = 0 from
y = -1000 to +1000 on ground at z = 0, each written the way its recorder writes it:

- departure.csv: a light aircraft lines up on runway 36, takes off, climbs straight ahead and
  turns right to the east, climbing. An EFIS-style export of this project's CSV: GNSS rows
  once a second (position), AHRS rows twice a second (attitude), so every other row has no
  position; the GNSS loses its vertical solution for a few seconds (alt_m alone empty) and the
  AHRS drops out for a second (attitude cells empty). Positions wander by well under a metre,
  as a GNSS fix does.
- circuit.igc: a glider flies the end of a left-hand circuit for runway 36, west of the
  field: the downwind leg, base, final with airbrakes, the landing and the ground roll. B
  records each second (positions in thousandths of minutes, whole-metre GNSS and pressure
  altitudes), the headers a logger writes; no attitude (the replay estimates it).
- low-pass.fdr: an X-Plane recording of an approach to runway 36 from 4.6 km out, a low pass at
  about 25 m along the runway and a climbing right turn away: DATA lines twice a second with
  the simulator's own attitude (no sensor noise: X-Plane records its state).

Each flight is flown by a script of legs (speed, vertical speed and turn rate, blended
smoothly from one leg to the next; bank is that of a coordinated turn, pitch the flight path
plus the angle of attack) at SIM_HZ, and sampled at its recorder's times. Geodetic positions
are the world positions around the rig's database origin ([cigi] origin: the bundled
airfield's), heights above it as the origin's height system has them. The paths keep clear of
the bundled terrain (tests/host_sim/replay/test_samples.py checks it). Nothing is random: the
GNSS wander is a sum of sines, so the files are the same on every machine.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.rig.geodetic import geodetic_of_enu
from services.rig.rigfile import CigiSpec

from .samples import FLIGHTS_DIR, SAMPLES

#: Rate the scripts are flown at, Hz.
SIM_HZ = 20
#: Standard gravity, m/s^2 (bank of a coordinated turn: tan(bank) = speed x turn rate / g).
G_MPS2 = 9.80665
#: Seconds over which a leg's vertical speed and turn rate blend in from the last leg's.
BLEND_S = 3.0
#: Seconds a touchdown takes to settle onto the wheels.
TOUCHDOWN_S = 1.0
#: Time constant of the attitude's lag behind its target, seconds: a pilot rolls into a turn
#: and rotates over a second or two, not in a frame.
ATTITUDE_LAG_S = 0.8
#: The world's geodetic origin: the rig's database origin, the bundled airfield's.
ORIGIN = CigiSpec().origin


@dataclass(frozen=True)
class Leg:
    """A stretch of a scripted flight.

    Attributes:
        seconds: its duration.
        speed_mps: speed along the path at its end, reached at a constant rate over the leg.
        climb_mps: vertical speed (up positive), blended in over BLEND_S.
        turn_dps: heading rate, degrees a second (right positive), blended in over BLEND_S.
        ground: on the runway: the height is held at the eye's height above it and the wings
            are level.
        pitch_deg: the nose attitude on the ground (0 rolling, up to rotate); in the air the
            pitch is the flight path's angle plus the angle of attack.
    """

    seconds: float
    speed_mps: float
    climb_mps: float = 0.0
    turn_dps: float = 0.0
    ground: bool = False
    pitch_deg: float = 0.0


@dataclass(frozen=True)
class Aircraft:
    """What a flight's attitude depends on.

    Attributes:
        eye_m: the logged position's height above the runway on the ground (the eye's).
        alpha_deg: angle of attack at alpha_speed_mps; it grows as 1 / speed^2 below it.
        alpha_speed_mps: the speed of alpha_deg.
    """

    eye_m: float
    alpha_deg: float
    alpha_speed_mps: float


@dataclass(frozen=True)
class Flight:
    """A flown script: arrays at SIM_HZ. t_s from 0; x, y, z world metres (east, north, up);
    heading, pitch, roll degrees (docs/conventions.md); speed_mps along the path."""

    t_s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    heading: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    speed_mps: np.ndarray

    def at(self, times: Sequence[float] | np.ndarray) -> dict[str, np.ndarray]:
        """Every quantity at the given times (seconds; interpolated linearly, the heading the
        short way round)."""
        t = np.asarray(times, np.float64)
        unwrapped = np.degrees(np.unwrap(np.radians(self.heading)))
        out = {name: np.interp(t, self.t_s, getattr(self, name))
               for name in ("x", "y", "z", "pitch", "roll", "speed_mps")}
        out["heading"] = np.interp(t, self.t_s, unwrapped) % 360.0
        return out


def _smoothstep(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


def fly(start: tuple[float, float, float], heading_deg: float, speed_mps: float, legs: Sequence[Leg],
        aircraft: Aircraft) -> Flight:
    """Fly a script of legs from a world position (metres), heading (degrees) and speed (m/s),
    already at the first leg's vertical speed and turn rate."""
    dt = 1.0 / SIM_HZ
    x, y, z = start
    heading, speed = heading_deg, speed_mps
    climb, turn = (0.0 if legs[0].ground else legs[0].climb_mps), legs[0].turn_dps
    rows: list[tuple[float, ...]] = []
    pitch: float | None = None
    roll: float | None = None
    for leg in legs:
        climb0, turn0, speed0, z0 = climb, turn, speed, z
        steps = round(leg.seconds * SIM_HZ)
        for k in range(steps):
            tau = k * dt
            blend = _smoothstep(tau / BLEND_S)
            climb = 0.0 if leg.ground else climb0 + (leg.climb_mps - climb0) * blend
            turn = turn0 + (leg.turn_dps - turn0) * blend
            speed = speed0 + (leg.speed_mps - speed0) * (tau / leg.seconds)
            if leg.ground:
                target_pitch, target_roll = leg.pitch_deg, 0.0
                # A touchdown settles onto the wheels over TOUCHDOWN_S from the height the
                # script reached (within a metre of the eye's), not in one step.
                z = aircraft.eye_m + (z0 - aircraft.eye_m) * (1.0 - _smoothstep(tau / TOUCHDOWN_S))
            else:
                path_deg = math.degrees(math.asin(climb / speed))
                alpha = aircraft.alpha_deg * (aircraft.alpha_speed_mps / speed) ** 2
                target_pitch = path_deg + min(alpha, 12.0)
                target_roll = math.degrees(math.atan(speed * math.radians(turn) / G_MPS2))
            # The attitude lags its target (ATTITUDE_LAG_S), starting where the script starts.
            gain = 1.0 - math.exp(-dt / ATTITUDE_LAG_S)
            pitch = target_pitch if pitch is None else pitch + (target_pitch - pitch) * gain
            roll = target_roll if roll is None else roll + (target_roll - roll) * gain
            rows.append((len(rows) * dt, x, y, z, heading % 360.0, pitch, roll, speed))
            horizontal = math.sqrt(max(speed * speed - climb * climb, 0.0))
            x += horizontal * math.sin(math.radians(heading)) * dt
            y += horizontal * math.cos(math.radians(heading)) * dt
            z += climb * dt
            heading += turn * dt
    a = np.array(rows)
    return Flight(*(a[:, i] for i in range(8)))


def wander(t: np.ndarray, amplitude_m: float, phase: float) -> np.ndarray:
    """A GNSS fix's slow wander about the truth, metres: a sum of sines of periods 7-40 s
    (deterministic, unlike a random walk, so the files never change by themselves). The
    recorders leave the height alone on the runway: a replayed eye that wandered below the
    runway would look through it."""
    periods = (40.0, 17.0, 7.3)
    weights = (0.6, 0.3, 0.1)
    out = np.zeros_like(t, dtype=np.float64)
    for i, (p, w) in enumerate(zip(periods, weights, strict=True)):
        out += w * np.sin(2 * np.pi * t / p + phase * (i + 1))
    return amplitude_m * out


def geodetic(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat deg, lon deg, height m) of world positions around ORIGIN."""
    return geodetic_of_enu(x, y, z, ORIGIN)


# -- the flights -----------------------------------------------------------------------------------

LIGHT_AIRCRAFT = Aircraft(eye_m=2.0, alpha_deg=4.0, alpha_speed_mps=33.0)
# The glider's eye is 0.8 m up: its height on the runway, 350.0 m, is a whole metre, as IGC
# stores it, so the replayed eye stays above the runway.
GLIDER = Aircraft(eye_m=0.8, alpha_deg=4.0, alpha_speed_mps=26.0)
JET = Aircraft(eye_m=3.5, alpha_deg=5.0, alpha_speed_mps=65.0)


def departure() -> Flight:
    """Lined up at the threshold of 36, a take-off, a straight climb, a right turn east."""
    return fly((0.0, -960.0, LIGHT_AIRCRAFT.eye_m), 0.0, 0.0, [
        Leg(3.0, 0.0, ground=True),  # brakes on, full power
        Leg(15.0, 27.0, ground=True),  # take-off roll
        Leg(2.0, 29.0, ground=True, pitch_deg=7.0),  # rotation
        Leg(30.0, 34.0, climb_mps=3.6),  # climb straight ahead
        Leg(30.0, 36.0, climb_mps=3.2, turn_dps=3.0),  # rate-one turn right, to the east
        Leg(20.0, 38.0, climb_mps=3.0),  # on east, climbing
    ], LIGHT_AIRCRAFT)


def circuit() -> Flight:
    """A glider's downwind leg west of the field, base, final with airbrakes, the landing."""
    return fly((-780.0, 200.0, 200.0), 180.0, 27.0, [
        Leg(60.0, 27.0, climb_mps=-1.0),  # downwind, south, past the threshold
        Leg(15.0, 27.0, climb_mps=-1.5, turn_dps=-6.0),  # turn onto base, east
        Leg(10.0, 27.0, climb_mps=-1.2),  # base
        Leg(15.0, 26.0, climb_mps=-1.6, turn_dps=-6.0),  # turn onto final, north
        Leg(20.0, 26.0, climb_mps=-3.5),  # final, airbrakes out
        Leg(4.0, 24.0, climb_mps=-1.3),  # round-out over the threshold
        Leg(6.0, 21.0, climb_mps=-0.85),  # hold-off
        Leg(18.0, 0.0, ground=True),  # ground roll to a stop
    ], GLIDER)


def low_pass() -> Flight:
    """An approach to 36 from 4.6 km out, a low pass along it, a climbing right turn away."""
    return fly((0.0, -4600.0, 313.0), 0.0, 68.0, [
        Leg(51.5, 68.0, climb_mps=-5.3),  # approach, 4.5 degrees down over the hills south
        Leg(8.0, 66.0, climb_mps=-0.9),  # shallowing out over the threshold
        Leg(14.0, 66.0),  # the low pass along the runway
        Leg(10.0, 70.0, climb_mps=8.0),  # pull up over the hedge and the power line
        Leg(20.0, 75.0, climb_mps=8.0, turn_dps=3.0),  # climbing turn right
    ], JET)


# -- the recorders ---------------------------------------------------------------------------------

def departure_csv(flight: Flight) -> str:
    """The CSV an EFIS-style logger exports: GNSS rows each second, AHRS rows each half second."""
    # From the first GNSS fix to the last: a row before or after every position could not be placed.
    times = np.arange(0.0, math.floor(float(flight.t_s[-1])) + 1e-9, 0.5)
    s = flight.at(times)
    east = s["x"] + wander(times, 0.5, 0.3)
    north = s["y"] + wander(times, 0.5, 1.7)
    up = s["z"] + np.where(s["z"] > LIGHT_AIRCRAFT.eye_m + 0.01, wander(times, 0.7, 2.9), 0.0)
    lat, lon, h = geodetic(east, north, up)
    lines = ["# ig-rig sample flight: departure from runway 36 of the bundled airfield (host_sim/replay/"
             "build_samples.py)",
             "# GNSS each second (lat_deg, lon_deg, alt_m: WGS-84, height in the airfield origin's system), AHRS "
             "each half second",
             "time_s,lat_deg,lon_deg,alt_m,heading_deg,pitch_deg,roll_deg"]
    for i, t in enumerate(times):
        gnss = abs(t - round(t)) < 1e-9
        # The GNSS loses its vertical solution for 4 s during the climb; the AHRS drops out for
        # a second in the turn.
        vertical = gnss and not 36.0 <= t < 40.0
        ahrs = not 60.0 <= t < 61.0
        if not (gnss or ahrs):
            continue  # no sensor sampled: the logger writes no row
        cells = [f"{t:.1f}",
                 f"{lat[i]:.7f}" if gnss else "", f"{lon[i]:.7f}" if gnss else "",
                 f"{h[i]:.1f}" if vertical else "",
                 f"{s['heading'][i]:.1f}" if ahrs else "", f"{s['pitch'][i]:.1f}" if ahrs else "",
                 f"{s['roll'][i]:.1f}" if ahrs else ""]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _igc_angle(value: float, degree_digits: int, positive: str, negative: str) -> str:
    """DDMMmmm / DDDMMmmm and the hemisphere letter of an IGC B record."""
    thousandths = round(abs(value) * 60000.0)
    degrees, rest = divmod(thousandths, 60000)
    return f"{degrees:0{degree_digits}d}{rest:05d}{positive if value >= 0 else negative}"


#: UTC time of day of the circuit's first fix, seconds (14:02:10).
CIRCUIT_START_S = 14 * 3600 + 2 * 60 + 10


def circuit_igc(flight: Flight) -> str:
    """An IGC file as a glider's logger writes it: headers, then a B record each second."""
    times = np.arange(0.0, math.floor(float(flight.t_s[-1])) + 1e-9, 1.0)
    s = flight.at(times)
    east = s["x"] + wander(times, 0.8, 0.7)
    north = s["y"] + wander(times, 0.8, 2.1)
    up = s["z"] + np.where(s["z"] > GLIDER.eye_m + 0.01, wander(times, 1.2, 1.3), 0.0)
    lat, lon, h = geodetic(east, north, up)
    lines = ["AXXXIGR sample logger",
             "HFDTEDATE:150626,01",
             "HFFXA035",
             "HFPLTPILOTINCHARGE:Sample Pilot",
             "HFGTYGLIDERTYPE:ASK 21",
             "HFGIDGLIDERID:D-1234",
             "HFDTMGPSDATUM:WGS84",
             "HFRFWFIRMWAREVERSION:1.0",
             "HFFTYFRTYPE:ig-rig,build_samples.py",
             "HFGPSRECEIVER:none,simulated",
             "HFPRSPRESSALTSENSOR:none,simulated",
             "HFALGALTGPS:ELL",
             "HFALPALTPRESSURE:ISA",
             "LXXXsample flight of ig-rig: a circuit to land on runway 36 of the bundled airfield"]
    for i, t in enumerate(times):
        sod = CIRCUIT_START_S + int(t)
        hh, mm, ss = sod // 3600, sod // 60 % 60, sod % 60
        gnss = round(h[i])
        # Standard-atmosphere pressure altitude: a day of lower pressure reads 38 m higher.
        pressure = round(h[i] + 38.0)
        lines.append(f"B{hh:02d}{mm:02d}{ss:02d}{_igc_angle(lat[i], 2, 'N', 'S')}"
                     f"{_igc_angle(lon[i], 3, 'E', 'W')}A{pressure:05d}{gnss:05d}")
    return "\r\n".join(lines) + "\r\n"


FT_M = 0.3048


def low_pass_fdr(flight: Flight) -> str:
    """An X-Plane FDR file: its keyword lines, then a DATA line each half second."""
    times = np.arange(0.0, math.floor(float(flight.t_s[-1]) * 2) / 2 + 1e-9, 0.5)
    s = flight.at(times)
    lat, lon, h = geodetic(s["x"], s["y"], s["z"])
    touchdown_lat, touchdown_lon, field = geodetic(np.array(0.0), np.array(-700.0), np.array(0.0))
    lines = ["A", "1", "",
             "COMM,ig-rig sample flight: an approach to runway 36 of the bundled airfield, a low pass, a climbing "
             "turn away (host_sim/replay/build_samples.py)",
             "COMM,DATA columns written: time s, temp degC, lon deg, lat deg, h msl ft, radio alt ft (above the "
             "runway), aileron, elevator, rudder, pitch deg, roll deg, heading deg true; the rest is left out",
             "ACFT,Aircraft/Laminar Research/Cessna Citation X/Cessna_CitationX.acf,",
             "TAIL,N321IG,",
             "TIME,15:20:00,",
             "DATE,15/06/26,",
             "PRES,29.92,",
             "TEMP,59,",
             "WIND,340,8,",
             f"CALI,{float(touchdown_lon):.7f},{float(touchdown_lat):.7f},{float(field) / FT_M:.0f},",
             ""]
    # Control deflections that go with the attitude's changes (the recorder logs the yoke).
    aileron = np.clip(np.gradient(s["roll"], times) / 15.0, -1.0, 1.0)
    elevator = np.clip(np.gradient(s["pitch"], times) / 5.0, -1.0, 1.0)
    for i, t in enumerate(times):
        values = (f"{t:.1f}", "15", f"{lon[i]:.7f}", f"{lat[i]:.7f}", f"{h[i] / FT_M:.1f}",
                  f"{s['z'][i] / FT_M:.1f}", f"{aileron[i]:.3f}", f"{elevator[i]:.3f}", "0.000",
                  f"{s['pitch'][i]:.2f}", f"{s['roll'][i]:.2f}", f"{s['heading'][i]:.2f}")
        lines.append("DATA," + ",".join(values) + ",")
    return "\n".join(lines) + "\n"


#: Sample name -> (flight script, recorder).
BUILDERS = {
    "departure": (departure, departure_csv),
    "circuit": (circuit, circuit_igc),
    "low-pass": (low_pass, low_pass_fdr),
}


def build(name: str) -> str:
    """The text of a sample's log."""
    script, recorder = BUILDERS[name]
    return recorder(script())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a checked-in log is not what this writes")
    parser.add_argument("--out", type=Path, default=FLIGHTS_DIR, help=f"folder of the logs (default {FLIGHTS_DIR})")
    args = parser.parse_args(argv)
    if set(BUILDERS) != set(SAMPLES):
        raise SystemExit(f"BUILDERS {sorted(BUILDERS)} and samples.SAMPLES {sorted(SAMPLES)} differ")
    stale = []
    for name, (file, _) in SAMPLES.items():
        path = args.out / file
        text = build(name)
        if args.check:
            # Bytes, not text: IGC lines end in CR LF, which reading as text would hide.
            if not path.is_file() or path.read_bytes() != text.encode("ascii"):
                stale.append(str(path))
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="ascii", newline="")
        print(f"wrote {path} ({len(text.encode())} bytes)")
    if stale:
        print(f"out of date: {', '.join(stale)}; run python -m host_sim.replay.build_samples", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
