"""Haze of JP H07-76990: the share of haze colour in a pixel as a function of range and pitch.

JP H07-76990 gives ``Iout = Iorig (1 - H) + I_H H`` with ``H = f(R_S, Vis, theta)`` (slant range,
half-haze distance, pitch of the pixel's ray) limited to [0, 1]. The function used here is the
one of an exponential atmosphere: extinction ``beta(z) = ln 2 / Vis * exp(-(z - z0) / Hs)``
(Vis is the distance over which a horizontal path at height z0 is half haze; Hs the scale
height), integrated along the ray from the eye (height z_e) with elevation sine s over range R:

    tau = beta(z_e) * R * g(R s / Hs),    g(x) = (1 - exp(-x)) / x,    H = 1 - exp(-tau)

so a ray looking down into denser air is hazier than a level one of the same range, the sky
overhead (R -> infinity, s > 0: tau = beta(z_e) Hs / s) keeps most of its colour and the sky at
the horizon turns to haze colour. g is evaluated by its series near x = 0 (no 0/0 for level
rays), and Hs = infinity is homogeneous haze (g = 1). A scene without haze skips all of this.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from channel_worker.pipeline.contract import HAZE_SLOTS
from channel_worker.pipeline.scene.atmosphere import Haze

#: Beyond this optical depth a surface is 99.9 % haze: the terrain scan stops there.
OPAQUE_TAU = 7.0


def haze_params(haze: Haze | None, eye_z: float) -> np.ndarray:
    """(7,) float64 for the kernels: [on, beta at the eye, 1 / Hs, r, g, b, eye z].

    All zero when there is no haze (the kernels test params[0] once).
    """
    out = np.zeros(HAZE_SLOTS, np.float64)
    if haze is None:
        return out
    inv_hs = 0.0 if math.isinf(haze.scale_height_m) else 1.0 / haze.scale_height_m
    out[:] = (1.0, beta_at(haze, eye_z), inv_hs, haze.colour[0], haze.colour[1], haze.colour[2],
              eye_z)
    return out


def beta_at(haze: Haze, z: float) -> float:
    """Extinction coefficient at world height z, 1/metres."""
    inv_hs = 0.0 if math.isinf(haze.scale_height_m) else 1.0 / haze.scale_height_m
    # Guard: the scene parser requires visibility_m > 0 and scale_height_m > 0. The exponent is
    # clamped: an eye far below the base height would overflow to inf.
    return math.log(2.0) / haze.visibility_m * math.exp(min(-(z - haze.base_height_m) * inv_hs, 700.0))


@njit(cache=True, inline="always")
def haze_amount(params, range_m, sin_elev):
    """H in [0, 1] for a surface at range_m (metres, may be inf for the sky) along a ray whose
    elevation sine is sin_elev."""
    beta = params[1]
    if beta <= 0.0 or range_m <= 0.0:
        return 0.0  # no air to see through (beta underflows 1e3 scale heights above the base)
    x = range_m * sin_elev * params[2]
    if math.isinf(range_m):
        if sin_elev <= 0.0 or params[2] == 0.0:
            return 1.0  # a level or homogeneous path to infinity is all haze
        tau = beta / (sin_elev * params[2])  # guard: both factors > 0 here
    elif abs(x) < 1e-4:
        tau = beta * range_m * (1.0 - 0.5 * x + x * x / 6.0)
    elif x < -700.0:
        # Far down into air e^700 times denser: exp(-x) would overflow; in logarithms,
        # log tau = log beta + log R - x - log(-x). Guard: beta, R > 0 and -x > 700.
        log_tau = math.log(beta) + math.log(range_m) - x - math.log(-x)
        if log_tau > 50.0:
            return 1.0
        tau = math.exp(log_tau)
    else:
        # Guard: |x| >= 1e-4 so the division is safe.
        tau = beta * range_m * (-math.expm1(-x)) / x
    return -math.expm1(-tau)


def haze_amount_py(haze: Haze, eye_z: float, range_m: float, sin_elev: float) -> float:
    """haze_amount for one ray from Python (tests, reports)."""
    return float(haze_amount(haze_params(haze, eye_z), float(range_m), float(sin_elev)))
