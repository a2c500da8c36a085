"""numba kernels for multi-sample visibility (see visibility.py)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import BACKGROUND_ID, EARTH_ID, F_ON, SKY_ID
from channel_worker.pipeline.fog.fog import fog_cos
from channel_worker.pipeline.resolve.shading import through_air

#: Relative margin on the early stop of a sub-area list: 1/z at a sample inside a polygon
#: can exceed the polygon's largest vertex 1/z only by rounding (~1e-16 relative).
_EARLY_STOP_MARGIN = 1e-9

#: Marks a sub-area whose samples do not all see one thing (not a feature identity).
_MIXED = -100


@njit(cache=True, inline="always")
def _inside(px, py, s0, s1, ia, ib, ic, bias):
    """Exact edge test of sample (px, py) (1/SUBPIXEL units) against polygon edges s0:s1."""
    for j in range(s0, s1):
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
def visibility_kernel(tile_start, entry_polygon, entry_full, size, tiles_x, width, height,
                      poly_start, ia, ib, ic, bias, x0, x1, y0, y1, nearest, inv_z, opacity,
                      layer, off_fixed, subpixel, horizon, mapping, any_translucent, want_range,
                      out_opaque, out_trans, out_count, out_range, out_dropped, out_stopped,
                      fused, colour, sky, earth, dz_row, height_above, out_rgb, bg_on, bg_rgb,
                      bg_iz, bg_range, air, cloud_on, cloud):
    """Per sub-area, per sample: the nearest opaque feature and the nearer translucent ones.

    Sub-areas run in parallel, each with its own small sample store that stays in cache.
    A list is read nearest first; reading stops once every sample of the sub-area holds an
    opaque feature nearer than the nearest point of the next feature (hierarchical depth
    rejection; with the list order it skips all the rest).

    horizon: (kx, ky, k0), the world-z of the ray through a screen point (horizon.py); an
    uncovered sample sees the earth where it is negative, the sky elsewhere.
    mapping: (sx_scale, sx_off, sy_scale, sy_off), screen = tangent * scale + offset.
    any_translucent: the frame has translucent polygons (else out_count is pre-zeroed and
    out_trans never written). want_range: fill out_range (else it is left untouched).

    fused: instead of writing the sample store, shade each sample from its features and write
    the box-filtered pixel colour to out_rgb (and, with want_range, the pixel's nearest range
    including the earth plane, dz_row / height_above as in the resolve stage): the seed's
    per-sub-area pixel output, with no sample-sized array in memory.

    bg_on: the frame has a Background (terrain stage): every sample starts out holding it as
    its nearest opaque feature (BACKGROUND_ID at bg_iz, nothing where bg_iz is 0), so polygons
    behind the terrain are hidden and a list stops early behind a hill; what no polygon covers
    takes the background's colour bg_rgb and range bg_range. air: air.air_params (polygons are
    seen through the haze and fog per sample at their range when air has either). cloud_on: cloud (H, W, 5) holds each
    pixel's cloud (Background.cloud), laid over every polygon sample beyond its entry range.
    """
    n_tiles = tile_start.shape[0] - 1
    s_count = off_fixed.shape[0]
    k_max = out_trans.shape[3]
    inv_sub = 1.0 / subpixel
    # A thread takes a whole row of sub-areas at a time (handed out one by one, for balance:
    # sky rows are cheap) and walks it left to right, so its pixel writes run along the
    # image rows instead of jumping a page per row of every sub-area; the sample store is
    # allocated once per row of sub-areas. (The caller sets the parallel chunk size to 1.)
    tiles_y = n_tiles // tiles_x
    n_max = size * size * s_count
    max_edges = 3
    for p in range(poly_start.shape[0] - 1):
        max_edges = max(max_edges, poly_start[p + 1] - poly_start[p])
    for row in prange(tiles_y):
        o_iz = np.empty(n_max, np.float64)
        o_id = np.empty(n_max, np.int32)
        o_lay = np.empty(n_max, np.int32)
        n_t = n_max if any_translucent else 1
        t_iz = np.empty((n_t, k_max), np.float64)
        t_id = np.empty((n_t, k_max), np.int32)
        t_lay = np.empty((n_t, k_max), np.int32)
        t_cnt = np.zeros(n_t, np.int32)
        e_step = np.empty(max_edges, np.int64)
        for t in range(row * tiles_x, (row + 1) * tiles_x):
            _tile(t, tile_start, entry_polygon, entry_full, size, tiles_x, width, height,
                  poly_start, ia, ib, ic, bias, x0, x1, y0, y1, nearest, inv_z, opacity, layer,
                  off_fixed, subpixel, horizon, mapping, any_translucent, want_range,
                  out_opaque, out_trans, out_count, out_range, out_dropped, out_stopped,
                  o_iz, o_id, o_lay, t_iz, t_id, t_lay, t_cnt, s_count, k_max, inv_sub,
                  fused, colour, sky, earth, dz_row, height_above, out_rgb, e_step, bg_on,
                  bg_rgb, bg_iz, bg_range, air, cloud_on, cloud)


@njit(cache=True)
def _tile(t, tile_start, entry_polygon, entry_full, size, tiles_x, width, height,
          poly_start, ia, ib, ic, bias, x0, x1, y0, y1, nearest, inv_z, opacity, layer,
          off_fixed, subpixel, horizon, mapping, any_translucent, want_range,
          out_opaque, out_trans, out_count, out_range, out_dropped, out_stopped,
          o_iz, o_id, o_lay, t_iz, t_id, t_lay, t_cnt, s_count, k_max, inv_sub,
          fused, colour, sky, earth, dz_row, height_above, out_rgb, e_step, bg_on, bg_rgb,
          bg_iz, bg_range, air, cloud_on, cloud):
    """One sub-area of visibility_kernel, with the chunk's sample store as scratch."""
    tx0, ty0, tx1, ty1 = _subarea_rect(t, tiles_x, size, width, height)
    tw = tx1 - tx0
    # With a Background the sky and earth come painted by the terrain stage, per pixel.
    background = 0 if bg_on else _background(tx0, ty0, size, horizon)
    n = tw * (ty1 - ty0) * s_count
    if fused and bg_on and tile_start[t] == tile_start[t + 1]:
        # No polygon here: the background as the terrain stage made it.
        for y in range(ty0, ty1):
            for x in range(tx0, tx1):
                out_rgb[y, x, 0] = bg_rgb[y, x, 0]
                out_rgb[y, x, 1] = bg_rgb[y, x, 1]
                out_rgb[y, x, 2] = bg_rgb[y, x, 2]
                if want_range:
                    out_range[y, x] = bg_range[y, x]
        return
    if fused and tile_start[t] == tile_start[t + 1]:
        # Nothing in the sub-area: the background alone, one colour unless the horizon
        # crosses it (and, with ranges, only if it is sky: the earth's range varies).
        # Checked before the store is even cleared.
        if _fill_background(tx0, ty0, tx1, ty1, background, sky, earth, want_range, out_rgb,
                            out_range):
            return
    # Only the identities need clearing: 1/z and layer are read only where an identity is set.
    covered = 0
    if bg_on:
        # The terrain is the first opaque feature of every sample it covers; its layer is
        # below every polygon's, so a polygon at exactly its depth is seen.
        for y in range(ty0, ty1):
            for x in range(tx0, tx1):
                base = ((y - ty0) * tw + (x - tx0)) * s_count
                for s in range(s_count):
                    iz = bg_iz[y, x, s]
                    if iz > 0.0:
                        o_id[base + s] = BACKGROUND_ID
                        o_iz[base + s] = iz
                        o_lay[base + s] = -1
                        covered += 1
                    else:
                        o_id[base + s] = -1
    else:
        for i in range(n):
            o_id[i] = -1
    if any_translucent:
        for i in range(n):
            t_cnt[i] = 0
    # Sub-areas with no translucent feature in their list take the opaque-only path even in
    # a frame that has translucent features elsewhere.
    trans_here = False
    if any_translucent:
        for k in range(tile_start[t], tile_start[t + 1]):
            if opacity[entry_polygon[k]] < 1.0:
                trans_here = True
                break
    # The farthest stored opaque 1/z only grows as nearer features replace samples, so a stale
    # value is a safe lower bound; it is recomputed only when a stop might be missed by it.
    farthest = 0.0
    stale = False
    dropped = 0
    for k in range(tile_start[t], tile_start[t + 1]):
        p = entry_polygon[k]
        if covered == n:
            bound = nearest[p] * (1.0 + _EARLY_STOP_MARGIN)
            if bound >= farthest and stale:
                farthest = o_iz[0]
                for i in range(1, n):
                    farthest = min(farthest, o_iz[i])
                stale = False
            if bound < farthest:
                out_stopped[t] = tile_start[t + 1] - k
                break
        full = entry_full[k]
        a = inv_z[p, 0]
        b = inv_z[p, 1]
        c = inv_z[p, 2]
        lay = layer[p]
        opaque = opacity[p] >= 1.0
        s0 = poly_start[p]
        s1 = poly_start[p + 1]
        lx0 = max(x0[p], tx0)
        lx1 = min(x1[p], tx1 - 1)
        ly0 = max(y0[p], ty0)
        ly1 = min(y1[p], ty1 - 1)
        if opaque and not trans_here:
            # The common case in its own small function: fewer live values, better code.
            added = _cover_opaque(p, full, a, b, c, lay, s0, s1, lx0, lx1, ly0, ly1, tx0, ty0, tw,
                                  s_count, off_fixed, subpixel, inv_sub, ia, ib, ic, bias,
                                  o_iz, o_id, o_lay, e_step)
            if added >= 0:
                covered += added
                stale = True
            continue
        changed = False
        n_edges = s1 - s0
        if not full:
            for j in range(n_edges):
                e_step[j] = ia[s0 + j] * subpixel
        for s in range(s_count):
            ox = off_fixed[s, 0]
            oy = off_fixed[s, 1]
            for y in range(ly0, ly1 + 1):
                py = y * subpixel + oy
                klo = 0
                khi = lx1 - lx0
                if not full:
                    klo, khi = _row_span(n_edges, s0, ia, ib, ic, bias, e_step,
                                         lx0 * subpixel + ox, py, khi)
                for x in range(lx0 + klo, lx0 + khi + 1):
                    px = x * subpixel + ox
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
    out_dropped[t] = dropped

    kx, ky, k0 = horizon[0], horizon[1], horizon[2]
    sx_scale, sx_off, sy_scale, sy_off = mapping[0], mapping[1], mapping[2], mapping[3]
    if fused:
        # A sub-area whose every sample sees one thing and nothing translucent (open sky,
        # open ground, the inside of a large face) is one colour: fill it without shading.
        uniform = o_id[0]
        for i in range(n):
            if o_id[i] != uniform or (any_translucent and t_cnt[i] != 0):
                uniform = _MIXED
                break
        if uniform < 0 and uniform != _MIXED:
            uniform = background if background != 0 else _MIXED
        if air[0] != 0.0 or air[F_ON] != 0.0 or cloud_on:
            uniform = _MIXED  # hazed, fogged or clouded colours vary with range
        if uniform != _MIXED and not want_range:
            if uniform >= 0:
                cr, cg, cb = colour[uniform, 0], colour[uniform, 1], colour[uniform, 2]
            elif uniform == EARTH_ID:
                cr, cg, cb = earth[0], earth[1], earth[2]
            else:
                cr, cg, cb = sky[0], sky[1], sky[2]
            for y in range(ty0, ty1):
                for x in range(tx0, tx1):
                    out_rgb[y, x, 0] = cr
                    out_rgb[y, x, 1] = cg
                    out_rgb[y, x, 2] = cb
            return
        _box_pixels(tx0, ty0, tx1, ty1, tw, s_count, off_fixed, subpixel, inv_sub, horizon,
                    mapping, background, want_range, o_iz, o_id, t_iz, t_id, t_cnt,
                    any_translucent, opacity, colour, sky, earth, dz_row, height_above, out_rgb,
                    out_range, bg_on, bg_rgb, bg_range, air, cloud_on, cloud)
        return
    for y in range(ty0, ty1):
        sy_row = (y * subpixel) * inv_sub
        for x in range(tx0, tx1):
            base = ((y - ty0) * tw + (x - tx0)) * s_count
            near_range = np.inf
            for s in range(s_count):
                i = base + s
                f = o_id[i]
                if f < 0 and bg_on:
                    f = BACKGROUND_ID  # resolve reads its colour and range from the Background
                elif f < 0:
                    if background != 0:
                        f = background
                    else:
                        sx = (x * subpixel + off_fixed[s, 0]) * inv_sub
                        sy = sy_row + off_fixed[s, 1] * inv_sub
                        f = EARTH_ID if kx * sx + ky * sy + k0 < 0.0 else SKY_ID
                elif want_range:
                    sx = (x * subpixel + off_fixed[s, 0]) * inv_sub
                    sy = sy_row + off_fixed[s, 1] * inv_sub
                    # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
                    rx = (sx - sx_off) / sx_scale
                    ry = (sy - sy_off) / sy_scale
                    near_range = min(near_range, math.sqrt(rx * rx + ry * ry + 1.0) / o_iz[i])
                out_opaque[y, x, s] = f
                if any_translucent:
                    m = t_cnt[i]
                    out_count[y, x, s] = m
                    for q in range(m):
                        out_trans[y, x, s, q] = t_id[i, q]
            if want_range:
                out_range[y, x] = near_range


@njit(cache=True, inline="always")
def _row_span(n_edges, s0, ia, ib, ic, bias, e_step, px0, py, span):
    """(first, last) k in 0..span with the sample at px0 + k * SUBPIXEL, py inside every edge
    (first > last if none): the covered run of one row of samples, solved exactly per edge.

    Edge j's value at the k-th sample, less its top-left bias, is e0 + step * k in integers
    (step = ia * SUBPIXEL), inside iff >= 0, so each edge bounds k from one side.
    """
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


@njit(cache=True)
def _cover_opaque(p, full, a, b, c, lay, s0, s1, lx0, lx1, ly0, ly1, tx0, ty0, tw, s_count,
                  off_fixed, subpixel, inv_sub, ia, ib, ic, bias, o_iz, o_id, o_lay, e_step):
    """Depth-test one opaque polygon into the store of a sub-area with no translucency.

    Returns the number of samples newly covered, or -1 if no sample changed.
    """
    n_edges = s1 - s0
    if not full:
        for j in range(n_edges):
            e_step[j] = ia[s0 + j] * subpixel
    added = 0
    changed = False
    span = lx1 - lx0
    for s in range(s_count):
        ox = off_fixed[s, 0]
        oy = off_fixed[s, 1]
        for y in range(ly0, ly1 + 1):
            py = y * subpixel + oy
            klo = 0
            khi = span
            if not full:
                klo, khi = _row_span(n_edges, s0, ia, ib, ic, bias, e_step, lx0 * subpixel + ox,
                                     py, span)
                if klo > khi:
                    continue
            row = ((y - ty0) * tw - tx0) * s_count + s
            fy = b * (py * inv_sub) + c
            for x in range(lx0 + klo, lx0 + khi + 1):
                px = x * subpixel + ox
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
def _background(tx0, ty0, size, horizon):
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


@njit(cache=True)
def _fill_background(tx0, ty0, tx1, ty1, background, sky, earth, want_range, out_rgb, out_range):
    """Fill the sub-area with its background if it has a single one (with ranges: only the
    sky, at +inf; the earth's range varies); False if it was not filled."""
    if background == EARTH_ID and not want_range:
        cr, cg, cb = earth[0], earth[1], earth[2]
    elif background == SKY_ID:
        cr, cg, cb = sky[0], sky[1], sky[2]
    else:
        return False
    for y in range(ty0, ty1):
        for x in range(tx0, tx1):
            out_rgb[y, x, 0] = cr
            out_rgb[y, x, 1] = cg
            out_rgb[y, x, 2] = cb
            if want_range:
                out_range[y, x] = np.inf
    return True


@njit(cache=True)
def _box_pixels(tx0, ty0, tx1, ty1, tw, s_count, off_fixed, subpixel, inv_sub, horizon, mapping,
                background, want_range, o_iz, o_id, t_iz, t_id, t_cnt, any_translucent, opacity,
                colour, sky, earth, dz_row, height_above, out_rgb, out_range, bg_on, bg_rgb,
                bg_range, air, cloud_on, cloud):
    """Pixel outputs of one sub-area: each sample shaded (translucent features front to back
    over the opaque one, or the background: terrain, sky, earth), averaged over the pixel;
    optionally the range. With haze each polygon sample is hazed by its own range, and with
    clouds seen through the pixel's cloud if it lies beyond the cloud's entry range."""
    fogged = air[F_ON] != 0.0
    by_range = air[0] != 0.0 or fogged or cloud_on
    kx, ky, k0 = horizon[0], horizon[1], horizon[2]
    sx_scale, sx_off, sy_scale, sy_off = mapping[0], mapping[1], mapping[2], mapping[3]
    inv_s = 1.0 / s_count
    sky_r, sky_g, sky_b = sky[0], sky[1], sky[2]
    earth_r, earth_g, earth_b = earth[0], earth[1], earth[2]
    for y in range(ty0, ty1):
        for x in range(tx0, tx1):
            base = ((y - ty0) * tw + (x - tx0)) * s_count
            if not want_range:
                # Most pixels, even in a busy sub-area, see one thing with every sample (with
                # haze or clouds: one polygon, seen through the air at the pixel's centre).
                f0 = o_id[base]
                same = f0 >= 0 or (background != 0 and not by_range)
                for s in range(1, s_count):
                    if o_id[base + s] != f0:
                        same = False
                        break
                if same and any_translucent:
                    for s in range(s_count):
                        if t_cnt[base + s] != 0:
                            same = False
                            break
                if same:
                    if f0 >= 0 and by_range:
                        iz = 0.0
                        for s in range(s_count):
                            iz += o_iz[base + s]
                        rx = ((x + 0.5) - sx_off) / sx_scale
                        ry = ((y + 0.5) - sy_off) / sy_scale
                        ray = math.sqrt(rx * rx + ry * ry + 1.0)
                        cos_ax = fog_cos(air, rx, ry, ray) if fogged else 0.0
                        # Guards: 1/z > 0 for polygons (clipped to z >= near); ray >= 1.
                        cr, cg, cb = through_air(air, cloud_on, cloud, y, x, ray * s_count / iz,
                                                 (dz_row[0] * rx + dz_row[1] * ry + dz_row[2]) / ray,
                                                 cos_ax, colour[f0, 0], colour[f0, 1], colour[f0, 2])
                        out_rgb[y, x, 0] = cr
                        out_rgb[y, x, 1] = cg
                        out_rgb[y, x, 2] = cb
                    elif f0 >= 0:
                        out_rgb[y, x, 0] = colour[f0, 0]
                        out_rgb[y, x, 1] = colour[f0, 1]
                        out_rgb[y, x, 2] = colour[f0, 2]
                    elif background == EARTH_ID:
                        out_rgb[y, x, 0] = earth_r
                        out_rgb[y, x, 1] = earth_g
                        out_rgb[y, x, 2] = earth_b
                    else:
                        out_rgb[y, x, 0] = sky_r
                        out_rgb[y, x, 1] = sky_g
                        out_rgb[y, x, 2] = sky_b
                    continue
            r = 0.0
            g = 0.0
            b = 0.0
            near_range = np.inf
            for s in range(s_count):
                i = base + s
                through = 1.0
                ray = 1.0
                sin_el = 0.0
                cos_ax = 0.0
                if by_range:
                    rx = ((x * subpixel + off_fixed[s, 0]) * inv_sub - sx_off) / sx_scale
                    ry = ((y * subpixel + off_fixed[s, 1]) * inv_sub - sy_off) / sy_scale
                    ray = math.sqrt(rx * rx + ry * ry + 1.0)
                    sin_el = (dz_row[0] * rx + dz_row[1] * ry + dz_row[2]) / ray  # guard: ray >= 1
                    if fogged:
                        cos_ax = fog_cos(air, rx, ry, ray)
                if any_translucent:
                    for q in range(t_cnt[i]):
                        p = t_id[i, q]
                        a = opacity[p] * through
                        cr, cg, cb = colour[p, 0], colour[p, 1], colour[p, 2]
                        if by_range:
                            # Guard: translucent features are clipped to z >= near > 0 too.
                            cr, cg, cb = through_air(air, cloud_on, cloud, y, x, ray / t_iz[i, q],
                                                     sin_el, cos_ax, cr, cg, cb)
                        r += a * cr
                        g += a * cg
                        b += a * cb
                        through *= 1.0 - opacity[p]
                f = o_id[i]
                if f >= 0:
                    cr, cg, cb = colour[f, 0], colour[f, 1], colour[f, 2]
                    if by_range:
                        cr, cg, cb = through_air(air, cloud_on, cloud, y, x, ray / o_iz[i], sin_el,
                                                 cos_ax, cr, cg, cb)
                    r += through * cr
                    g += through * cg
                    b += through * cb
                    if want_range:
                        rx = ((x * subpixel + off_fixed[s, 0]) * inv_sub - sx_off) / sx_scale
                        ry = ((y * subpixel + off_fixed[s, 1]) * inv_sub - sy_off) / sy_scale
                        # Guard: polygons are clipped to z >= near > 0, so 1/z > 0.
                        near_range = min(near_range, math.sqrt(rx * rx + ry * ry + 1.0) / o_iz[i])
                    continue
                if bg_on:
                    r += through * bg_rgb[y, x, 0]
                    g += through * bg_rgb[y, x, 1]
                    b += through * bg_rgb[y, x, 2]
                    if want_range:
                        near_range = min(near_range, bg_range[y, x])
                    continue
                f = background
                if f == 0 or (want_range and f == EARTH_ID):
                    sx = (x * subpixel + off_fixed[s, 0]) * inv_sub
                    sy = (y * subpixel + off_fixed[s, 1]) * inv_sub
                    dz = kx * sx + ky * sy + k0
                    if f == 0:
                        f = EARTH_ID if dz < 0.0 else SKY_ID
                    if want_range and f == EARTH_ID:
                        rx = (sx - sx_off) / sx_scale
                        ry = (sy - sy_off) / sy_scale
                        ez = dz_row[0] * rx + dz_row[1] * ry + dz_row[2]
                        # Guard: ez < 0 for earth samples (the same line as dz, in tangents);
                        # at the horizon rounding may give 0 or a tiny positive: range -> huge.
                        near_range = min(near_range, math.sqrt(rx * rx + ry * ry + 1.0) * height_above / max(-ez, 1e-300))
                # Scalars, not an array chosen per sample: that would cost a reference-count
                # update (an atomic) per sample.
                if f == EARTH_ID:
                    r += through * earth_r
                    g += through * earth_g
                    b += through * earth_b
                else:
                    r += through * sky_r
                    g += through * sky_g
                    b += through * sky_b
            out_rgb[y, x, 0] = r * inv_s
            out_rgb[y, x, 1] = g * inv_s
            out_rgb[y, x, 2] = b * inv_s
            if want_range:
                out_range[y, x] = near_range


@njit(cache=True, parallel=True)
def coverage_kernel(tile_start, entry_polygon, entry_full, size, tiles_x, width, height,
                    poly_start, ia, ib, ic, bias, x0, x1, y0, y1, off_fixed, subpixel, out_count):
    """How many polygons cover each sample: the same lists as visibility_kernel, but each
    sample decided by the direct edge test (_inside), independently of its row solver."""
    n_tiles = tile_start.shape[0] - 1
    s_count = off_fixed.shape[0]
    for t in prange(n_tiles):
        tx0, ty0, tx1, ty1 = _subarea_rect(t, tiles_x, size, width, height)
        for k in range(tile_start[t], tile_start[t + 1]):
            p = entry_polygon[k]
            full = entry_full[k]
            for y in range(max(y0[p], ty0), min(y1[p], ty1 - 1) + 1):
                for x in range(max(x0[p], tx0), min(x1[p], tx1 - 1) + 1):
                    for s in range(s_count):
                        px = x * subpixel + off_fixed[s, 0]
                        py = y * subpixel + off_fixed[s, 1]
                        if full or _inside(px, py, poly_start[p], poly_start[p + 1], ia, ib, ic, bias):
                            out_count[y, x, s] += 1
