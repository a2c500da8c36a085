"""Reference optical depth of layered fog, for tests and benchmarks only: exact integration.

The production fog (channel_worker/pipeline/fog/fog.py, the layered fog of US 5,535,374)
approximates the optical depth of every ray with a per-frame table of average extinction,
interpolated between entries. This module computes the same quantity exactly, ray by ray, so
the table's error can be measured. It is written to be obviously right, not fast, and shares
no code with fog.py: a reference that reused the production's integral (fog.cumulative) or
its interpolation (fog.sigma_at) would repeat their mistakes instead of exposing them.

The medium (world frame, metres)
--------------------------------
Parallel strata perpendicular to the unit axis n (the given axis, normalised here). A world
point p has axis position ``s = (p - origin) . n``. N sample planes lie at ``s_k = k * spacing``,
k = 0 .. N-1, with extinction sigma_k (1/metres, >= 0). Between two neighbouring planes sigma
is linear in s; below plane 0 it is sigma_0 and above plane N-1 it is sigma_{N-1}, for ever
(one plane: homogeneous fog).

The ray
-------
From the eye (world, float64) along the unit direction u (normalised here, so the ray
parameter t is the Euclidean distance from the eye), for t in [0, R]. Its axis position is
``h + t c`` with ``h = (eye - origin) . n`` and ``c = u . n``. The optical depth is

    tau = integral over t in [0, R] of sigma(h + t c) dt.

How it is integrated (exactly, no step length)
----------------------------------------------
The ray is cut at every sample plane it crosses strictly inside (0, R): ``t_k = (s_k - h) / c``.
Between two neighbouring cuts the ray stays inside one linear piece of sigma (or beyond an
end, where sigma is constant), so sigma is linear in t there and the trapezoid rule is exact:
``(t_b - t_a) (sigma_a + sigma_b) / 2``. At a cut sigma is the plane's own sample sigma_k, not
a value interpolated at a rounded position.

- c = 0 (a ray parallel to the strata): no cut; sigma is the eye's all along, tau = sigma R.
- R infinite (the sky): the finite part runs to the last cut (or the eye if there is none);
  beyond it the ray is past the end of the structure it heads to (n.u > 0: above plane N-1,
  < 0: below plane 0, = 0: in the eye's stratum) where sigma is constant: tau is infinite if
  that sigma is > 0, else the finite part alone.
- An eye outside the structure needs nothing special: its cuts are the planes ahead of it.

Everything is float64 and relative to the structure's origin (``eye - origin`` first), so a
structure and eye 1000 km from the world origin give the same result as near it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Strata:
    """The fog structure as this module reads it.

    Attributes:
        axis: (3,) float64 unit vector perpendicular to the strata.
        origin: (3,) float64 world point on sample plane 0.
        spacing: distance between sample planes along the axis, metres (> 0).
        extinction: (N,) float64 sigma at each sample plane, 1/metres (>= 0), N >= 1.
    """

    axis: np.ndarray
    origin: np.ndarray
    spacing: float
    extinction: np.ndarray


def strata(fog: Any = None, *, axis: Any = None, origin: Any = None, spacing: float | None = None,
           extinction: Any = None) -> Strata:
    """A Strata from plain arrays, or from any object with attributes axis, origin, spacing_m
    (or spacing) and extinction (e.g. scene.atmosphere.Fog; read by name only, nothing of fog.py
    is used). Keyword arrays override the object's."""
    if fog is not None:
        axis = fog.axis if axis is None else axis
        origin = fog.origin if origin is None else origin
        if spacing is None:
            spacing = getattr(fog, "spacing_m", None)
            spacing = getattr(fog, "spacing", None) if spacing is None else spacing
        extinction = fog.extinction if extinction is None else extinction
    if axis is None or origin is None or spacing is None or extinction is None:
        raise ValueError("strata: need axis, origin, spacing and extinction")
    a = np.asarray(axis, np.float64).reshape(3)
    norm = float(np.sqrt(np.sum(a * a)))
    if not (np.isfinite(a).all() and norm > 0.0):
        raise ValueError(f"strata: axis must be a nonzero finite vector, got {a.tolist()}")
    ext = np.atleast_1d(np.asarray(extinction, np.float64))
    if ext.ndim != 1 or ext.size == 0 or not (np.isfinite(ext).all() and (ext >= 0.0).all()):
        raise ValueError(f"strata: extinction must be N >= 1 finite values >= 0, got {ext}")
    dx = float(spacing)
    if not (np.isfinite(dx) and dx > 0.0):
        raise ValueError(f"strata: spacing must be finite and > 0, got {spacing}")
    return Strata(a / norm, np.asarray(origin, np.float64).reshape(3), dx, ext)


def sigma_at(st: Strata, s: np.ndarray | float) -> np.ndarray:
    """Extinction at axis positions s (metres from plane 0): linear between planes, the end
    value beyond them."""
    s = np.asarray(s, np.float64)
    n = st.extinction.size
    if n == 1:
        return np.full(s.shape, st.extinction[0])
    # Position in units of the spacing, clamped to the structure: beyond an end the clamp
    # lands on the end plane and the weight below makes that plane's value the answer.
    x = np.clip(s / st.spacing, 0.0, n - 1.0)
    k = np.minimum(np.floor(x).astype(np.int64), n - 2)
    w = x - k
    return (1.0 - w) * st.extinction[k] + w * st.extinction[k + 1]


def axis_optical_depths(st: Strata, h: float, cosines: np.ndarray,
                        ranges: np.ndarray) -> np.ndarray:
    """Exact optical depth of rays from an eye at axis position h (metres from plane 0) with
    direction cosines c with the axis, out to ranges R (metres, inf for the sky).

    Args:
        st: the structure.
        h: the eye's axis position.
        cosines: (M,) the rays' direction cosines with the axis, in [-1, 1].
        ranges: (M,) metres >= 0, or inf.

    Returns:
        (M,) float64 optical depth (inf where an infinite ray stays in fog for ever).
    """
    c = np.asarray(cosines, np.float64).reshape(-1)
    r = np.asarray(ranges, np.float64).reshape(-1)
    if c.shape != r.shape:
        raise ValueError(f"axis_optical_depths: {c.shape} cosines but {r.shape} ranges")
    sig = st.extinction
    n = sig.size
    h = float(h)
    planes = np.arange(n) * st.spacing
    infinite = np.isinf(r)

    # Ray parameter at which each ray meets each plane; a parallel ray never does (-inf: not
    # ahead of it). A cosine so small that (s_k - h) / c overflows (|c| below ~1e-300) meets
    # it at infinity: an infinite ray then sees the fog before that plane for ever.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t_cut = np.where(c[:, None] != 0.0, (planes[None, :] - h) / c[:, None], -np.inf)
    # The last cut ahead of each ray ends the finite part of an infinite ray.
    ahead = t_cut > 0.0
    t_last = np.where(ahead, t_cut, 0.0).max(axis=1)
    t_end = np.where(infinite, t_last, r)
    # Cuts strictly inside (0, t_end) only; the others become zero-length pieces at the eye.
    inside = ahead & (t_cut < t_end[:, None])
    sig_eye = float(sigma_at(st, h))
    sig_end = sigma_at(st, h + t_end * c)
    t = np.concatenate([np.zeros((r.size, 1)), np.where(inside, t_cut, 0.0), t_end[:, None]],
                       axis=1)
    s = np.concatenate([np.full((r.size, 1), sig_eye),
                        np.where(inside, sig[None, :], sig_eye), sig_end[:, None]], axis=1)
    # Sort the cuts along each ray (a stable sort keeps the eye first among the zeros).
    order = np.argsort(t, axis=1, kind="stable")
    t = np.take_along_axis(t, order, axis=1)
    s = np.take_along_axis(s, order, axis=1)
    # Where the ray ends exactly on a plane t_end equals that cut; it was excluded above
    # (t_cut < t_end), so the end point carries sigma there, interpolated: the same value.
    # A piece can be infinitely long only after an overflowing cut: clear (0), or fog for
    # ever (inf); never 0 * inf. Between two cuts both at infinity there is nothing (not
    # inf - inf).
    with np.errstate(invalid="ignore"):
        length = np.diff(t, axis=1)
        length = np.where(np.isnan(length), 0.0, length)
        mean = 0.5 * (s[:, 1:] + s[:, :-1])
        tau = np.sum(np.where(mean > 0.0, length * mean, 0.0), axis=1)

    # The tail of an infinite ray: constant sigma of the region it ends in, for ever.
    tail_sigma = np.where(c > 0.0, sig[-1], np.where(c < 0.0, sig[0], sig_eye))
    return np.where(infinite & (tail_sigma > 0.0), np.inf, tau)


def axis_position(st: Strata, eye: np.ndarray) -> float:
    """The eye's axis position h = (eye - origin) . n, metres from plane 0. The difference
    first: two nearby large world positions subtract exactly or nearly."""
    return float(np.sum((np.asarray(eye, np.float64).reshape(3) - st.origin) * st.axis))


def optical_depths(st: Strata, eye: np.ndarray, directions: np.ndarray,
                   ranges: np.ndarray) -> np.ndarray:
    """Exact optical depth of rays from one world eye position along world directions.

    Args:
        st: the structure (strata(...)).
        eye: (3,) float64 world position, metres.
        directions: (M, 3) world directions (normalised here).
        ranges: (M,) metres >= 0, or inf for the sky.

    Returns:
        (M,) float64 optical depth.
    """
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    d = d / np.sqrt(np.sum(d * d, axis=1))[:, None]
    return axis_optical_depths(st, axis_position(st, eye), d @ st.axis, ranges)


def optical_depth(st: Strata, eye: np.ndarray, direction: np.ndarray, range_m: float) -> float:
    """optical_depths for one ray."""
    return float(optical_depths(st, eye, np.asarray(direction, np.float64).reshape(1, 3),
                                np.array([range_m], np.float64))[0])


def layer_integral(st: Strata) -> float:
    """Integral of sigma along the axis from plane 0 to plane N-1 (trapezoids: exact for the
    linear pieces): what a ray crossing the whole structure at cosine c sees, divided by |c|,
    when the medium beyond both ends is clear."""
    sig = st.extinction
    return float(np.sum(0.5 * (sig[1:] + sig[:-1])) * st.spacing)
