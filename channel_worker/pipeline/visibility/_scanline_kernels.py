"""numba kernels for the scan-line hidden-surface renderer (see scanline.py, docs/scanline.md).

Two kernels: edge_list_kernel builds the Note's EDGE LIST from the snapped polygons, and
scan_frame_kernel runs the Line Phase and the Element Phase over bands of scan lines.

Intercepts are exact. A sample at pixel x of scan line y sits at (x S + S/2, y S + S/2) in
1/S pixel units (S = SUBPIXEL), and the half-plane of an edge from (X0, Y0) by (dx, dy) keeps it
when E = (Px - X0) dy - (Py - Y0) dx >= bias (bias 0 on top/left edges, else 1). On one scan
line that is a bound on x alone, x >= ceil(N / D) (ENTER edge, dy > 0) or x <= floor(N / D)
(EXIT edge, dy < 0), with integers N, D that this module keeps as an exact quotient and
remainder: the Note's recursion i(j + 1) = i(j) + delta_i, with the fraction carried exactly
instead of in 9 bits, so no rounding ever moves a span end.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import EARTH_ID, SKY_ID, SUBPIXEL
from channel_worker.pipeline.jit import borrowing, claim, lanes, new_queue

#: Edge kinds (the Note's EN/EX bit, plus horizontal edges, which bound no span along the scan:
#: on a scan line they either keep the whole line or none of it).
ENTER = 0
EXIT = 1
GATE = 2

#: Columns of band_stats, summed (or, for the *_MAX ones, maxed) over bands by the caller.
STAT_CROSSINGS = 0  # edge/scan-line intersections processed (ACTIVE LIST entries per line)
STAT_ACTIVE_MAX = 1  # longest ACTIVE LIST
STAT_MULTIPLE = 2  # MULTIPLE EDGE routine calls (two or more edges at one intercept)
STAT_ON_MAX = 3  # most faces "on" at once
STAT_FIELD = 4  # FIELD entries: changes of the visible face along a scan line
STAT_OVERFLOW = 5  # samples with more than K nearer translucent faces
STAT_DROPPED = 6  # translucent faces dropped from full stores (sum over samples)
N_STATS = 7


class EdgeList(NamedTuple):
    """The EDGE LIST (edge_list_kernel): per edge its kind (ENTER, EXIT, GATE), its face, its
    first and last scan line, and its exact intercept: numerator num0 + y step over den at
    scan line y, the step split as step_q den + step_r (0 <= step_r < den)."""

    kind: np.ndarray
    poly: np.ndarray
    jmin: np.ndarray
    jmax: np.ndarray
    num0: np.ndarray
    den: np.ndarray
    step: np.ndarray
    step_q: np.ndarray
    step_r: np.ndarray


class PriorityList(NamedTuple):
    """Per face: its index in the PRIORITY LIST (rank, 0 = seen in front of everything), whether
    it is opaque, and its 1/z plane on the screen (for ranges)."""

    rank: np.ndarray
    is_opaque: np.ndarray
    inv_z: np.ndarray


class ScanOut(NamedTuple):
    """The sample store the scan writes, one sample per pixel: (H, W, 1) nearest opaque face,
    (H, W, 1, K) translucent faces ahead of it, (H, W, 1) their count, (H, W) range."""

    opaque: np.ndarray
    trans: np.ndarray
    trans_count: np.ndarray
    range_m: np.ndarray


class LineLists(NamedTuple):
    """One band's working lists: the ACTIVE LIST (edge, intercept quotient and remainder, the
    column where it acts) and the ON/OFF LIST as counts per face (active ENTER edges, those
    passed, EXIT/GATE edges passed) with the faces on, in priority order."""

    act_e: np.ndarray
    act_q: np.ndarray
    act_r: np.ndarray
    act_t: np.ndarray
    n_enter: np.ndarray
    passed_in: np.ndarray
    passed_out: np.ndarray
    on: np.ndarray


@njit(cache=True)
def edge_list_kernel(fixed, start, height, out, out_extended):
    """The EDGE LIST: per edge its kind, face, first and last scan line, and exact intercept.

    An edge of a convex polygon is active on the scan lines whose sample row lies within its
    own y extent, ends included (the Note's jmin..jmax). Snapping to the 1/S grid can leave a
    polygon slightly non-convex (three nearly collinear vertices); the edge test then keeps the
    intersection of all the edges' half-planes, which some edge not crossing the scan line may
    cut. Such a polygon's edges are made active over the polygon's whole y extent instead
    (out_extended[p] = 1), so on every scan line every one of its half-planes is applied.

    Per edge, the intercept numerator at scan line y is num0 + y * step, over den > 0:
    ENTER: first covered column ceil(num / den); EXIT: last covered column floor(num / den);
    GATE (dy == 0): the scan line is kept iff num <= 0 (den 1).
    out: (kind, poly, jmin, jmax, num0, den, step) arrays, one row per edge written.
    Returns the number of edges written (edges that meet no sample row are left out).
    """
    out_kind, out_poly, out_jmin, out_jmax, out_num0, out_den, out_step = out
    subpixel = SUBPIXEL
    n_poly = start.shape[0] - 1
    half = subpixel // 2
    n_out = 0
    for p in range(n_poly):
        s0 = start[p]
        n = start[p + 1] - s0
        y_lo = fixed[s0, 1]
        y_hi = y_lo
        # Convex, simple and wound with negative doubled area: every turn has cross <= 0
        # (a straight continuation, cross == 0, must not reverse), and the edge direction
        # turns down and up only once (dy changes sign twice around the polygon).
        convex = True
        sign_changes = 0
        last_sign = 0
        first_sign = 0
        for i in range(n):
            a = s0 + i
            b = s0 + (i + 1) % n
            c = s0 + (i + 2) % n
            dx0 = fixed[b, 0] - fixed[a, 0]
            dy0 = fixed[b, 1] - fixed[a, 1]
            dx1 = fixed[c, 0] - fixed[b, 0]
            dy1 = fixed[c, 1] - fixed[b, 1]
            cross = dx0 * dy1 - dy0 * dx1
            if cross > 0 or (cross == 0 and dx0 * dx1 + dy0 * dy1 <= 0):
                convex = False
            s = 1 if dy0 > 0 else (-1 if dy0 < 0 else 0)
            if s != 0:
                if first_sign == 0:
                    first_sign = s
                elif s != last_sign:
                    sign_changes += 1
                last_sign = s
            y_lo = min(y_lo, fixed[a, 1])
            y_hi = max(y_hi, fixed[a, 1])
        if last_sign != first_sign:
            sign_changes += 1
        if sign_changes != 2:
            convex = False
        out_extended[p] = 0 if convex else 1
        for i in range(n):
            a = s0 + i
            b = s0 + (i + 1) % n
            x0 = fixed[a, 0]
            y0 = fixed[a, 1]
            dx = fixed[b, 0] - x0
            dy = fixed[b, 1] - y0
            if convex:
                e_lo = min(y0, y0 + dy)
                e_hi = max(y0, y0 + dy)
            else:
                e_lo = y_lo
                e_hi = y_hi
            # Scan line y samples row y S + S/2: the first at or below e_lo, the last at or
            # above e_hi (floor division; S > 0).
            jmin = max(-((half - e_lo) // subpixel), 0)
            jmax = min((e_hi - half) // subpixel, height - 1)
            if jmin > jmax:
                continue
            bias = 0 if (dy > 0 or (dy == 0 and dx < 0)) else 1
            # int64 is ample: projection clamps coordinates to the raster, so for rasters
            # below 2^20 pixels every product of two coordinates stays below 2^56.
            # The half-plane keeps (Px, Py) iff Px dy >= G with G = X0 dy + (Py - Y0) dx + bias.
            g0 = x0 * dy + (half - y0) * dx + bias
            if dy > 0:
                # Px = x S + S/2 >= G / dy  <=>  x >= (G - (S/2) dy) / (S dy)
                out_kind[n_out] = ENTER
                out_num0[n_out] = g0 - half * dy
                out_den[n_out] = subpixel * dy
                out_step[n_out] = subpixel * dx
            elif dy < 0:
                # Px <= -G / |dy|  <=>  x <= (-G - (S/2) |dy|) / (S |dy|)
                out_kind[n_out] = EXIT
                out_num0[n_out] = -g0 + half * dy
                out_den[n_out] = -subpixel * dy
                out_step[n_out] = -subpixel * dx
            else:
                # 0 >= G: the row is inside this edge or wholly outside it.
                out_kind[n_out] = GATE
                out_num0[n_out] = g0
                out_den[n_out] = 1
                out_step[n_out] = subpixel * dx
            out_poly[n_out] = p
            out_jmin[n_out] = jmin
            out_jmax[n_out] = jmax
            n_out += 1
    return n_out


@njit(cache=True, parallel=True)
def scan_frame_kernel(edges, incidence, faces, frame, n_bands, out, band_stats, threads):
    """Run the scan-line algorithm over the frame, bands of scan lines in parallel.

    Each band runs the phases of ARL Systems Note 77 on its own lines from its own ACTIVE LIST;
    every result and counter is a function of one scan line alone (the arithmetic is exact),
    so the output does not depend on the number of bands or threads.

    edges: the EdgeList; incidence: edge indices by ascending jmin (the INCIDENCE LIST);
    faces: the PriorityList; frame: FrameConstants (horizon, mapping); out: ScanOut (opaque,
    trans, count zeroed); band_stats: (n_bands, N_STATS) int64 zeroed; threads:
    numba.get_num_threads() (jit.lanes).
    """
    height = out.range_m.shape[0]
    # Guard: the caller passes 1 <= n_bands <= height.
    rows = (height + n_bands - 1) // n_bands
    # Bands from a queue shared by the threads (jit.lanes): sky bands are cheap, busy ones
    # dear, and whichever thread is free takes the next.
    n_lanes = lanes(threads, n_bands)
    queue = new_queue()
    for _lane in prange(n_lanes):
        while True:
            band = claim(queue)
            if band >= n_bands:
                break
            y_lo = band * rows
            y_hi = min(height, y_lo + rows)
            if y_lo < y_hi:
                _scan_band(y_lo, y_hi, edges, incidence, faces, frame, out, band_stats[band])


@njit(cache=True)
def _scan_band(y_lo, y_hi, edges, incidence, faces, frame, out, stats):
    """Frame Phase set-up for one band, then Line Phase + Element Phase per scan line."""
    kind, poly, jmin, jmax = edges.kind, edges.poly, edges.jmin, edges.jmax
    num0, den, step, step_q, step_r = edges.num0, edges.den, edges.step, edges.step_q, edges.step_r
    n_edges = kind.shape[0]
    n_poly = faces.rank.shape[0]
    width = out.range_m.shape[1]
    # ACTIVE LIST capacity: the edges that meet the band.
    cap = 0
    for e in range(n_edges):
        if jmin[e] < y_hi and jmax[e] >= y_lo:
            cap += 1
    act_e = np.empty(cap, np.int64)  # EDGE LIST index
    act_q = np.empty(cap, np.int64)  # floor(num / den) at the current scan line ...
    act_r = np.empty(cap, np.int64)  # ... and the remainder, 0 <= r < den
    act_t = np.empty(cap, np.int64)  # the pixel column where the edge acts, in [0, width]
    # ON/OFF LIST, generalised to counts so that a face with several half-planes active on a
    # line (a vertex on the line, an extended non-convex face) is on only inside all of them:
    # on iff every active ENTER edge has been passed and no EXIT/GATE edge has.
    n_enter = np.zeros(n_poly, np.int64)
    passed_in = np.zeros(n_poly, np.int64)
    passed_out = np.zeros(n_poly, np.int64)
    on = np.empty(cap + 1, np.int64)  # faces on, in PRIORITY LIST order
    lists = LineLists(act_e, act_q, act_r, act_t, n_enter, passed_in, passed_out, on)
    n_act = 0
    ptr = 0  # INCIDENCE LIST pointer
    for y in range(y_lo, y_hi):
        # Line Phase, deletion: drop edges whose last scan line is behind; step the others.
        m = 0
        for i in range(n_act):
            e = act_e[i]
            if jmax[e] < y:
                if kind[e] == ENTER:
                    n_enter[poly[e]] -= 1
                continue
            # The exact recursion: step = step_q den + step_r with 0 <= step_r < den, so the
            # remainder stays in [0, den) with at most one carry.
            q = act_q[i] + step_q[e]
            r = act_r[i] + step_r[e]
            if r >= den[e]:
                r -= den[e]
                q += 1
            act_e[m] = e
            act_q[m] = q
            act_r[m] = r
            act_t[m] = _column(kind[e], q, r, width)
            m += 1
        n_act = m
        # Line Phase, append: edges whose first scan line is this one (at the band's first
        # line also those begun above it), their intercept computed directly.
        while ptr < n_edges and jmin[incidence[ptr]] <= y:
            e = incidence[ptr]
            ptr += 1
            if jmax[e] < y:
                continue
            num = num0[e] + y * step[e]
            # Guard: den >= 1 for every edge (S |dy| with dy != 0, or 1 for a GATE edge).
            q = num // den[e]
            act_e[n_act] = e
            act_q[n_act] = q
            act_r[n_act] = num - q * den[e]
            act_t[n_act] = _column(kind[e], q, num - q * den[e], width)
            if kind[e] == ENTER:
                n_enter[poly[e]] += 1
            n_act += 1
        # Line Phase, sort by intercept: insertion sort, cheap on a list nearly in order from
        # the line before (the Note's bubble sort, same reason).
        for i in range(1, n_act):
            t = act_t[i]
            if act_t[i - 1] <= t:
                continue
            e = act_e[i]
            q = act_q[i]
            r = act_r[i]
            k = i
            while k > 0 and act_t[k - 1] > t:
                act_e[k] = act_e[k - 1]
                act_q[k] = act_q[k - 1]
                act_r[k] = act_r[k - 1]
                act_t[k] = act_t[k - 1]
                k -= 1
            act_e[k] = e
            act_q[k] = q
            act_r[k] = r
            act_t[k] = t
        stats[STAT_CROSSINGS] += n_act
        stats[STAT_ACTIVE_MAX] = max(stats[STAT_ACTIVE_MAX], n_act)
        _element_phase(y, n_act, lists, edges, faces, frame, out, stats)


@njit(cache=True, inline="always")
def _column(kind, q, r, width):
    """Pixel column at which an edge acts on the scan line, clamped to [0, width].

    ENTER: the first column inside it, ceil(num / den). EXIT: one past the last column inside
    it, floor(num / den) + 1. GATE: 0 if the line is outside it (acts before every pixel),
    width if inside (never acts).
    """
    if kind == ENTER:
        t = q + (1 if r > 0 else 0)
    elif kind == EXIT:
        t = q + 1
    else:
        t = width if q <= 0 else 0
    return min(max(t, 0), width)


@borrowing
def _element_phase(y, n_act, lists, edges, faces, frame, out, stats):
    """Visible faces along one scan line: background, then the spans between intercepts."""
    act_e, act_t, on = lists.act_e, lists.act_t, lists.on
    n_enter, passed_in, passed_out = lists.n_enter, lists.passed_in, lists.passed_out
    kind, poly, rank, is_opaque = edges.kind, edges.poly, faces.rank, faces.is_opaque
    horizon = frame.horizon
    out_opaque, out_range = out.opaque, out.range_m
    subpixel = SUBPIXEL
    width = out_range.shape[1]
    half = subpixel // 2
    inv_sub = 1.0 / subpixel
    sy = (y * subpixel + half) * inv_sub
    # Horizon synthesis: the sky is the whole screen at the lowest priority, the earth polygon
    # (bounded by the horizon line) over it, every face over both. The horizon value is affine
    # in sx and its float evaluation monotone, so the earth is a prefix or a suffix of the line.
    x_h = _horizon_column(horizon, sy, width, subpixel)
    left = EARTH_ID if _earth(horizon, 0, sy, subpixel) else SKY_ID
    right = SKY_ID if left == EARTH_ID else EARTH_ID
    for x in range(width):
        out_opaque[y, x, 0] = left if x < x_h else right
        out_range[y, x] = np.inf
    n_on = 0
    br = -1  # BR: the face visible just left of the current intercept (-1: background)
    x_cur = 0
    i = 0
    while i < n_act:
        t = act_t[i]
        if t >= width:
            break
        j = i + 1
        while j < n_act and act_t[j] == t:
            j += 1
        if t > x_cur:
            _span(y, x_cur, t, n_on, on, faces, frame, sy, out, stats)
            x_cur = t
        if j - i > 1:
            # MULTIPLE EDGE routine: every ENTER at this intercept first, then every EXIT, so
            # the order of coincident edges in the list cannot turn a face off and on again.
            stats[STAT_MULTIPLE] += 1
        for m in range(i, j):
            e = act_e[m]
            if kind[e] == ENTER:
                p = poly[e]
                passed_in[p] += 1
                if passed_in[p] == n_enter[p] and passed_out[p] == 0:
                    n_on = _turn_on(p, n_on, on, rank)
        for m in range(i, j):
            e = act_e[m]
            if kind[e] != ENTER:
                p = poly[e]
                if passed_out[p] == 0 and passed_in[p] == n_enter[p]:
                    n_on = _turn_off(p, n_on, on)
                passed_out[p] += 1
        stats[STAT_ON_MAX] = max(stats[STAT_ON_MAX], n_on)
        visible = -1
        for m in range(n_on):
            if is_opaque[on[m]]:
                visible = on[m]
                break
        if visible != br:
            stats[STAT_FIELD] += 1
            br = visible
        i = j
    if x_cur < width:
        _span(y, x_cur, width, n_on, on, faces, frame, sy, out, stats)
    for m in range(n_act):
        p = poly[act_e[m]]
        passed_in[p] = 0
        passed_out[p] = 0


@njit(cache=True, inline="always")
def _turn_on(p, n_on, on, rank):
    """Insert face p into the on faces, kept in PRIORITY LIST order."""
    k = n_on
    while k > 0 and rank[on[k - 1]] > rank[p]:
        on[k] = on[k - 1]
        k -= 1
    on[k] = p
    return n_on + 1


@njit(cache=True, inline="always")
def _turn_off(p, n_on, on):
    """Remove face p from the on faces (if it is there)."""
    for k in range(n_on):
        if on[k] == p:
            for m in range(k, n_on - 1):
                on[m] = on[m + 1]
            return n_on - 1
    return n_on


@borrowing
def _span(y, x0, x1, n_on, on, faces, frame, sy, out, stats):
    """Write pixels x0..x1-1 of scan line y (screen y sy): the highest-priority opaque face on,
    and the translucent faces on ahead of it in the priority list (nearest first, at most K)."""
    is_opaque, inv_z, mapping = faces.is_opaque, faces.inv_z, frame.mapping
    out_opaque, out_trans, out_count, out_range = out.opaque, out.trans, out.trans_count, out.range_m
    subpixel = SUBPIXEL
    visible = -1
    n_front = 0
    for m in range(n_on):
        if is_opaque[on[m]]:
            visible = on[m]
            break
        n_front += 1
    if visible >= 0:
        sx_scale, sx_off, sy_scale, sy_off = mapping[0], mapping[1], mapping[2], mapping[3]
        a, b, c = inv_z[visible, 0], inv_z[visible, 1], inv_z[visible, 2]
        inv_sub = 1.0 / subpixel
        half = subpixel // 2
        # Guard: screen_mapping's scales are non-zero (left < right, bottom < top).
        ry = (sy - sy_off) / sy_scale
        for x in range(x0, x1):
            sx = (x * subpixel + half) * inv_sub
            out_opaque[y, x, 0] = visible
            iz = a * sx + b * sy + c
            rx = (sx - sx_off) / sx_scale
            # Guard: a face is clipped to near <= z <= far, so 1/z > 0 at any point inside
            # it; the clamp only keeps a hand-made plane from dividing by zero.
            out_range[y, x] = math.sqrt(rx * rx + ry * ry + 1.0) / max(iz, 1e-300)
    if n_front > 0:
        k_max = out_trans.shape[3]
        kept = min(n_front, k_max)
        for x in range(x0, x1):
            out_count[y, x, 0] = kept
            for m in range(kept):
                out_trans[y, x, 0, m] = on[m]
        if n_front > k_max:
            stats[STAT_OVERFLOW] += x1 - x0
            stats[STAT_DROPPED] += (n_front - k_max) * (x1 - x0)


@njit(cache=True, inline="always")
def _earth(horizon, x, sy, subpixel):
    """Does the pixel centre of column x (on the row at sy) see the earth?

    The same expression, in the same order, as the sub-area renderer evaluates per sample.
    """
    sx = (x * subpixel + subpixel // 2) * (1.0 / subpixel)
    return horizon[0] * sx + horizon[1] * sy + horizon[2] < 0.0


@njit(cache=True)
def _horizon_column(horizon, sy, width, subpixel):
    """First column whose earth/sky answer differs from column 0's (width if none).

    The answer changes at most once along a line (the float horizon value is monotone in sx:
    rounding a product by a constant, or a sum with a constant, keeps the order), so a binary
    search finds where; every pixel's answer equals the per-pixel test.
    """
    first = _earth(horizon, 0, sy, subpixel)
    lo = 0
    hi = width
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _earth(horizon, mid, sy, subpixel) != first:
            hi = mid
        else:
            lo = mid
    return hi
