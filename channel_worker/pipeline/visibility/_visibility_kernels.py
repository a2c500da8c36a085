"""numba kernels for multi-sample visibility (see visibility.py)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID, SKY_ID, SUBPIXEL
from channel_worker.pipeline.jit import borrowing, lanes
from channel_worker.pipeline.resolve._resolve_kernels import box_subarea
from channel_worker.pipeline.resolve.shading import sample_point

#: Relative margin on the early stop of a sub-area list: 1/z at a sample inside a polygon
#: can exceed the polygon's largest vertex 1/z only by rounding (~1e-16 relative).
_EARLY_STOP_MARGIN = 1e-9


class StoreOut(NamedTuple):
    """Where visibility_kernel writes: the sample store, or (fused) each pixel's colour.

    Attributes:
        fused: shade each sample and write the box-filtered pixel (rgb, and with want_range
            the pixel's nearest range) instead of the sample store.
        want_range: fill range_m (the store's polygon_range, or the fused pixel range).
        any_translucent: the frame has translucent polygons (else trans_count is pre-zeroed and
            trans never written).
        opaque: (H, W, S) int32 the store's nearest opaque feature per sample.
        trans: (H, W, S, K) int32 its translucent features, nearest first.
        trans_count: (H, W, S) uint8 how many of trans are meaningful.
        range_m: (H, W) float32.
        rgb: (H, W, 3) float32 (fused).
        dropped: (tiles,) int64 translucent features dropped from a full store, per sub-area.
        stopped: (tiles,) int64 list entries never read (the early stop), per sub-area.
    """

    fused: bool
    want_range: bool
    any_translucent: bool
    opaque: np.ndarray
    trans: np.ndarray
    trans_count: np.ndarray
    range_m: np.ndarray
    rgb: np.ndarray
    dropped: np.ndarray
    stopped: np.ndarray


class Scratch(NamedTuple):
    """One thread's sample store for a sub-area (sample i of the sub-area: ((y - ty0) * tw +
    (x - tx0)) * S + s): the nearest opaque feature's 1/z, identity and layer, the nearer
    translucent ones (nearest first) and their count, and each edge's integer step."""

    o_iz: np.ndarray
    o_id: np.ndarray
    o_lay: np.ndarray
    t_iz: np.ndarray
    t_id: np.ndarray
    t_lay: np.ndarray
    t_cnt: np.ndarray
    e_step: np.ndarray


@njit(cache=True, inline="always")
def _inside(px, py, rows, exact):
    """Exact edge test of sample (px, py) (1/SUBPIXEL units) against polygon edges
    rows = (s0, s1); exact = (ia, ib, ic, bias), the integer edge functions (contract.Edges)."""
    ia, ib, ic, bias = exact
    for j in range(rows[0], rows[1]):  # noqa: SIM110  (numba compiles the loop, not all())
        if ia[j] * px + ib[j] * py + ic[j] < bias[j]:
            return False
    return True


@njit(cache=True, inline="always")
def _nearer(iz, lay, idx, ref_iz, ref_lay, ref_idx):
    """Depth order of two features at one sample: larger 1/z is nearer; at exactly equal 1/z
    (coplanar features sharing a plane) the higher layer is seen, then the earlier polygon."""
    if iz != ref_iz:
        return iz > ref_iz
    if lay != ref_lay:
        return lay > ref_lay
    return idx < ref_idx


@njit(cache=True, parallel=True)
def visibility_kernel(bins, screen, edges, frame, background, sh, out, threads, cov):
    """Per sub-area, per sample: the nearest opaque feature and the nearer translucent ones.

    Sub-areas run in parallel, each with its own small sample store that stays in cache.
    A list is read nearest first; reading stops once every sample of the sub-area holds an
    opaque feature nearer than the nearest point of the next feature (hierarchical depth
    rejection; with the list order it skips all the rest).

    bins, screen, edges, frame, background: the contract's values (Bins, ScreenPolygons,
    Edges, FrameConstants, Background); sh: the frame's Shading (resolve.shading), used on the
    fused path; out: StoreOut; threads: numba.get_num_threads() (jit.lanes); cov: the frame's
    Coverage (resolve._coverage_kernels), read by the fused box filter.

    With a background (background.on) every sample starts out holding it as its nearest opaque
    feature (BACKGROUND_ID at background.inv_z, nothing where that is 0), so polygons behind
    the terrain are hidden and a list stops early behind a hill; what no polygon covers shows
    the background. Without one, an uncovered sample sees the earth where the horizon value
    (frame.horizon) is negative, the sky elsewhere.
    """
    s_count = frame.offsets_fixed.shape[0]
    k_max = out.trans.shape[3]
    n_max = bins.size * bins.size * s_count
    max_edges = 3
    for p in range(screen.start.shape[0] - 1):
        max_edges = max(max_edges, screen.start[p + 1] - screen.start[p])
    # A thread takes whole rows of sub-areas, every lanes-th one (sky rows are cheap, ground
    # rows dear: interleaving balances them, see jit.lanes), and walks each left to right,
    # so its pixel writes run along the image rows instead of jumping a page per row of
    # every sub-area; the sample store is allocated once per thread.
    n_lanes = lanes(threads, bins.tiles_y)
    for lane in prange(n_lanes):
        n_t = n_max if out.any_translucent else 1
        sc = Scratch(np.empty(n_max, np.float64), np.empty(n_max, np.int32),
                     np.empty(n_max, np.int32), np.empty((n_t, k_max), np.float64),
                     np.empty((n_t, k_max), np.int32), np.empty((n_t, k_max), np.int32),
                     np.zeros(n_t, np.int32), np.empty(max_edges, np.int64))
        _rows(lane, n_lanes, bins, screen, edges, frame, background, sh, out, sc, cov)


@borrowing
def _rows(lane, n_lanes, bins, screen, edges, frame, background, sh, out, sc, cov):
    """The sub-areas of visibility_kernel's lane: rows lane, lane + n_lanes, ..."""
    for row in range(lane, bins.tiles_y, n_lanes):
        for t in range(row * bins.tiles_x, (row + 1) * bins.tiles_x):
            _tile(t, bins, screen, edges, frame, background, sh, out, sc, cov)


@borrowing
def _tile(t, bins, screen, edges, frame, background, sh, out, sc, cov):
    """One sub-area of visibility_kernel, with the row's sample store sc as scratch."""
    tx0, ty0, tx1, ty1 = _subarea_rect(t, bins.tiles_x, bins.size, frame.width, frame.height)
    tw = tx1 - tx0
    s_count = frame.offsets_fixed.shape[0]
    k_max = out.trans.shape[3]
    any_translucent = out.any_translucent
    # With a background the sky and earth come painted by the background stage, per pixel.
    backdrop = 0 if background.on else _backdrop(tx0, ty0, bins.size, frame.horizon)
    n = tw * (ty1 - ty0) * s_count
    k_first = bins.start[t]
    k_end = bins.start[t + 1]
    if out.fused and k_first == k_end:
        # Nothing in the sub-area: the background alone; without one, a single colour unless
        # the horizon crosses it (and, with ranges, only if it is sky: the earth's range
        # varies). Checked before the store is even cleared.
        if background.on:
            _copy_background(tx0, ty0, tx1, ty1, background, out)
            return
        if _fill_backdrop(tx0, ty0, tx1, ty1, backdrop, frame, out):
            return
    o_iz, o_id, o_lay = sc.o_iz, sc.o_id, sc.o_lay
    t_iz, t_id, t_lay, t_cnt = sc.t_iz, sc.t_id, sc.t_lay, sc.t_cnt
    covered = _start_store(tx0, ty0, tx1, ty1, s_count, n, background, sc)
    if any_translucent:
        for i in range(n):
            t_cnt[i] = 0
    # Sub-areas with no translucent feature in their list take the opaque-only path even in
    # a frame that has translucent features elsewhere.
    trans_here = False
    if any_translucent:
        for k in range(k_first, k_end):
            if screen.opacity[bins.polygon[k]] < 1.0:
                trans_here = True
                break
    exact = (edges.ia, edges.ib, edges.ic, edges.bias)
    off_fixed = frame.offsets_fixed
    inv_sub = 1.0 / SUBPIXEL
    # The farthest stored opaque 1/z only grows as nearer features replace samples, so a stale
    # value is a safe lower bound; it is recomputed only when a stop might be missed by it.
    farthest = 0.0
    stale = False
    dropped = 0
    # An edge can cross a pixel of the sub-area only if a partially covering feature was read.
    partial = False
    for k in range(k_first, k_end):
        p = bins.polygon[k]
        if covered == n:
            bound = edges.nearest_inv_z[p] * (1.0 + _EARLY_STOP_MARGIN)
            if bound >= farthest and stale:
                farthest = o_iz[0]
                for i in range(1, n):
                    farthest = min(farthest, o_iz[i])
                stale = False
            if bound < farthest:
                out.stopped[t] = k_end - k
                break
        full = bins.full[k]
        partial |= not full
        a = screen.inv_z[p, 0]
        b = screen.inv_z[p, 1]
        c = screen.inv_z[p, 2]
        lay = screen.layer[p]
        opaque = screen.opacity[p] >= 1.0
        rows = (screen.start[p], screen.start[p + 1])
        box = (max(edges.x0[p], tx0), min(edges.x1[p], tx1 - 1),
               max(edges.y0[p], ty0), min(edges.y1[p], ty1 - 1))
        if opaque and not trans_here:
            # The common case in its own small function: fewer live values, better code.
            added = _cover_opaque(p, full, (a, b, c, lay), rows, box, (tx0, ty0, tw), exact,
                                  off_fixed, sc)
            if added >= 0:
                covered += added
                stale = True
            continue
        lx0, lx1, ly0, ly1 = box
        changed = False
        n_edges = rows[1] - rows[0]
        if not full:
            for j in range(n_edges):
                sc.e_step[j] = exact[0][rows[0] + j] * SUBPIXEL
        for s in range(s_count):
            ox = off_fixed[s, 0]
            oy = off_fixed[s, 1]
            for y in range(ly0, ly1 + 1):
                py = y * SUBPIXEL + oy
                klo = 0
                khi = lx1 - lx0
                if not full:
                    klo, khi = _row_span(exact, rows[0], n_edges, sc.e_step, lx0 * SUBPIXEL + ox,
                                         py, khi)
                for x in range(lx0 + klo, lx0 + khi + 1):
                    px = x * SUBPIXEL + ox
                    i = ((y - ty0) * tw + (x - tx0)) * s_count + s
                    iz = a * (px * inv_sub) + (b * (py * inv_sub) + c)
                    if o_id[i] != -1 and not _nearer(iz, lay, p, o_iz[i], o_lay[i], o_id[i]):
                        continue
                    if opaque:
                        if o_id[i] == -1:
                            covered += 1
                        o_iz[i] = iz
                        o_id[i] = p
                        o_lay[i] = lay
                        changed = True
                        if not any_translucent:
                            continue
                        # Translucent features now behind the opaque one are hidden.
                        m = t_cnt[i]
                        while m > 0 and not _nearer(t_iz[i, m - 1], t_lay[i, m - 1],
                                                    t_id[i, m - 1], iz, lay, p):
                            m -= 1
                        t_cnt[i] = m
                    else:
                        m = t_cnt[i]
                        pos = m
                        while pos > 0 and _nearer(iz, lay, p, t_iz[i, pos - 1],
                                                  t_lay[i, pos - 1], t_id[i, pos - 1]):
                            pos -= 1
                        if m == k_max:
                            # Store full: the farthest of the K + 1 is dropped (it is
                            # the one seen through all the others).
                            dropped += 1
                            if pos == k_max:
                                continue
                            m -= 1
                        for q in range(m, pos, -1):
                            t_iz[i, q] = t_iz[i, q - 1]
                            t_id[i, q] = t_id[i, q - 1]
                            t_lay[i, q] = t_lay[i, q - 1]
                        t_iz[i, pos] = iz
                        t_id[i, pos] = p
                        t_lay[i, pos] = lay
                        t_cnt[i] = m + 1
        if opaque and changed:
            stale = True
    out.dropped[t] = dropped
    if out.fused:
        box_subarea((tx0, ty0, tx1, ty1), backdrop, frame, background, sh, any_translucent,
                    out.want_range, sc, out.rgb, out.range_m, cov, cov.on and partial)
    else:
        _write_store(tx0, ty0, tx1, ty1, backdrop, frame, background, out, sc)


@njit(cache=True, inline="always")
def _start_store(tx0, ty0, tx1, ty1, s_count, n, background, sc):
    """Clear the sub-area's store; with a background, every sample it covers starts out
    holding it. Returns how many samples hold an opaque feature. Only the identities need
    clearing: 1/z and layer are read only where an identity is set."""
    covered = 0
    if background.on:
        # The terrain is the first opaque feature of every sample it covers; its layer is
        # below every polygon's, so a polygon at exactly its depth is seen.
        tw = tx1 - tx0
        for y in range(ty0, ty1):
            for x in range(tx0, tx1):
                base = ((y - ty0) * tw + (x - tx0)) * s_count
                for s in range(s_count):
                    iz = background.inv_z[y, x, s]
                    if iz > 0.0:
                        sc.o_id[base + s] = BACKGROUND_ID
                        sc.o_iz[base + s] = iz
                        sc.o_lay[base + s] = -1
                        covered += 1
                    else:
                        sc.o_id[base + s] = -1
    else:
        for i in range(n):
            sc.o_id[i] = -1
    return covered


@borrowing
def _write_store(tx0, ty0, tx1, ty1, backdrop, frame, background, out, sc):
    """Copy the sub-area's store into the frame's sample store (out.opaque, .trans, .trans_count),
    naming what an uncovered sample sees, and each pixel's nearest polygon range."""
    tw = tx1 - tx0
    s_count = frame.offsets_fixed.shape[0]
    kx, ky, k0 = frame.horizon[0], frame.horizon[1], frame.horizon[2]
    m = frame.mapping
    for y in range(ty0, ty1):
        for x in range(tx0, tx1):
            base = ((y - ty0) * tw + (x - tx0)) * s_count
            near_range = np.inf
            for s in range(s_count):
                i = base + s
                f = sc.o_id[i]
                if f < 0 and background.on:
                    f = BACKGROUND_ID  # resolve reads its colour and range from the Background
                elif f < 0:
                    if backdrop != 0:
                        f = backdrop
                    else:
                        sx, sy = sample_point(frame, x, y, s)
                        f = EARTH_ID if kx * sx + ky * sy + k0 < 0.0 else SKY_ID
                elif out.want_range:
                    sx, sy = sample_point(frame, x, y, s)
                    # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
                    rx = (sx - m[1]) / m[0]
                    ry = (sy - m[3]) / m[2]
                    near_range = min(near_range, math.sqrt(rx * rx + ry * ry + 1.0) / sc.o_iz[i])
                out.opaque[y, x, s] = f
                if out.any_translucent:
                    cnt = sc.t_cnt[i]
                    out.trans_count[y, x, s] = cnt
                    for q in range(cnt):
                        out.trans[y, x, s, q] = sc.t_id[i, q]
            if out.want_range:
                out.range_m[y, x] = near_range


@njit(cache=True, inline="always")
def _row_span(exact, s0, n_edges, e_step, px0, py, span):
    """(first, last) k in 0..span with the sample at px0 + k * SUBPIXEL, py inside every edge
    (first > last if none): the covered run of one row of samples, solved exactly per edge.

    exact: (ia, ib, ic, bias), the integer edge functions; edges s0 .. s0 + n_edges - 1.
    Edge j's value at the k-th sample, less its top-left bias, is e0 + step * k in integers
    (step = ia * SUBPIXEL, e_step), inside iff >= 0, so each edge bounds k from one side.
    """
    ia, ib, ic, bias = exact
    klo = 0
    khi = span
    for j in range(n_edges):
        e0 = ia[s0 + j] * px0 + ib[s0 + j] * py + ic[s0 + j] - bias[s0 + j]
        step = e_step[j]
        if step > 0:
            if e0 < 0:
                klo = max(klo, (step - 1 - e0) // step)  # ceil(-e0 / step), both positive
        elif step < 0:
            if e0 < 0:
                return 1, 0
            khi = min(khi, e0 // -step)  # floor(e0 / -step); guard: step != 0 here
        elif e0 < 0:
            return 1, 0
    return klo, khi


@borrowing
def _cover_opaque(p, full, plane, rows, box, origin, exact, off_fixed, sc):
    """Depth-test one opaque polygon into the store of a sub-area with no translucency.

    plane: (a, b, c, layer), 1/z = a sx + b sy + c; rows: (s0, s1), its edges; box: (lx0,
    lx1, ly0, ly1) the pixels of the sub-area its bounds reach; origin: (tx0, ty0, tw) of the
    sub-area. Returns the number of samples newly covered, or -1 if no sample changed.
    """
    a, b, c, lay = plane
    s0 = rows[0]
    n_edges = rows[1] - s0
    lx0, lx1, ly0, ly1 = box
    tx0, ty0, tw = origin
    s_count = off_fixed.shape[0]
    inv_sub = 1.0 / SUBPIXEL
    o_iz, o_id, o_lay, e_step = sc.o_iz, sc.o_id, sc.o_lay, sc.e_step
    if not full:
        for j in range(n_edges):
            e_step[j] = exact[0][s0 + j] * SUBPIXEL
    added = 0
    changed = False
    span = lx1 - lx0
    for s in range(s_count):
        ox = off_fixed[s, 0]
        oy = off_fixed[s, 1]
        for y in range(ly0, ly1 + 1):
            py = y * SUBPIXEL + oy
            klo = 0
            khi = span
            if not full:
                klo, khi = _row_span(exact, s0, n_edges, e_step, lx0 * SUBPIXEL + ox, py, span)
                if klo > khi:
                    continue
            row = ((y - ty0) * tw - tx0) * s_count + s
            fy = b * (py * inv_sub) + c
            for x in range(lx0 + klo, lx0 + khi + 1):
                px = x * SUBPIXEL + ox
                i = row + x * s_count
                # Same expression, same order as in _tile: a * sx + (b * sy + c) is evaluated
                # identically for every feature, so coplanar ties stay exact.
                iz = a * (px * inv_sub) + fy
                f = o_id[i]
                if f != -1 and not _nearer(iz, lay, p, o_iz[i], o_lay[i], f):
                    continue
                if f == -1:
                    added += 1
                o_iz[i] = iz
                o_id[i] = p
                o_lay[i] = lay
                changed = True
    return added if changed else -1


@njit(cache=True, inline="always")
def _subarea_rect(t, tiles_x, size, width, height):
    """(x0, y0, x1, y1) pixels of sub-area t (row-major), clipped to the raster; x1, y1 exclusive."""
    ty = t // tiles_x
    x0 = (t - ty * tiles_x) * size
    y0 = ty * size
    return x0, y0, min(x0 + size, width), min(y0 + size, height)


@njit(cache=True, inline="always")
def _backdrop(tx0, ty0, size, horizon):
    """EARTH_ID or SKY_ID if every point of the sub-area sees that behind the features, 0 if the
    horizon crosses it: the horizon value is affine, so its sign over the sub-area is that of
    its corners when they all agree."""
    kx, ky, k0 = horizon[0], horizon[1], horizon[2]
    h00 = kx * tx0 + ky * ty0 + k0
    h10 = kx * (tx0 + size) + ky * ty0 + k0
    h01 = kx * tx0 + ky * (ty0 + size) + k0
    h11 = kx * (tx0 + size) + ky * (ty0 + size) + k0
    if h00 < 0.0 and h10 < 0.0 and h01 < 0.0 and h11 < 0.0:
        return EARTH_ID
    if h00 >= 0.0 and h10 >= 0.0 and h01 >= 0.0 and h11 >= 0.0:
        return SKY_ID
    return 0


@borrowing
def _fill_backdrop(tx0, ty0, tx1, ty1, backdrop, frame, out):
    """Fill the sub-area with its backdrop if it has a single one (with ranges: only the
    sky, at +inf; the earth's range varies); False if it was not filled."""
    if backdrop == EARTH_ID and not out.want_range:
        cr, cg, cb = frame.earth[0], frame.earth[1], frame.earth[2]
    elif backdrop == SKY_ID:
        cr, cg, cb = frame.sky[0], frame.sky[1], frame.sky[2]
    else:
        return False
    for y in range(ty0, ty1):
        for x in range(tx0, tx1):
            out.rgb[y, x, 0] = cr
            out.rgb[y, x, 1] = cg
            out.rgb[y, x, 2] = cb
            if out.want_range:
                out.range_m[y, x] = np.inf
    return True


@borrowing
def _copy_background(tx0, ty0, tx1, ty1, background, out):
    """The sub-area as the background stage painted it (no polygon in it)."""
    for y in range(ty0, ty1):
        for x in range(tx0, tx1):
            out.rgb[y, x, 0] = background.rgb[y, x, 0]
            out.rgb[y, x, 1] = background.rgb[y, x, 1]
            out.rgb[y, x, 2] = background.rgb[y, x, 2]
            if out.want_range:
                out.range_m[y, x] = background.range_m[y, x]


@njit(cache=True, parallel=True)
def coverage_kernel(bins, screen, edges, off_fixed, out_count):
    """How many polygons cover each sample: the same lists as visibility_kernel, but each
    sample decided by the direct edge test (_inside), independently of its row solver."""
    n_tiles = bins.start.shape[0] - 1
    s_count = off_fixed.shape[0]
    height, width = out_count.shape[0], out_count.shape[1]
    exact = (edges.ia, edges.ib, edges.ic, edges.bias)
    for t in prange(n_tiles):
        tx0, ty0, tx1, ty1 = _subarea_rect(t, bins.tiles_x, bins.size, width, height)
        for k in range(bins.start[t], bins.start[t + 1]):
            p = bins.polygon[k]
            full = bins.full[k]
            rows = (screen.start[p], screen.start[p + 1])
            for y in range(max(edges.y0[p], ty0), min(edges.y1[p], ty1 - 1) + 1):
                for x in range(max(edges.x0[p], tx0), min(edges.x1[p], tx1 - 1) + 1):
                    for s in range(s_count):
                        px = x * SUBPIXEL + off_fixed[s, 0]
                        py = y * SUBPIXEL + off_fixed[s, 1]
                        if full or _inside(px, py, rows, exact):
                            out_count[y, x, s] += 1
