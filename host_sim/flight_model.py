"""A simple, stable aircraft model flown by the cockpit controls (docs/host-flight-model.md).

A point mass in flight-path axes flown through a fly-by-wire style control law, the kind of
model an IG test host needs: it flies like a light aircraft, responds to every control, and no
sequence of control inputs can make it diverge. What keeps it bounded:

- the stick commands load factor on top of the 1 g that holds the flight path (a neutral
  stick keeps the flight path, as a fly-by-wire normal law does), and the wheel commands a
  bank angle; both through first-order lags discretised exactly (stable for any step);
- lift is limited by the stall (cl_max) and the load factor to [-1, 3.8] g, so the flight path
  turns at a bounded rate; the flight-path angle is held within +-GAMMA_LIMIT_DEG;
- drag grows with the square of the speed while thrust is bounded, so the speed is bounded
  (and, with the flight path held, converges to where thrust balances drag and weight);
- the ground is a floor: the wheels hold the eye at eye_height_m above it.

`step` advances the state by a fixed time step (semi-implicit Euler: speed and angles, then
the position from the new ones); the caller chooses the step, independent of the frame rate
(host_sim/controlled.py uses 100 Hz). The model is deterministic: the same initial state and
control sequence give bit-identical states.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from .inputs.base import Controls

G_MPS2 = 9.80665
#: The flight-path angle is held within this, degrees: a steep climb or dive, never a loop
#: (the point-mass model has no meaning past the vertical).
GAMMA_LIMIT_DEG = 45.0
#: Below this airspeed the turn equations use it instead (they divide by the speed), m/s.
V_MIN_MPS = 5.0


@dataclass(frozen=True)
class Aircraft:
    """Parameters of the model: a light single-engine aircraft. SI units, angles in degrees."""

    mass_kg: float = 1000.0
    wing_area_m2: float = 16.0
    air_density_kgpm3: float = 1.225
    thrust_max_n: float = 3000.0
    cl0: float = 0.3  # lift coefficient at zero angle of attack
    cl_alpha_per_rad: float = 5.0
    cl_max: float = 1.5  # stall: lift stops growing with angle of attack
    cl_flaps: float = 0.4  # added lift coefficient (and added cl_max) at full flaps
    cd0: float = 0.03
    cd_flaps: float = 0.04
    cd_speed_brake: float = 0.08
    k_induced: float = 0.055  # induced drag: cd = k cl^2
    load_factor_min: float = -1.0
    load_factor_max: float = 3.8
    tau_stick_s: float = 0.4  # the pitch command follows the stick with this lag
    alpha_neutral_deg: float = 4.0  # on the wheels: angle of attack with the stick centred
    alpha_range_deg: float = 8.0  # on the wheels: stick fully aft adds this (rotation)
    incidence_deg: float = 4.0  # wing incidence: body pitch = flight path + alpha - incidence
    bank_max_deg: float = 60.0  # full wheel
    tau_bank_s: float = 0.8
    slip_max_deg: float = 8.0  # full pedal in the air: the nose turns off the flight path
    tau_slip_s: float = 0.5
    eye_height_m: float = 3.0  # eye above the ground with the wheels on it
    ground_z_m: float = 0.0  # the ground is the plane z = ground_z_m
    rolling_friction: float = 0.02
    brake_friction: float = 0.6  # with the park brake set
    wheelbase_m: float = 2.5
    steer_max_deg: float = 30.0  # nose wheel angle at full pedal
    steer_rate_max_deg_s: float = 30.0  # fastest heading change on the ground
    pitch_ground_max_deg: float = 12.0  # tail strike: body pitch on the wheels


@dataclass(frozen=True)
class State:
    """The aircraft's state; world frame x east, y north, z up (docs/conventions.md).

    Attributes:
        x_m, y_m, z_m: eye position, metres.
        speed_mps: airspeed (no wind: also ground speed), >= 0.
        gamma_rad: flight-path angle, climb positive.
        track_rad: direction of flight, clockwise from north, [0, 2 pi).
        bank_rad: bank angle, right wing down positive.
        stick: the pitch command, the stick lagged by tau_stick_s, -1 .. 1.
        alpha_rad: angle of attack of the wing (follows from the lift the law asks for).
        slip_rad: angle from the flight path to the nose, right positive.
        on_ground: the wheels are on the ground.
    """

    x_m: float
    y_m: float
    z_m: float
    speed_mps: float = 0.0
    gamma_rad: float = 0.0
    track_rad: float = 0.0
    bank_rad: float = 0.0
    stick: float = 0.0
    alpha_rad: float = math.radians(4.0)
    slip_rad: float = 0.0
    on_ground: bool = True

    def attitude_deg(self, aircraft: Aircraft) -> tuple[float, float, float]:
        """(heading, pitch, roll) of the eye, degrees: heading in [0, 360)."""
        body_pitch = math.degrees(self.gamma_rad + self.alpha_rad) - aircraft.incidence_deg
        if self.on_ground:
            body_pitch = min(max(body_pitch, 0.0), aircraft.pitch_ground_max_deg)
        heading = math.degrees(self.track_rad + self.slip_rad) % 360.0
        return (0.0 if heading >= 360.0 else heading), body_pitch, math.degrees(self.bank_rad)


def on_runway(x_m: float, y_m: float, heading_deg: float, aircraft: Aircraft = Aircraft()) -> State:
    """At rest on the ground at (x, y), facing heading_deg."""
    return State(x_m, y_m, aircraft.ground_z_m + aircraft.eye_height_m, track_rad=math.radians(heading_deg % 360.0),
                 alpha_rad=math.radians(aircraft.incidence_deg))


def step(state: State, controls: Controls, dt_s: float, aircraft: Aircraft = Aircraft()) -> State:
    """The state dt_s seconds later, flown with the given controls (docs/host-flight-model.md).

    Controls outside their ranges are clamped and non-finite ones read as neutral, so that the
    model holds whatever reaches it.
    """
    a = aircraft
    pitch, roll, yaw = (_clamp(_finite(v), -1.0, 1.0) for v in (controls.pitch, controls.roll, controls.yaw))
    throttle, flaps, speed_brake = (_clamp(_finite(v), 0.0, 1.0)
                                    for v in (controls.throttle, controls.flaps, controls.speed_brake))
    # The park brake sets both wheel brakes; the toe brakes press them in part. The point mass
    # has no wheel track, so the two toe brakes brake as their mean and do not turn it.
    toe = 0.5 * sum(_clamp(_finite(v), 0.0, 1.0) for v in (controls.brake_left, controls.brake_right))
    braking = 1.0 if _finite(controls.park_brake) >= 0.5 else toe
    s = state
    mg = a.mass_kg * G_MPS2

    # Command responses: first-order lags towards the commands, discretised exactly
    # (x += (target - x) (1 - e^(-dt/tau))), which cannot overshoot for any step.
    stick = s.stick + (pitch - s.stick) * _lag(dt_s, a.tau_stick_s)
    bank_c = 0.0 if s.on_ground else math.radians(a.bank_max_deg * roll)  # wings level on the wheels
    slip_c = 0.0 if s.on_ground else math.radians(a.slip_max_deg * yaw)  # pedals steer on the ground
    bank = s.bank_rad + (bank_c - s.bank_rad) * _lag(dt_s, a.tau_bank_s)
    slip = s.slip_rad + (slip_c - s.slip_rad) * _lag(dt_s, a.tau_slip_s)

    q_s = 0.5 * a.air_density_kgpm3 * s.speed_mps ** 2 * a.wing_area_m2
    cl_top = a.cl_max + a.cl_flaps * flaps  # the stall
    cl_zero = a.cl0 + a.cl_flaps * flaps  # lift coefficient at zero angle of attack
    gamma, track, on_ground = s.gamma_rad, s.track_rad, s.on_ground
    if on_ground:
        # On the wheels the stick sets the angle of attack (rotation); lift from it.
        alpha = math.radians(a.alpha_neutral_deg + a.alpha_range_deg * stick)
        cl = min(cl_zero + a.cl_alpha_per_rad * alpha, cl_top)
    else:
        # The law: the load factor that holds the flight path in this bank (cos gamma /
        # cos bank), plus the stick's share, within the structural limits; the stall caps it.
        hold = math.cos(gamma) / math.cos(bank)
        extra = stick * (a.load_factor_max - 1.0 if stick > 0.0 else 1.0 - a.load_factor_min)
        n = _clamp(hold + extra, a.load_factor_min, a.load_factor_max)
        cl = _clamp(n * mg / q_s, -cl_top, cl_top) if q_s > 0.0 else cl_top
        alpha = (cl - cl_zero) / a.cl_alpha_per_rad
    lift = q_s * cl
    drag = q_s * (a.cd0 + a.cd_flaps * flaps + a.cd_speed_brake * speed_brake + a.k_induced * cl * cl)
    thrust = a.thrust_max_n * throttle

    if on_ground:
        # Rolling: friction on the weight the wings do not carry, from rolling to braked as the
        # brakes are pressed; braked, the aircraft holds while thrust stays below the friction.
        normal = max(mg - lift, 0.0)
        friction = (a.rolling_friction + (a.brake_friction - a.rolling_friction) * braking) * normal
        if s.speed_mps <= 0.0 and thrust <= friction:
            accel = 0.0
        else:
            accel = (thrust - drag - friction) / a.mass_kg
        speed = max(s.speed_mps + accel * dt_s, 0.0)
        steer = math.radians(a.steer_max_deg * yaw)
        turn = _clamp(speed * math.tan(steer) / a.wheelbase_m, -math.radians(a.steer_rate_max_deg_s),
                      math.radians(a.steer_rate_max_deg_s))
        track += turn * dt_s
        gamma = 0.0
        on_ground = lift <= mg  # lift-off once the wings carry the weight
    else:
        v = max(s.speed_mps, V_MIN_MPS)
        accel = (thrust - drag) / a.mass_kg - G_MPS2 * math.sin(gamma)
        gamma_rate = (lift * math.cos(bank) - mg * math.cos(gamma)) / (a.mass_kg * v)
        track_rate = lift * math.sin(bank) / (a.mass_kg * v * math.cos(gamma))
        speed = max(s.speed_mps + accel * dt_s, 0.0)
        limit = math.radians(GAMMA_LIMIT_DEG)
        gamma = _clamp(gamma + gamma_rate * dt_s, -limit, limit)
        track += track_rate * dt_s

    horizontal = speed * math.cos(gamma)
    x = s.x_m + horizontal * math.sin(track) * dt_s
    y = s.y_m + horizontal * math.cos(track) * dt_s
    z = s.z_m + speed * math.sin(gamma) * dt_s
    floor = a.ground_z_m + a.eye_height_m
    if z < floor or (z <= floor and on_ground):
        # Touchdown (or still rolling): the wheels stop the descent and absorb the sink rate.
        # An aircraft that has just lifted off (on_ground False at the floor) is left to climb.
        z, gamma, on_ground = floor, 0.0, True
    track %= 2.0 * math.pi
    if track >= 2.0 * math.pi:  # -1e-17 % 2 pi rounds to 2 pi
        track = 0.0
    return replace(s, x_m=x, y_m=y, z_m=z, speed_mps=speed, gamma_rad=gamma, track_rad=track, bank_rad=bank,
                   stick=stick, alpha_rad=alpha, slip_rad=slip, on_ground=on_ground)


def _lag(dt_s: float, tau_s: float) -> float:
    return 1.0 - math.exp(-dt_s / tau_s)


def _clamp(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0
