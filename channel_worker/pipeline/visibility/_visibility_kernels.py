"""numba kernels for multi-sample visibility (see visibility.py)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID, SKY_ID, SUBPIXEL
from channel_worker.pipeline.jit import bit_count, borrowing, claim, lanes, low_bits, lowest_bit, new_queue
from channel_worker.pipeline.shade._box_kernels import box_subarea
from channel_worker.pipeline.shade.group import ShadeFrame
from channel_worker.pipeline.shade.scratch import Scratch
from channel_worker.pipeline.shade.shading import sample_point

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
        hidden: (tiles,) int64 list entries read but wholly behind covered samples (_hidden).
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
    hidden: np.ndarray


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
def visibility_kernel(bins, screen, edges, frame, background, sh, cov, out, threads, lay):
    """Per sub-area: the nearest opaque feature and the nearer translucent ones per sample.

    Sub-areas run in parallel, each with its own small sample store that stays in cache.
    A feature's coverage of the sub-area is built as bit masks (MaskLayout), a row of
    samples at a time from its edges (_coverage), and merged 64 samples at a time: samples
    that hold nothing take it without a depth test; samples that hold an opaque feature are
    compared only where the order is ambiguous, that is where the feature's nearest point
    is not behind the row's farthest stored 1/z. A feature whose box lies under covered
    samples that are all nearer costs only that test (_hidden). A list is read nearest
    first; reading stops once every sample holds an opaque feature nearer than the nearest
    point of the next feature (with the list order it skips all the rest).

    bins, screen, edges: the contract's values (Bins, ScreenPolygons, Edges); frame,
    background, sh, cov: the parts of the frame's ShadeFrame (shade.group; a parallel kernel
    takes them apart because numba 0.68's parfor lowering cannot rebuild a group of groups
    inside the loop); out: StoreOut; threads: numba.get_num_threads() (jit.lanes); lay: the
    MaskLayout (shade.scratch).

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
    # A thread takes runs of _TASK_TILES sub-areas along a row from a queue shared by the
    # threads (sky sub-areas are cheap, the airfield's dear: whichever thread is free takes
    # the next run, see jit.lanes), and walks each left to right, so its pixel writes run
    # along the image rows; the sample store is allocated once per thread.
    n_tasks = (bins.tiles_x + _TASK_TILES - 1) // _TASK_TILES * bins.tiles_y
    n_lanes = lanes(threads, n_tasks)
    n_words = bins.size * lay.wpr
    queue = new_queue()
    for _lane in prange(n_lanes):
        n_t = n_max if out.any_translucent else 1
        sc = Scratch(np.empty(n_max, np.float64), np.empty(n_max, np.int32),
                     np.empty((n_t, k_max), np.float64), np.empty((n_t, k_max), np.int32),
                     np.empty((n_t, k_max), np.int32), np.zeros(n_t, np.int32),
                     np.empty(max_edges, np.int64), np.empty(max_edges, np.float64),
                     np.empty(max_edges, np.int64), np.zeros(n_words, np.uint64),
                     np.zeros(n_words, np.uint64), np.empty(bins.size, np.float64),
                     np.zeros(bins.size, np.uint64))
        _runs(queue, n_tasks, bins, screen, edges, frame, background, sh, cov, out, sc, lay)


#: Sub-areas per task of visibility_kernel's queue: a run along a row (64 pixels at the
#: default size), long enough that the queue's atomic add is nothing against it, short
#: enough that a 1024 x 768 frame has 768 tasks for 16 threads to share.
_TASK_TILES = 4


@borrowing
def _runs(queue, n_tasks, bins, screen, edges, frame, background, sh, cov, out, sc, lay):
    """The runs of sub-areas one lane of visibility_kernel claims from queue until none is
    left (frame, background, sh, cov: the ShadeFrame's parts)."""
    sf = ShadeFrame(frame, background, sh, cov)
    runs_per_row = (bins.tiles_x + _TASK_TILES - 1) // _TASK_TILES
    while True:
        task = claim(queue)
        if task >= n_tasks:
            return
        row = task // runs_per_row
        first = row * bins.tiles_x + (task % runs_per_row) * _TASK_TILES
        for t in range(first, min(first + _TASK_TILES, (row + 1) * bins.tiles_x)):
            _tile(t, bins, screen, edges, sf, out, sc, lay)


@borrowing
def _tile(t, bins, screen, edges, sf, out, sc, lay):
    """One sub-area of visibility_kernel, with the lane's sample store sc as scratch."""
    frame, background = sf.frame, sf.background
    tx0, ty0, tx1, ty1 = _subarea_rect(t, bins.tiles_x, bins.size, frame.width, frame.height)
    tw = tx1 - tx0
    s_count = frame.offsets_fixed.shape[0]
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
    covered = _start_store(tx0, ty0, tx1, ty1, s_count, n, background, sc, lay)
    if any_translucent:
        for i in range(n):
            sc.t_cnt[i] = 0
    # Sub-areas with no translucent feature in their list take the opaque-only merge even in
    # a frame that has translucent features elsewhere.
    trans_here = False
    if any_translucent:
        for k in range(k_first, k_end):
            if screen.opacity[bins.polygon[k]] < 1.0:
                trans_here = True
                break
    # The farthest stored opaque 1/z only grows as nearer features replace samples, so a stale
    # value is a safe lower bound; it is recomputed only when a stop might be missed by it.
    farthest = 0.0
    stale = False
    dropped = 0
    hidden = 0
    # An edge can cross a pixel of the sub-area only if a partially covering feature was read.
    partial = False
    for k in range(k_first, k_end):
        p = bins.polygon[k]
        bound = edges.nearest_inv_z[p] * (1.0 + _EARLY_STOP_MARGIN)
        if covered == n:
            if bound >= farthest and stale:
                farthest = sc.o_iz[0]
                for i in range(1, n):
                    farthest = min(farthest, sc.o_iz[i])
                stale = False
            if bound < farthest:
                out.stopped[t] = k_end - k
                break
        box = (max(edges.x0[p], tx0), min(edges.x1[p], tx1 - 1),
               max(edges.y0[p], ty0), min(edges.y1[p], ty1 - 1))
        if box[0] > box[1] or box[2] > box[3]:
            continue
        if _hidden(box, bound, tx0, ty0, sc, lay):
            hidden += 1
            continue
        full = bins.full[k]
        partial |= not full
        if not _coverage(p, full, box, tx0, ty0, screen, edges, frame.offsets_fixed, sc, lay):
            continue
        plane = (screen.inv_z[p, 0], screen.inv_z[p, 1], screen.inv_z[p, 2], screen.layer[p])
        opaque = screen.opacity[p] >= 1.0
        if opaque and not trans_here:
            # The common case in its own small function: fewer live values, better code.
            added = _merge_opaque(p, plane, bound, box, (tx0, ty0, tw), frame.offsets_fixed,
                                  screen.layer, sc, lay)
        else:
            added, lost = _merge_general(p, plane, opaque, bound, box, (tx0, ty0, tw),
                                         frame.offsets_fixed, screen.layer, sc, lay)
            dropped += lost
        if added >= 0:
            covered += added
            stale = True
    out.dropped[t] = dropped
    out.hidden[t] = hidden
    if covered < n:
        _mark_uncovered(tw, ty1 - ty0, s_count, sc, lay)
    if out.fused:
        box_subarea(sf, (tx0, ty0, tx1, ty1), backdrop, any_translucent, out.want_range, sc,
                    out.rgb, out.range_m, sf.cov.on and partial)
    else:
        _write_store(tx0, ty0, tx1, ty1, backdrop, frame, background, out, sc)


@njit(cache=True, inline="always")
def _start_store(tx0, ty0, tx1, ty1, s_count, n, background, sc, lay):
    """Clear the sub-area's masks; with a background, every sample it covers starts out holding
    it. Returns how many samples hold an opaque feature. The store itself is read only where
    the masks say a sample is covered (_mark_uncovered names the rest once the list is read)."""
    covered = 0
    rows = ty1 - ty0
    for i in range(rows * lay.wpr):
        sc.covered[i] = 0
    for r in range(rows):
        sc.row_far[r] = np.inf
        sc.mixed[r] = 0
    if background.on:
        # The terrain is the first opaque feature of every sample it covers; its layer is
        # below every polygon's, so a polygon at exactly its depth is seen.
        tw = tx1 - tx0
        for y in range(ty0, ty1):
            r = y - ty0
            for s in range(s_count):
                word = r * lay.wpr + s // lay.spw
                shift = (s % lay.spw) * lay.size
                for x in range(tx0, tx1):
                    iz = background.inv_z[y, x, s]
                    if iz > 0.0:
                        i = ((y - ty0) * s_count + s) * tw + (x - tx0)
                        sc.o_id[i] = BACKGROUND_ID
                        sc.o_iz[i] = iz
                        sc.covered[word] |= np.uint64(1) << np.uint64(shift + x - tx0)
                        sc.row_far[r] = min(sc.row_far[r], iz)
                        covered += 1
            # Pixels where the terrain holds some samples but not all.
            any_px = np.uint64(0)
            all_px = ~np.uint64(0)
            for w in range(lay.wpr):
                any_px, all_px = _fold(sc.covered[r * lay.wpr + w], w, any_px, all_px, s_count,
                                       lay)
            sc.mixed[r] = any_px & ~all_px
    return covered


@njit(cache=True, inline="always")
def _slots(w, s_count, lay):
    """How many sample rows word w of a pixel row holds (the last word may hold fewer)."""
    return min(lay.spw, s_count - w * lay.spw)


@njit(cache=True, inline="always")
def _slot_bits(bits, slot, lay):
    """The pixel columns (bit x for column x) of sample row `slot` of a mask word."""
    return (bits >> np.uint64(slot * lay.size)) & low_bits(lay.size)


@njit(cache=True, inline="always")
def _sample_row(b, c, r, w, slot, origin, off_fixed, lay):
    """(sample s, store index of column 0, its x offset, b sy + c) of sample row `slot` of word
    w of pixel row r: what a feature's plane a sx + (b sy + c) needs along that sample row.
    Same expression, same order everywhere, so coplanar ties stay exact."""
    ty0, tw = origin[1], origin[2]
    s = w * lay.spw + slot
    py = (ty0 + r) * SUBPIXEL + off_fixed[s, 1]
    return s, (r * off_fixed.shape[0] + s) * tw, off_fixed[s, 0], b * (py * (1.0 / SUBPIXEL)) + c


@njit(cache=True, inline="always")
def _mark_uncovered(tw, th, s_count, sc, lay):
    """o_id = -1 at every sample no opaque feature covers (what the box filter and the store
    read as "nothing here")."""
    cols = low_bits(tw)
    for r in range(th):
        for w in range(lay.wpr):
            m_all = ~sc.covered[r * lay.wpr + w] & (cols * lay.rep[w])
            for slot in range(_slots(w, s_count, lay)):
                s = w * lay.spw + slot
                m = _slot_bits(m_all, slot, lay)
                while m != 0:
                    x = lowest_bit(m)
                    m &= m - np.uint64(1)
                    sc.o_id[(r * s_count + s) * tw + x] = -1


@njit(cache=True, inline="always")
def _hidden(box, bound, tx0, ty0, sc, lay):
    """Every sample of the feature's box in the sub-area holds an opaque feature nearer than
    the feature's nearest point (bound): it can change nothing (hierarchical rejection)."""
    lx0, lx1, ly0, ly1 = box
    cols = low_bits(lx1 - lx0 + 1) << np.uint64(lx0 - tx0)
    for y in range(ly0, ly1 + 1):
        r = y - ty0
        if bound >= sc.row_far[r]:
            return False
        for w in range(lay.wpr):
            m = cols * lay.rep[w]
            if (sc.covered[r * lay.wpr + w] & m) != m:
                return False
    return True


@njit(cache=True, inline="always")
def _layer(layers, f):
    """The layer of a stored opaque feature: the background's is below every polygon's."""
    return layers[f] if f >= 0 else -1


# Inlined: called once per list entry, and a call passes every array of its groups.
@njit(cache=True, inline="always")
def _coverage(p, full, box, tx0, ty0, screen, edges, off_fixed, sc, lay):
    """Polygon p's coverage of its box in the sub-area as masks in sc.cw (rows of the box),
    a row of samples at a time; False if it covers no sample there.

    Only the edges that some sample of the box lies outside take part (an edge whose worst
    box corner is inside is inside everywhere: affine). Each row's covered run is solved
    exactly per edge in integers: edge j less its top-left bias at the k-th sample of the row
    is e0 + step k (step = ia SUBPIXEL), inside iff >= 0, so each edge bounds k from one side
    (_first_inside: a floating-point quotient corrected in integers, no integer division).
    """
    lx0, lx1, ly0, ly1 = box
    ia, ib, ic, bias = edges.ia, edges.ib, edges.ic, edges.bias
    ext = lay.extent
    n_act = 0
    if not full:
        px_lo = lx0 * SUBPIXEL + ext[0]
        px_hi = lx1 * SUBPIXEL + ext[1]
        py_lo = ly0 * SUBPIXEL + ext[2]
        py_hi = ly1 * SUBPIXEL + ext[3]
        for j in range(screen.start[p], screen.start[p + 1]):
            px = px_lo if ia[j] > 0 else px_hi
            py = py_lo if ib[j] > 0 else py_hi
            if ia[j] * px + ib[j] * py + ic[j] < bias[j]:
                sc.act[n_act] = j
                sc.e_step[n_act] = ia[j] * SUBPIXEL
                # Guard: only read where the step is not 0.
                sc.e_inv[n_act] = 1.0 / sc.e_step[n_act] if ia[j] != 0 else 0.0
                n_act += 1
    wpr = lay.wpr
    for i in range((ly0 - ty0) * wpr, (ly1 - ty0 + 1) * wpr):
        sc.cw[i] = 0
    span = lx1 - lx0
    any_bit = False
    for s in range(off_fixed.shape[0]):
        ox = off_fixed[s, 0]
        oy = off_fixed[s, 1]
        word = s // lay.spw
        shift = (s % lay.spw) * lay.size + lx0 - tx0
        px0 = lx0 * SUBPIXEL + ox
        for y in range(ly0, ly1 + 1):
            py = y * SUBPIXEL + oy
            klo = 0
            khi = span
            for q in range(n_act):
                j = sc.act[q]
                e0 = ia[j] * px0 + ib[j] * py + ic[j] - bias[j]
                step = sc.e_step[q]
                # The edge is affine along the row: its sign at both ends of the box's run
                # settles most rows without a quotient (inside at both, or outside at both).
                e1 = e0 + step * span
                if e0 >= 0:
                    if e1 < 0:  # falls below 0 along the row: step < 0
                        khi = min(khi, _first_inside(-e0 - 1, -step, -sc.e_inv[q]) - 1)
                elif e1 < 0:
                    khi = -1  # outside at both ends: outside on the whole row
                    break
                else:  # rises to 0 along the row: step > 0
                    klo = max(klo, _first_inside(e0, step, sc.e_inv[q]))
            if klo <= khi:
                sc.cw[(y - ty0) * wpr + word] |= low_bits(khi - klo + 1) << np.uint64(shift + klo)
                any_bit = True
    return any_bit


@njit(cache=True, inline="always")
def _first_inside(e0, step, inv):
    """The least k >= 0 with e0 + step k >= 0, for e0 < 0 < step (inv = 1 / step): ceil(-e0 /
    step), estimated in float64 and made exact by integer checks (|e0| < 2**50, so the
    estimate is off by at most one either way)."""
    k = np.int64(math.ceil(-e0 * inv))
    if e0 + step * k < 0:
        k += 1
    elif k > 0 and e0 + step * (k - 1) >= 0:
        k -= 1
    return k


# Inlined: called once per list entry, and a call passes every array of its groups.
@njit(cache=True, inline="always")
def _merge_opaque(p, plane, bound, box, origin, off_fixed, layers, sc, lay):
    """Merge opaque polygon p's coverage (sc.cw) into the store of a sub-area with no
    translucency: uncovered samples take it outright, covered ones only where it is nearer
    (tested only in rows where the order is ambiguous). Returns the number of samples newly
    covered, or -1 if no sample changed.

    plane: (a, b, c, layer), 1/z = a sx + b sy + c; bound: its largest 1/z (with margin);
    box: (lx0, lx1, ly0, ly1) its pixels in the sub-area; origin: (tx0, ty0, tw).
    """
    a, b, c, lay_p = plane
    ly0, ly1 = box[2], box[3]
    ty0 = origin[1]
    low = _plane_floor(a, b, c, box)
    added = 0
    changed = False
    wpr = lay.wpr
    for y in range(ly0, ly1 + 1):
        r = y - ty0
        compare = bound >= sc.row_far[r]
        won_any = np.uint64(0)
        won_all = ~np.uint64(0)
        for w in range(wpr):
            idx = r * wpr + w
            cov = sc.cw[idx]
            old = sc.covered[idx]
            new = cov & ~old
            won = new
            if new != 0:
                sc.covered[idx] = old | new
                added += bit_count(new)
                _take(p, a, b, c, new, r, w, origin, off_fixed, sc, lay)
            if compare:
                amb = cov & old
                if amb != 0:
                    won |= _contest(p, a, b, c, lay_p, amb, r, w, origin, off_fixed, layers,
                                    sc, lay)
            won_any, won_all = _fold(won, w, won_any, won_all, off_fixed.shape[0], lay)
        if won_any != 0:
            sc.row_far[r] = min(sc.row_far[r], low)
            sc.mixed[r] = (sc.mixed[r] | won_any) & ~won_all
            changed = True
    return added if changed else -1


@njit(cache=True, inline="always")
def _plane_floor(a, b, c, box):
    """A lower bound of a b c's 1/z over the box's samples (affine: least at a corner of the
    pixel rectangle, which holds every sample), less a relative 1e-9 for rounding."""
    lx0, lx1, ly0, ly1 = box
    v = c + min(a * lx0, a * (lx1 + 1)) + min(b * ly0, b * (ly1 + 1))
    return v - abs(v) * 1e-9


@njit(cache=True, inline="always")
def _take(p, a, b, c, bits, r, w, origin, off_fixed, sc, lay):
    """Samples `bits` of word w of row r hold nothing yet: polygon p takes them, a run of
    pixels at a time (a convex polygon's row is one run)."""
    tx0 = origin[0]
    inv_sub = 1.0 / SUBPIXEL
    for slot in range(_slots(w, off_fixed.shape[0], lay)):
        m = _slot_bits(bits, slot, lay)
        if m == 0:
            continue
        _, base, ox, fy = _sample_row(b, c, r, w, slot, origin, off_fixed, lay)
        while m != 0:
            x0 = lowest_bit(m)
            run = lowest_bit(~(m >> np.uint64(x0)))
            for x in range(x0, x0 + run):
                i = base + x
                sc.o_iz[i] = a * (((tx0 + x) * SUBPIXEL + ox) * inv_sub) + fy
                sc.o_id[i] = p
            m &= ~(low_bits(run) << np.uint64(x0))


@njit(cache=True, inline="always")
def _fold(bits, w, any_px, all_px, s_count, lay):
    """(any_px, all_px) updated with word w of a row's sample masks: the pixel columns where
    any, and where every, sample of the row is in bits (fold over the samples' slots)."""
    for slot in range(_slots(w, s_count, lay)):
        m = _slot_bits(bits, slot, lay)
        any_px |= m
        all_px &= m
    return any_px, all_px


@njit(cache=True, inline="always")
def _contest(p, a, b, c, lay_p, bits, r, w, origin, off_fixed, layers, sc, lay):
    """Samples `bits` of word w of row r hold an opaque feature: polygon p replaces it where
    it is nearer. Returns the samples it won (a mask like bits)."""
    tx0 = origin[0]
    inv_sub = 1.0 / SUBPIXEL
    won = np.uint64(0)
    for slot in range(_slots(w, off_fixed.shape[0], lay)):
        m = _slot_bits(bits, slot, lay)
        if m == 0:
            continue
        _, base, ox, fy = _sample_row(b, c, r, w, slot, origin, off_fixed, lay)
        while m != 0:
            x = lowest_bit(m)
            m &= m - np.uint64(1)
            i = base + x
            iz = a * (((tx0 + x) * SUBPIXEL + ox) * inv_sub) + fy
            f = sc.o_id[i]
            if _nearer(iz, lay_p, p, sc.o_iz[i], _layer(layers, f), f):
                sc.o_iz[i] = iz
                sc.o_id[i] = p
                won |= np.uint64(1) << np.uint64(slot * lay.size + x)
    return won


@borrowing
def _merge_general(p, plane, opaque, bound, box, origin, off_fixed, layers, sc, lay):
    """Merge polygon p's coverage (sc.cw) into the store of a sub-area with translucency, a
    sample at a time: an opaque feature takes or contests samples as in
    _merge_opaque and hides the translucent ones behind it; a translucent one enters the
    sample's list of nearer translucent features. Rows where every covered sample is nearer
    than p skip their covered samples. Returns (samples newly covered or -1 if no opaque
    sample changed, translucent features dropped from a full list)."""
    a, b, c, lay_p = plane
    ly0, ly1 = box[2], box[3]
    tx0, ty0 = origin[0], origin[1]
    low = _plane_floor(a, b, c, box)
    s_count = off_fixed.shape[0]
    inv_sub = 1.0 / SUBPIXEL
    k_max = sc.t_iz.shape[1]
    added = 0
    changed = False
    dropped = 0
    wpr = lay.wpr
    for y in range(ly0, ly1 + 1):
        r = y - ty0
        compare = bound >= sc.row_far[r]
        wrote = False
        for w in range(wpr):
            idx = r * wpr + w
            cov = sc.cw[idx]
            old = sc.covered[idx]
            bits = cov if compare else cov & ~old
            if bits == 0:
                continue
            # Pixels that see translucency are shaded a sample at a time whatever their opaque
            # samples hold: whatever this feature touches is marked mixed and stays so.
            touched, _ = _fold(bits, w, np.uint64(0), np.uint64(0), s_count, lay)
            sc.mixed[r] |= touched
            if opaque:
                new = cov & ~old
                sc.covered[idx] = old | new
                added += bit_count(new)
            for slot in range(_slots(w, s_count, lay)):
                m = _slot_bits(bits, slot, lay)
                held = _slot_bits(old, slot, lay)
                _, base, ox, fy = _sample_row(b, c, r, w, slot, origin, off_fixed, lay)
                while m != 0:
                    x = lowest_bit(m)
                    m &= m - np.uint64(1)
                    i = base + x
                    iz = a * (((tx0 + x) * SUBPIXEL + ox) * inv_sub) + fy
                    f = sc.o_id[i]
                    if ((held >> np.uint64(x)) & np.uint64(1)) != 0 and not _nearer(
                            iz, lay_p, p, sc.o_iz[i], _layer(layers, f), f):
                        continue
                    if opaque:
                        sc.o_iz[i] = iz
                        sc.o_id[i] = p
                        wrote = True
                        # Translucent features now behind the opaque one are hidden.
                        n_t = sc.t_cnt[i]
                        while n_t > 0 and not _nearer(sc.t_iz[i, n_t - 1], sc.t_lay[i, n_t - 1],
                                                      sc.t_id[i, n_t - 1], iz, lay_p, p):
                            n_t -= 1
                        sc.t_cnt[i] = n_t
                    else:
                        n_t = sc.t_cnt[i]
                        pos = n_t
                        while pos > 0 and _nearer(iz, lay_p, p, sc.t_iz[i, pos - 1],
                                                  sc.t_lay[i, pos - 1], sc.t_id[i, pos - 1]):
                            pos -= 1
                        if n_t == k_max:
                            # Store full: the farthest of the K + 1 is dropped (it is the
                            # one seen through all the others).
                            dropped += 1
                            if pos == k_max:
                                continue
                            n_t -= 1
                        for q in range(n_t, pos, -1):
                            sc.t_iz[i, q] = sc.t_iz[i, q - 1]
                            sc.t_id[i, q] = sc.t_id[i, q - 1]
                            sc.t_lay[i, q] = sc.t_lay[i, q - 1]
                        sc.t_iz[i, pos] = iz
                        sc.t_id[i, pos] = p
                        sc.t_lay[i, pos] = lay_p
                        sc.t_cnt[i] = n_t + 1
        if wrote:
            sc.row_far[r] = min(sc.row_far[r], low)
            changed = True
    return (added if changed else -1), dropped


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
            base = (y - ty0) * s_count * tw + (x - tx0)
            near_range = np.inf
            for s in range(s_count):
                i = base + s * tw
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
