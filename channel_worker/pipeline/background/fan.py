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
of at least one line. A pixel belongs to the first line (lowest along the edge) whose point
falls in it, if its centre lies in the wedge; the wedge test is one homogeneous expression of
the pixel centre and V, the same in every wedge, so the wedges share no pixel and miss none
(ties on a diagonal go to UP and DOWN, the pixel at V itself to UP). Near V many lines fall
in one pixel: the first takes it, the others pass it by. A pixel lies within half a pixel of
its line's point across the line; the lines through the pixel centres of the aimed edges are
exact, so the channel's borders, where channels join, are sampled at their own pixels.
"""

from __future__ import annotations

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
    # The border pixels' centres, each once (screen x, y).
    cols = np.arange(w) + 0.5
    rows = np.arange(1, h - 1) + 0.5
    bx = np.concatenate([cols, cols, np.full(rows.size, 0.5), np.full(rows.size, w - 0.5)])
    by = np.concatenate([np.full(w, 0.5), np.full(w, h - 0.5), rows, rows])
    bx, by = np.unique(np.stack([bx, by], axis=1), axis=0).T  # one-pixel-wide screens
    wedges, aims, slopes, points = [], [], [], []
    for wedge in (UP, DOWN, LEFT, RIGHT):
        # The wedge's own coordinates of the border centres, and their offsets from V
        # (homogeneous: (p vw - vp, q vw - vq), pointing away from V).
        p_c = bx if wedge in (UP, DOWN) else by
        q_c = np.choose(wedge, [-by, by, -bx, bx])
        dp = p_c * vw - vp[wedge]
        dq = q_c * vw - vq[wedge]
        # Aimed at: the border pixels where the wedge's lines leave the screen (moving on
        # away from V leaves it: the edge the wedge faces, and the side edges on V's far
        # side), in the wedge or within _SPARE_LINES pixels of it across a diagonal.
        # (With V at infinity every pixel has one direction: a wedge holds all or none.) A
        # border pixel all but on V's own row or column is left out: its slope would
        # overflow, and the lines beside it reach that pixel.
        far = _leaves_screen(bx, by, vx, vy, vw, w, h)
        tiny = 1e-9 * max(vw, abs(vp[wedge]), abs(vq[wedge]))
        keep = far & (dq > tiny) & (dq + _SPARE_LINES * vw >= np.abs(dp))
        if not keep.any():
            continue
        p_c, q_c, dp, dq = p_c[keep], q_c[keep], dp[keep], dq[keep]
        slope = dp / dq  # guard: dq > 0
        aim = p_c + (qa[wedge] - q_c) * slope  # p where the line crosses the aimed row
        order = np.argsort(aim, kind="stable")
        wedges.append(np.full(order.size, wedge, np.int64))
        aims.append(aim[order])
        slopes.append(slope[order])
        points.append(np.stack([bx[keep][order], by[keep][order]], axis=1))
    if not aims:  # cannot happen: every pixel lies in some wedge
        raise ValueError("line_fan: no wedge holds a pixel")
    wedge_of = np.concatenate(wedges)
    aim = np.concatenate(aims)
    slope = np.concatenate(slopes)
    prev = np.zeros(aim.shape, np.bool_)
    prev[1:] = wedge_of[1:] == wedge_of[:-1]
    nxt = np.zeros(aim.shape, np.bool_)
    nxt[:-1] = prev[1:]
    # Each line's azimuth from its border pixel's centre, on the aimed side of V (the
    # half-plane's own side); at V itself any azimuth is right.
    sx, sy = np.concatenate(points).T
    rays = np.stack([(sx - m1) / m0, (sy - m3) / m2, np.ones_like(sx)], axis=1) @ rot
    phi = np.arctan2(rays[:, 0], rays[:, 1])
    return LineFan(wedge_of, np.ascontiguousarray(aim), np.ascontiguousarray(slope), prev, nxt,
                   np.sin(phi), np.cos(phi), qa, nmajor, nminor, vp, vq, vw, bool(nadir))


def _leaves_screen(bx: np.ndarray, by: np.ndarray, vx: float, vy: float, vw: float,
                   w: int, h: int) -> np.ndarray:
    """Which border centres (bx, by) are where a ray from V through them leaves the screen:
    on the edge it is heading for (the wedge's aimed edge, or a side edge V lies inside of)."""
    dx = bx * vw - vx  # the ray's direction away from V (homogeneous, vw >= 0)
    dy = by * vw - vy
    return (((by == 0.5) & (dy < 0.0)) | ((by == h - 0.5) & (dy > 0.0))
            | ((bx == 0.5) & (dx < 0.0)) | ((bx == w - 0.5) & (dx > 0.0)))
