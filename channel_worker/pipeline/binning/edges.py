"""Edge setup: every projected feature edge as a line equation, plus per-feature bounds.

Two forms of each edge are kept, for two different jobs (EP 0611020):

- the normalised line equation d = e x + f y + g, divided by the edge length so that
  substituting a point gives its perpendicular distance in pixels (positive inside). The
  binning stage compares it with the limiting distance dcrit = |e a| + |f b| of a sub-area;
- the exact integer edge function E = ia X + ib Y + ic on the 1/SUBPIXEL grid, which decides
  per sample, with the top-left rule, whether a sample is inside. Both come from the same
  snapped vertices, so a sub-area the normalised form calls fully covered is covered by the
  exact test at every sample (the binning stage adds a guard band for rounding).
"""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import SUBPIXEL, Edges, ScreenPolygons


def setup_edges(screen: ScreenPolygons, width: int, height: int) -> Edges:
    """Line equations and bounds of every edge and polygon of the frame.

    Polygons arrive with negative doubled area in y-down screen coordinates (project.py), so
    E(P) = (Px - X0) dy - (Py - Y0) dx is positive inside. An edge is a left edge when dy > 0
    and a top edge when dy == 0 and dx < 0; samples exactly on it belong to the polygon.
    Guard: projection drops repeated consecutive vertices, so no edge has zero length and the
    normalisation never divides by zero.
    """
    fixed = screen.fixed
    start = screen.start
    n = screen.polygon_count
    nv = fixed.shape[0]
    if n == 0:
        z = np.zeros(0, np.int64)
        zf = np.zeros(0, np.float64)
        return Edges(zf, zf, zf, z, z, z, z, z, z, z, z, zf)
    counts = np.diff(start)
    poly_of = np.repeat(np.arange(n), counts)
    nxt = np.arange(nv) + 1
    last = start[1:] - 1
    nxt[last] = start[:-1]
    x0i, y0i = fixed[:, 0], fixed[:, 1]
    dx = fixed[nxt, 0] - x0i
    dy = fixed[nxt, 1] - y0i
    ia = dy
    ib = -dx
    ic = y0i * dx - x0i * dy
    bias = np.where((dy > 0) | ((dy == 0) & (dx < 0)), 0, 1).astype(np.int64)

    inv_sub = 1.0 / SUBPIXEL
    length = np.hypot(dx, dy) * inv_sub
    e = dy * inv_sub / length
    f = -dx * inv_sub / length
    g = (y0i * dx - x0i * dy) * (inv_sub * inv_sub) / length

    # A pixel x holds samples at x * SUBPIXEL + (0 .. SUBPIXEL - 1).
    lo = np.minimum.reduceat(fixed, start[:-1], axis=0)
    hi = np.maximum.reduceat(fixed, start[:-1], axis=0)
    px0 = np.clip((lo[:, 0] - (SUBPIXEL - 1)) // SUBPIXEL, 0, width - 1)
    px1 = np.clip(hi[:, 0] // SUBPIXEL, 0, width - 1)
    py0 = np.clip((lo[:, 1] - (SUBPIXEL - 1)) // SUBPIXEL, 0, height - 1)
    py1 = np.clip(hi[:, 1] // SUBPIXEL, 0, height - 1)

    # 1/z is affine on the screen, so its maximum over a convex polygon is at a vertex.
    abc = screen.inv_z[poly_of]
    iz = abc[:, 0] * (x0i * inv_sub) + abc[:, 1] * (y0i * inv_sub) + abc[:, 2]
    nearest = np.maximum.reduceat(iz, start[:-1])
    return Edges(e=e, f=f, g=g, ia=ia, ib=ib, ic=ic, bias=bias,
                 x0=px0.astype(np.int64), x1=px1.astype(np.int64),
                 y0=py0.astype(np.int64), y1=py1.astype(np.int64), nearest_inv_z=nearest)
