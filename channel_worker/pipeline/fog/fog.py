"""Non-homogeneous layered fog of US 5,535,374: parallel strata of extinction.

The scene defines the fog in world space (docs/scene-format.md "fog") as the extinction
coefficient sigma_k (1/metres) at equally spaced parallel sample planes: plane k lies at
distance s_k = k * spacing from the origin along the unit axis n. Between planes sigma is
linear; beyond the first and last plane it keeps the end value, so one plane is homogeneous
fog. A feature at range R whose ray makes direction cosine c with the axis is seen through
optical depth

    tau = integral of sigma along the ray = R * A(d),    d = R * c,

where A(d) is the average of sigma over the axis interval from the eye to distance d along it
(the strata are parallel, so the ray's path through each stratum is its axis thickness / c).
Its colour goes towards the fog colour: ``out = T * colour + (1 - T) * fog``, T = exp(-tau).

Per frame (fog_params): the eye's axis position h_e = (eye - origin) . n in float64; the
structure resampled onto planes through the eye, spaced table_spacing apart (an eighth of the
sample spacing unless the scene says otherwise), far enough on both sides to pass the
structure's ends by one spacing; and at each, the average A(d_j) from the exact integral of
the piecewise-linear sigma (the resampling loses no thin layer: every table entry is exact,
only the interpolation between entries is approximate), with sigma there.

Per sample (fog_depth): d addresses the table. Between two entries the integral I(d) = A(d) d
is interpolated as a cubic from its values and slopes (sigma) at both: exact where sigma is
linear across the cell, so only the cells holding a sample plane (a kink) are approximate,
and the error falls with the square of the table spacing. US 5,535,374's linear interpolation
of the average, at its spacing, misses by up to 0.10 in transmission on the bench's fog, this at
the default by 8.4e-4 (bench/README.md "Fog"): a grazing ray multiplies any error in I by
1 / |c|, and the average of a layer seen from afar falls like 1 / d, which no straight line
follows. The slopes are limited so the cubic never turns back (and in the eye's two cells,
whose slope at the eye is kept, it is held at its first peak). Beyond the table sigma is
constant, so A(d) = sigma_end + (A_end - sigma_end) d_end / d exactly (|d| > |d_end| >=
table_spacing > 0 there). A ray parallel to the strata has d = 0: A(0) = sigma at
the eye, the table's own entry, so nothing divides by c and T is continuous as the ray tilts
away. The sky (R infinite) sees R * A(R c) -> I_end / |c| on the side where the fog ends
clear (I_end: the integral from the eye to the table's end), all fog where it does not.

A scene without fog skips all of this (fog_params gives zeros; the kernels test one flag).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from channel_worker.pipeline.contract import (
    F_AXIS,
    F_COARSENED,
    F_DT,
    F_INT_HI,
    F_INT_LO,
    F_INV_DT,
    F_J0,
    F_N,
    F_ON,
    F_PEAK_DN,
    F_PEAK_UP,
    F_RGB,
    F_SIG_EYE,
    F_SIG_HI,
    F_SIG_LO,
    F_TABLE,
    F_TURN_DN,
    F_TURN_UP,
    F_WORLD_AXIS,
    View,
    clear_air,
)
from channel_worker.pipeline.scene.atmosphere import Fog
from services.rig.options import RenderOptions

#: Resample planes per sample plane spacing by default (RenderOptions.fog_table_subdivision;
#: US 5,535,374 spaces them equally; an eighth keeps the worst transmission error under 0.001,
#: a fifth of an 8-bit step, at the same cost per sample and microseconds per frame:
#: bench/README.md "Fog").
TABLE_SUBDIVISION = RenderOptions.fog_table_subdivision

#: Most table entries per frame: an eye far outside a finely sampled structure coarsens the
#: table spacing instead (counted by FogTable.coarsened); 2**16 entries are 0.5 MB.
MAX_TABLE = 1 << 16


def cumulative(fog: Fog, s: np.ndarray | float) -> np.ndarray:
    """Integral of sigma along the axis from sample plane 0 to axis position s (metres), exact
    for the piecewise-linear structure (negative below plane 0)."""
    s = np.asarray(s, np.float64)
    sig = fog.extinction
    dx = fog.spacing_m
    n = sig.shape[0]
    # Integral at each sample plane (trapezoids are exact for linear pieces).
    at_plane = np.concatenate([[0.0], np.cumsum(0.5 * (sig[1:] + sig[:-1]) * dx)])
    top = (n - 1) * dx
    k = np.clip(np.floor(s / dx), 0, max(n - 2, 0)).astype(np.int64)
    inside = (s > 0.0) & (s < top)
    t = s - k * dx
    if n > 1:
        slope = (sig[np.minimum(k + 1, n - 1)] - sig[k]) / dx  # guard: dx > 0 (Fog checks)
        mid = at_plane[k] + sig[k] * t + 0.5 * slope * t * t
    else:
        mid = np.zeros_like(s)
    below = sig[0] * s
    above = at_plane[-1] + sig[-1] * (s - top)
    return np.where(s <= 0.0, below, np.where(inside, mid, above))


def sigma_at(fog: Fog, s: np.ndarray | float) -> np.ndarray:
    """Extinction coefficient at axis position s (metres from plane 0), 1/metres."""
    planes = np.arange(fog.extinction.shape[0]) * fog.spacing_m
    return np.interp(np.asarray(s, np.float64), planes, fog.extinction)


def average_floor(fog: Fog, eye: np.ndarray, d_lo: float, d_hi: float) -> float:
    """A lower bound on the average extinction A(d) from the eye to any axis distance d in
    [d_lo, d_hi] (metres; the terrain scan stops where range x bound passes opaque).

    Exact over cells of a fine grid: in a cell [a, b] with 0 < a the integral grows, so
    A(d) = I(d) / d >= I(a) / b (likewise below the eye); a cell holding the eye averages sigma
    over a part of it, so at least its least sigma.
    """
    h_e = -float(np.dot(fog.origin - np.asarray(eye, np.float64), fog.axis))
    step = fog.spacing_m / TABLE_SUBDIVISION
    n = min(max(math.ceil((d_hi - d_lo) / step), 1), 4096)
    edges = np.linspace(d_lo, d_hi, n + 1)
    a, b = edges[:-1], edges[1:]
    integral = cumulative(fog, h_e + edges) - float(cumulative(fog, h_e))
    i_a, i_b = integral[:-1], integral[1:]
    bound = np.empty(n)
    up, down = a > 0.0, b < 0.0
    bound[up] = i_a[up] / b[up]  # guard: b > a > 0
    bound[down] = i_b[down] / a[down]  # guard: a < b < 0
    eye_cell = ~(up | down)
    if eye_cell.any():
        planes = np.arange(fog.extinction.shape[0]) * fog.spacing_m
        lo, hi = h_e + float(a[eye_cell][0]), h_e + float(b[eye_cell][-1])
        inside = fog.extinction[(planes > lo) & (planes < hi)]
        least = min(float(sigma_at(fog, lo)), float(sigma_at(fog, hi)),
                    float(inside.min()) if inside.size else math.inf)
        bound[eye_cell] = least
    # Rounding of the integrals (an eye a step from a plane) must not make it negative.
    return max(float(bound.min()), 0.0)


@dataclass(frozen=True)
class FogTable:
    """One frame's fog for the kernels.

    Attributes:
        params: float64 array laid out as F_* (the haze's slots before them zero; all zero
            without fog).
        eye_axis_m: the eye's axis position h_e, metres from sample plane 0.
        coarsened: whether the table spacing was widened to stay within MAX_TABLE entries.
    """

    params: np.ndarray
    eye_axis_m: float
    coarsened: bool


def fog_params(fog: Fog | None, view: View | None, eye: np.ndarray | None = None, *,
               subdivision: int = TABLE_SUBDIVISION) -> FogTable:
    """The per-frame fog table for one view (or, view None, for a bare eye position: tests and
    the bench give the eye and use the world axis only).

    Args:
        subdivision: resample planes per sample-plane spacing where the scene sets no
            table_spacing_m (RenderOptions.fog_table_subdivision).
    """
    if fog is None:
        return FogTable(clear_air(), 0.0, False)
    if eye is None:
        if view is None:
            raise ValueError("fog_params: give a view or an eye position")
        eye = view.eye
    # US 5,535,374: the eyepoint's place in the strata is the dot product of the eye-to-origin
    # vector with the axis (here negated: distance of the eye above plane 0), in float64.
    h_e = -float(np.dot(fog.origin - np.asarray(eye, np.float64), fog.axis))
    sig = fog.extinction
    top = (sig.shape[0] - 1) * fog.spacing_m
    dt = (fog.spacing_m / subdivision if fog.table_spacing_m is None
          else float(fog.table_spacing_m))
    # Entries below the eye: enough to pass plane 0 by one spacing (at least one); above,
    # to pass the top plane likewise.
    below = max(math.ceil(h_e / dt), 0) + 1
    above = max(math.ceil((top - h_e) / dt), 0) + 1
    coarsened = below + above + 1 > MAX_TABLE
    if coarsened:
        # The axis span the entries must cover, in MAX_TABLE entries: the two ceilings, the
        # spacing past each end and the eye's entry add at most 5. Guard: the span is > 0
        # here (else below + above + 1 <= 3).
        dt = (max(h_e, 0.0) + max(top - h_e, 0.0)) / (MAX_TABLE - 5)
        below = max(math.ceil(h_e / dt), 0) + 1
        above = max(math.ceil((top - h_e) / dt), 0) + 1
    n = below + above + 1
    d = (np.arange(n) - below) * dt  # axis distance of each resample plane from the eye
    c_eye = float(cumulative(fog, h_e))
    integral = cumulative(fog, h_e + d) - c_eye
    # The integral grows away from the eye; rounding (the eye a step from a plane) must not
    # give it the wrong sign or make it shrink: a negative depth would brighten the picture.
    integral[below:] = np.maximum.accumulate(np.maximum(integral[below:], 0.0))
    integral[:below + 1] = np.minimum.accumulate(np.minimum(integral[:below + 1], 0.0)[::-1])[::-1]
    sig_eye = float(sigma_at(fog, h_e))
    avg = np.empty(n)
    nz = d != 0.0
    avg[nz] = integral[nz] / d[nz]  # guard: only the eye's own entry has d = 0
    avg[below] = sig_eye
    out = np.zeros(F_TABLE + 2 * n, np.float64)
    out[F_ON] = 1.0
    out[F_RGB:F_RGB + 3] = fog.colour
    if view is not None:
        # World direction of eye ray (tx, ty, 1) is (tx, ty, 1) @ world_to_eye.
        out[F_AXIS:F_AXIS + 3] = view.world_to_eye @ fog.axis
    out[F_INV_DT] = 1.0 / dt  # guard: dt > 0
    out[F_DT] = dt
    out[F_J0] = below
    out[F_N] = n
    out[F_SIG_EYE] = sig_eye
    out[F_SIG_LO] = sig[0]
    out[F_SIG_HI] = sig[-1]
    out[F_INT_LO] = integral[0]
    out[F_INT_HI] = integral[-1]
    out[F_WORLD_AXIS:F_WORLD_AXIS + 3] = fog.axis
    out[F_COARSENED] = float(coarsened)
    # Interleaved: the average to plane j, then the integral's slope there (sigma), limited
    # (Fritsch-Carlson) so that the cubic between planes never turns back: the integral only
    # grows away from the eye. Exact data (sigma linear across a cell) are never limited: there
    # the slopes are at most twice the cell's mean. The eye's own slope is sigma at the eye,
    # kept: it is the parallel ray's extinction.
    slope = sigma_at(fog, h_e + d)
    step = np.abs(np.diff(integral)) / dt  # mean sigma over each cell
    cap = np.full(n, np.inf)
    cap[:-1] = 3.0 * step
    cap[1:] = np.minimum(cap[1:], 3.0 * step)
    cap[below] = np.inf
    slope = np.minimum(slope, cap)
    out[F_TABLE::2] = avg
    out[F_TABLE + 1::2] = slope
    # The eye's two cells keep the eye's slope, so their cubics may turn back: fog_depth holds
    # them at their first peak from there on.
    out[F_TURN_UP], out[F_PEAK_UP] = _eye_cell_turn(sig_eye, avg[below + 1], slope[below + 1])
    out[F_TURN_DN], out[F_PEAK_DN] = _eye_cell_turn(sig_eye, avg[below - 1], slope[below - 1])
    return FogTable(out, h_e, coarsened)


def _eye_cell_turn(s_eye: float, a_far: float, s_far: float) -> tuple[float, float]:
    """(w, P): the first point w in (0, 1) of an eye cell where its cubic
    P(w) = I / dt = (w^3 - 2 w^2 + w) s_eye + (3 w^2 - 2 w^3) a_far + (w^3 - w^2) s_far
    stops growing, and P there; (inf, 0) if it grows across the whole cell."""
    # P'(w) = a w^2 + b w + c, with P'(0) = s_eye >= 0.
    a = 3.0 * s_eye - 6.0 * a_far + 3.0 * s_far
    b = -4.0 * s_eye + 6.0 * a_far - 2.0 * s_far
    c = s_eye
    roots = np.roots([a, b, c]) if (a != 0.0 or b != 0.0) else np.zeros(0)
    real = sorted(float(r.real) for r in np.atleast_1d(roots)
                  if abs(r.imag) <= 1e-12 * max(1.0, abs(r.real)) and 0.0 < r.real < 1.0)
    for w in real:
        # A root where the slope goes from rising to falling (a double root only touches 0).
        if a * 2.0 * w + b < 0.0:
            return w, (w ** 3 - 2 * w ** 2 + w) * s_eye + (3 * w ** 2 - 2 * w ** 3) * a_far \
                + (w ** 3 - w ** 2) * s_far
    return math.inf, 0.0


@njit(cache=True, inline="always")
def fog_depth(f, range_m, cos_ax):
    """Optical depth of the fog block f (fog_params) along a ray of direction cosine cos_ax
    with the axis, from the eye to range_m (metres; inf for the sky)."""
    if math.isinf(range_m):
        if cos_ax > 0.0:
            if f[F_SIG_HI] > 0.0:
                return math.inf
            # Guard: cos_ax > 0; a tiny one gives inf (the integral is >= 0, never NaN).
            return f[F_INT_HI] / cos_ax
        if cos_ax < 0.0:
            if f[F_SIG_LO] > 0.0:
                return math.inf
            return f[F_INT_LO] / cos_ax  # guard: cos_ax < 0 (and the integral is <= 0)
        return math.inf if f[F_SIG_EYE] > 0.0 else 0.0
    d = range_m * cos_ax
    u = d * f[F_INV_DT] + f[F_J0]
    n = f[F_N]
    if u <= 0.0:
        d_end = -f[F_J0] * f[F_DT]
        # Beyond the table sigma is constant. Guard: u <= 0 means |d| >= |d_end| >= dt > 0.
        avg = f[F_SIG_LO] + (f[F_TABLE] - f[F_SIG_LO]) * (d_end / d)
    elif u >= n - 1.0:
        d_end = (n - 1.0 - f[F_J0]) * f[F_DT]
        last = F_TABLE + 2 * (int(n) - 1)
        avg = f[F_SIG_HI] + (f[last] - f[F_SIG_HI]) * (d_end / d)  # guard: d >= d_end >= dt
    else:
        i = int(u)
        w = u - i
        e = F_TABLE + 2 * i
        a0 = f[e]
        s0 = f[e + 1]
        a1 = f[e + 2]
        s1 = f[e + 3]
        dt = f[F_DT]
        k = i - f[F_J0]  # the cell spans axis distances k dt .. (k + 1) dt from the eye
        # The integral I(d) = A(d) d is cubic-Hermite interpolated from its values and slopes
        # (sigma) at the cell's ends: exact where sigma is linear across the cell, so only
        # cells holding a sample plane (a kink of sigma) are approximate.
        w2 = w * w
        w3 = w2 * w
        if k == 0.0:
            # From the eye up: I(0) = 0, so I / d needs no division and tends to sigma at
            # the eye (s0) as d -> 0: the parallel ray. Kept within the cell's ends' values
            # (I between 0 and a1 dt): the eye's slope is not limited.
            avg = (w2 - 2.0 * w + 1.0) * s0 + (3.0 * w - 2.0 * w2) * a1 + (w2 - w) * s1
            if w > f[F_TURN_UP]:
                # Past the cubic's first peak: held there (the depth never falls with range).
                # Guard: w > F_TURN_UP > 0.
                avg = max(avg, f[F_PEAK_UP] / w)
            avg = max(avg, 0.0)
            if w > 0.0 and avg * w > a1:
                avg = a1 / w  # guard: w > 0
        elif k == -1.0:
            # From the eye down (d = (w - 1) dt, I(d) at w = 1 is 0): the mirror image.
            v = 1.0 - w
            v2 = v * v
            avg = (v2 - 2.0 * v + 1.0) * s1 + (3.0 * v - 2.0 * v2) * a0 + (v2 - v) * s0
            if v > f[F_TURN_DN]:
                avg = max(avg, f[F_PEAK_DN] / v)  # guard: v > F_TURN_DN > 0
            avg = max(avg, 0.0)
            if v > 0.0 and avg * v > a0:
                avg = a0 / v  # guard: v > 0
        else:
            i0 = a0 * k * dt
            i1 = a1 * (k + 1.0) * dt
            integral = ((2.0 * w3 - 3.0 * w2 + 1.0) * i0 + (w3 - 2.0 * w2 + w) * dt * s0
                        + (3.0 * w2 - 2.0 * w3) * i1 + (w3 - w2) * dt * s1)
            avg = integral / d  # guard: |d| >= dt > 0 outside the eye's two cells
    return avg * range_m


@njit(cache=True, inline="always")
def fog_cos(f, tx, ty, ray):
    """Direction cosine with the fog axis of eye ray (tx, ty, 1) of length ray (>= 1)."""
    return (f[F_AXIS] * tx + f[F_AXIS + 1] * ty + f[F_AXIS + 2]) / ray


@njit(cache=True, inline="always")
def fog_blend(f, range_m, cos_ax, r, g, b):
    """(r, g, b) seen through the fog block f at range_m along a ray of axis cosine cos_ax."""
    t = math.exp(-fog_depth(f, range_m, cos_ax))
    k = 1.0 - t
    return t * r + k * f[F_RGB], t * g + k * f[F_RGB + 1], t * b + k * f[F_RGB + 2]


@njit(cache=True)
def fog_depths(f, range_m, cos_ax):
    """fog_depth for arrays of rays (tests and the bench)."""
    out = np.empty(range_m.shape[0])
    for i in range(range_m.shape[0]):
        out[i] = fog_depth(f, range_m[i], cos_ax[i])
    return out
