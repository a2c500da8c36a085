"""The lines the terrain is cast along (docs/terrain.md, section 1): screen lines through the
vertical vanishing point, each the image of one vertical half-plane through the eye.

A vertical half-plane through the eye (one azimuth) projects onto a screen line through V, the
image of the nadir or the zenith: at pitch 0 and roll 0 V lies at infinity below the screen
and the lines are the screen's columns (the classic Voxel Space column renderer); at any roll
and pitch they fan out from V (as Voxlap casts them). The screen is split into four wedges by
the two diagonals through V. A wedge's lines are aimed at the pixel centres of the screen edge
it faces, one a pixel, and stepped a pixel row (the UP and DOWN wedges) or column (LEFT and
RIGHT) at a time from that edge towards V: lines converge towards V, so at every step
neighbouring lines are at most one pixel apart and every pixel of the wedge holds the point
of at least one line (the aimed edge is continued past the screen's corners as far as the
wedge's lines still cross the screen, and two spare lines go past each end). A pixel belongs
to the line whose point in it is nearest its centre (ties to the lower line), if its centre
lies in the wedge; the wedge test is one homogeneous expression of the pixel centre and V, the
same in every wedge, so the wedges share no pixel and miss none (ties on a diagonal go to UP
and DOWN, the pixel at V itself to UP). Near V many lines fall in one pixel: the nearest
takes it, the others pass it by. The owner writes the pixel interpolated between itself and
the neighbouring line on the other side of the pixel's centre (_cast_kernels._write), so every
pixel, the channel's border pixels where channels join included, shows its own azimuth.
"""

from __future__ import annotations

import math

import numpy as np

from channel_worker.pipeline.contract import FrameConstants

from ._cast_kernels import DOWN, LEFT, RIGHT, UP
from ._groups import LineFan

#: Extra lines past each end of a wedge's computed range: a line that owns nothing costs a
#: pass over its steps, a missing one a hole.
_SPARE_LINES = 2

#: V's weight below which V is taken to lie at infinity, relative to its coordinates.
_FAR_V = 1e-9


def line_fan(frame: FrameConstants) -> LineFan:
    """The fan of lines covering the frame's pixels (module docstring)."""
    w, h = frame.width, frame.height
    m0, m1, m2, m3 = (float(v) for v in frame.mapping)
    rot = np.asarray(frame.world_to_eye, np.float64)
    down = rot @ np.array([0.0, 0.0, -1.0])  # the nadir in eye coordinates
    # V, homogeneous in screen pixels: the image of the nadir (weight > 0: in front), of the
    # zenith (the nadir behind: weight < 0, all signs turned), or a direction (weight 0).
    vx = m0 * down[0] + m1 * down[2]
    vy = m2 * down[1] + m3 * down[2]
    vw = float(down[2])
    nadir = vw >= 0.0
    if vw < 0.0:
        vx, vy, vw = -vx, -vy, -vw
    if vw <= _FAR_V * max(abs(vx), abs(vy)):
        # V beyond 1e9 pixels: parallel lines stray from the true fan by less than a
        # thousandth of a pixel across any screen, and V's coordinates would overflow the
        # projections below.
        vw = 0.0
    qa = np.array([-0.5, h - 0.5, -0.5, w - 0.5])
    nmajor = np.array([h, h, w, w], np.int64)
    nminor = np.array([w, w, h, h], np.int64)
    vp = np.array([vx, vx, vy, vy])
    vq = np.array([-vy, vy, -vx, vx])
    wedges, aims, slopes = [], [], []
    for wedge in (UP, DOWN, LEFT, RIGHT):
        lo, hi = _aim_range(float(vp[wedge]), float(vq[wedge]), vw, float(qa[wedge]),
                            int(nmajor[wedge]), int(nminor[wedge]), wedge >= LEFT)
        if lo > hi:
            continue
        j = np.arange(math.floor(lo - 0.5) - _SPARE_LINES, math.ceil(hi - 0.5) + _SPARE_LINES + 1)
        aim = j + 0.5
        den = qa[wedge] * vw - vq[wedge]
        # Guard: den = 0 puts V on the aimed row itself: the wedge's lines are single points.
        slope = (aim * vw - vp[wedge]) / den if den != 0.0 else np.zeros_like(aim)
        wedges.append(np.full(aim.shape, wedge, np.int64))
        aims.append(aim)
        slopes.append(slope)
    if not aims:  # cannot happen: every pixel lies in some wedge
        raise ValueError("line_fan: no wedge holds a pixel")
    wedge_of = np.concatenate(wedges)
    aim = np.concatenate(aims)
    slope = np.concatenate(slopes)
    prev = np.zeros(aim.shape, np.bool_)
    prev[1:] = wedge_of[1:] == wedge_of[:-1]
    nxt = np.zeros(aim.shape, np.bool_)
    nxt[:-1] = prev[1:]
    # Each line's azimuth from its aimed point, on the aimed side of V (the half-plane's own
    # side; at V itself, where a line is a point, any azimuth is right).
    q = qa[wedge_of]
    sx = np.choose(wedge_of, [aim, aim, -q, q])
    sy = np.choose(wedge_of, [-q, q, aim, aim])
    rays = np.stack([(sx - m1) / m0, (sy - m3) / m2, np.ones_like(sx)], axis=1) @ rot
    phi = np.arctan2(rays[:, 0], rays[:, 1])
    return LineFan(wedge_of, np.ascontiguousarray(aim), np.ascontiguousarray(slope), prev, nxt,
                   np.sin(phi), np.cos(phi), qa, nmajor, nminor, vp, vq, vw, bool(nadir))


def _aim_range(vp: float, vq: float, vw: float, qa: float, nmajor: int, nminor: int,
               strict: bool) -> tuple[float, float]:
    """The p range on the aimed row (q = qa) of the lines through V that reach the wedge's
    part of the screen, in the wedge's coordinates; lo > hi if the wedge holds no pixel."""
    q_lo, q_hi = qa + 0.5 - nmajor, qa + 0.5  # the screen's pixel edges along q
    corners_p = (0.0, float(nminor))
    if vw == 0.0:
        # V at infinity: parallel lines, leaving V along -(vp, vq); the wedge is the whole
        # screen or none of it.
        if not (-vq > abs(vp) if strict else -vq >= abs(vp) and -vq > 0.0):
            return 1.0, 0.0
        slope = vp / vq  # guard: -vq > 0
        ps = [p + (qa - q) * slope for p in corners_p for q in (q_lo, q_hi)]
        return min(ps), max(ps)
    big_p, big_q = vp / vw, vq / vw  # guard: vw > 0
    if big_q > qa:
        return 1.0, 0.0  # V beyond the aimed row: no pixel centre on the aimed side of it
    reach = qa - big_q
    lo, hi = big_p - reach, big_p + reach  # the diagonals through V
    if q_lo > big_q:
        # The screen lies wholly on the aimed side of V: its corners bound its shadow.
        ps = [big_p + (p - big_p) * reach / (q - big_q) for p in corners_p for q in (q_lo, q_hi)]
        lo, hi = max(lo, min(ps)), min(hi, max(ps))
    return lo, hi
