"""numba kernels of the terrain cast (fan.py): one radial scan per screen line through the
vertical vanishing point, emitted straight into the pixels it owns (JP H07-76990's column
scan, cast at any roll and pitch as Voxlap does).

A line is the image of one vertical half-plane through the eye (one azimuth). Its ground line
is walked outward by an exact 2-D DDA over the voxel grid of the wanted level (_walk). Each
surface piece rising above the horizon of what was seen so far is a segment in the half-plane,
(ground range, height relative to the eye) from its near to its far end, coloured by a _Paint:
the voxel's bilinear corner colours between two local points, or one colour (walls and
patterns). _surface and _wall find the part of a segment that shows; _emit projects it onto
the line (one division per end point: the screen position along the line is a projective
function of the point) and spreads it over the line's pixel steps by the share of each step
it covers; _finish_step keeps a step's terrain, through the haze and fog, in the line's
buffer. _write then writes the pixels the line owns, each interpolated between the line and
the neighbouring line on the other side of the pixel's centre, over the sky or earth plane
behind it.

Occlusion is by elevation tangent (z / r against the highest seen so far): no trigonometry
per voxel. A line's steps are the pixel rows (or columns) it crosses, in order of elevation
(fan.py's fan: every pixel belongs to exactly one line).

The per-line and per-segment functions are compiled without reference counting
(jit.borrowing): they take the groups whole, and numba would otherwise count every array of a
group in and out of every call.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from channel_worker.pipeline.contract import F_ON, F_RGB, F_WORLD_AXIS
from channel_worker.pipeline.fog.fog import fog_depth
from channel_worker.pipeline.jit import borrowing, claim, lanes, new_queue
from channel_worker.pipeline.scene.texture_sampling import TextureArrays, texture_modulation

from ._groups import (
    FIELD,
    FOREST,
    GRASS,
    PAD,
    ROCK,
    T_CLASS_FADE,
    T_CLASS_N,
    T_CLASSES,
    T_FIELD_H,
    T_FIELD_SHARE,
    T_FIELD_SLOPE,
    T_FIELD_W,
    T_FIELDS,
    T_FIELDS_N,
    T_HEDGE,
    T_HEDGE_M,
    T_LUM_REF,
    T_ORIGIN,
    T_PAD_COVERED,
    T_PADS_AT,
    T_PADS_N,
    T_ROCK_SLOPE,
)
from ._sky_kernels import backdrop_along
from .haze import haze_amount

# Line state (one small array per lane, so the helpers can update it in place).
_ROW, _AR, _AG, _AB, _AW, _IR = 0, 1, 2, 3, 4, 5
_R1, _Z1, _R2, _Z2 = 6, 7, 8, 9  # the last segment emitted
_TANMAX = 10  # tangent of the highest elevation seen so far (the line's horizon)
_SMAX = 11  # the horizon's position along the line (steps)
_GROUND = 12  # what the last surface emitted is: 1 ground, 2 a tree pattern's top, 3 its side, 0 else
_SLOPE = 13  # that voxel's slope (tangent), for the land's detail (TerrainDetail)
_DETAIL = 14  # 1: the line draws the land's detail (TerrainDetail.on)
_CANOPY = 2.0  # _GROUND's value for a tree's top
_CANOPY_SIDE = 3.0  # and for a stand's side
_CELL_I, _CELL_J, _CELL_FIELD = 15, 16, 17  # the last field cell _detail looked at, and its verdict
_AC = 18  # the current step's coverage by a forest's canopy or sides
_STATE = 19
# The line's buffer, a row per step: premultiplied colour (after haze and fog once the line is
# cast, _through_air), coverage, and 1/z (eye depth, metres) of the surface at the step's
# centre; for _through_air: the range haze and fog take, and for the land's detail whether
# the step ends on ground, its slope, the sine of the ray's angle to it, and the share of its
# coverage that is a forest's (its texture modulates that share alone: at a stand's edge a
# step is part meadow).
_B_R, _B_G, _B_B, _B_A, _B_IZ = 0, 1, 2, 3, 4
_B_RANGE, _B_GROUND, _B_SLOPE, _B_GRAZE, _B_FOREST = 5, 6, 7, 8, 9
_BUF = 10
# A line's record in its lane (cast_kernel): the steps it walks, the steps it owns, and its
# steps.
_M_LO, _M_HI, _M_FIRST, _M_LAST, _M_N = 0, 1, 2, 3, 4
_META = 5
#: Lines per block, at most and at least: a lane casts a block's lines in order, and the
#: lines on either side of it (two casts more per block: 6 % at 32 lines, 17 % at 12). Blocks
#: are made small enough for four per thread (_block_lines): at 16 threads a 1030-line frame
#: had 33 blocks of 32, two per thread, and the thread with two ground blocks set the time.
_BLOCK_MAX = 32
_BLOCK_MIN = 12


@njit(cache=True, inline="always")
def _block_lines(n_lines, threads):
    """Lines per block of cast_kernel's queue: four blocks per thread, within the bounds."""
    return min(_BLOCK_MAX, max(_BLOCK_MIN, n_lines // (4 * max(1, threads))))

#: Depth of the skirt down the database's edge (metres): deep enough to reach below any
#: horizon the scan starts from.
_SKIRT_M = 1e7

#: A wall is emitted where two neighbouring voxels' corners disagree by more than this (metres):
#: below it the step is float32 rounding of copies of one value.
_WALL_DZ = 1e-3

#: Distances (pixels) from a pixel centre closer than this are a tie (own_steps).
_TIE = 1e-9

#: Wedges of the fan (fan.py): which screen edge a wedge's lines are aimed at.
UP, DOWN, LEFT, RIGHT = 0, 1, 2, 3


class _Colours(NamedTuple):
    """The voxels' colours (VoxelPages.rgb and .lut): all that painting a segment reads of the
    database, so the per-segment functions take two arrays, not the whole database."""

    rgb: np.ndarray
    lut: np.ndarray


class _Paint(NamedTuple):
    """How a segment is coloured: the bilinear corner colours of voxel (vy, vx) of page at the
    local point (u0, v0) + t ((u1, v1) - (u0, v0)) for segment parameter t; or, page < 0,
    the one colour rgb (a wall, a pattern band or top)."""

    page: int
    vy: int
    vx: int
    u0: float
    v0: float
    u1: float
    v1: float
    rgb: tuple


class _Line(NamedTuple):
    """One line of the fan as the emission reads it. s is the position along the line in
    steps, in order of elevation (step k spans s = k .. k + 1); the unnormalised world
    direction of the screen point at s has horizontal component h0 + h1 s along the line's
    azimuth and vertical component z0 + z1 s (both affine in s: the screen maps linearly to
    eye rays). n: steps. tan_lo, tan_hi: elevation tangents at s = 0 and s = n (-inf or +inf
    where that end is the nadir or zenith). axh: the fog axis's horizontal component along
    the azimuth. dx, dy: the azimuth's unit direction (east, north); ex, ey, ez: the eye's
    position relative to the database origin, metres."""

    h0: float
    h1: float
    z0: float
    z1: float
    n: int
    tan_lo: float
    tan_hi: float
    axh: float
    dx: float
    dy: float
    ex: float
    ey: float
    ez: float


@njit(cache=True, inline="always")
def _direction(ln, s):
    """(horizontal, vertical) of the eye ray through the line's point at s; past the vanishing
    point (horizontal <= 0) the vertical itself."""
    h = ln.h0 + ln.h1 * s
    z = ln.z0 + ln.z1 * s
    if h <= 0.0:
        return 0.0, (-1.0 if s < 0.5 * ln.n else 1.0)
    return h, z


@njit(cache=True, inline="always")
def _s_of_tan(ln, t):
    """Position along the line (0 .. n) of the ray whose elevation tangent is t."""
    if t <= ln.tan_lo:
        return 0.0
    if t >= ln.tan_hi:
        return float(ln.n)
    den = ln.z1 - t * ln.h1
    # Guard: inside (tan_lo, tan_hi) the map from s to the tangent is monotone and finite, so
    # den = 0 would need t outside it; a rounding zero gives the end the tangent is nearer.
    if den == 0.0:
        return 0.0 if t - ln.tan_lo < ln.tan_hi - t else float(ln.n)
    s = (t * ln.h0 - ln.z0) / den
    return min(max(s, 0.0), float(ln.n))


@njit(cache=True, inline="always")
def _tan_of(r, z):
    """Elevation tangent of half-plane point (r, z) seen from the eye (r >= 0)."""
    if r > 0.0:
        return z / r
    return -math.inf if z < 0.0 else math.inf


@njit(cache=True, inline="always")
def _param_at(h, v, seg):
    """Where (0..1) along the segment (r1, z1, r2, z2) the ray of direction (h, v) meets it."""
    r1, z1, r2, z2 = seg
    dr = r2 - r1
    dz = z2 - z1
    den = dr * v - dz * h
    # Guard: a ray parallel to the segment (den ~ 0) meets it along its length; its middle
    # stands for it. The threshold scales with |direction| |segment|.
    scale = (abs(dr) + abs(dz)) * (abs(h) + abs(v))
    t = (z1 * h - r1 * v) / den if abs(den) > 1e-12 * scale else 0.5
    return min(max(t, 0.0), 1.0)


@njit(cache=True, inline="always")
def _inverse_range_at(h, v, seg):
    """1 / distance (1/metres) from the eye to where the ray of direction (h, v) meets the
    segment (r1, z1, r2, z2)."""
    r1, z1, r2, z2 = seg
    t = _param_at(h, v, seg)
    rr = r1 + t * (r2 - r1)
    zz = z1 + t * (z2 - z1)
    # Guard: the eye is kept above the surface (fan.py), so the distance is > 0.
    return 1.0 / max(math.sqrt(rr * rr + zz * zz), 1e-6)


@njit(cache=True, inline="always")
def _inverse_range_on_line(h, v, seg):
    """Signed 1 / distance along the ray of direction (h, v) to the line through the segment
    (r1, z1, r2, z2): (n . u) / (n . p1) with n normal to the line and u the ray's unit
    direction; negative if the ray meets the line behind the eye. The far end's inverse range
    where the line passes through the eye (n . p1 ~ 0)."""
    r1, z1, r2, z2 = seg
    nr = -(z2 - z1)
    nz = r2 - r1
    c = nr * r1 + nz * z1
    if abs(c) <= 1e-9 * (abs(nr) + abs(nz)) * (abs(r1) + abs(z1) + 1.0):
        return 1.0 / max(math.sqrt(r2 * r2 + z2 * z2), 1e-6)
    norm = math.sqrt(h * h + v * v)  # guard: _direction never returns (0, 0)
    return (nr * h + nz * v) / (c * norm)  # guard: |c| is not ~0


@njit(cache=True, inline="always")
def _colour_at(colours, paint, t):
    """Linear colour at parameter t of a segment painted by paint."""
    if paint.page < 0:
        return paint.rgb
    u = paint.u0 + t * (paint.u1 - paint.u0)
    v = paint.v0 + t * (paint.v1 - paint.v0)
    return _voxel_rgb(colours, paint.page, paint.vy, paint.vx, u, v)


@borrowing
def _finish_step(st, ln, air, buf, colours):
    """Keep the current step's terrain in the line's buffer from the accumulators in st (its
    colour goes through the land's detail, the haze and the fog once the line is cast:
    _through_air), and start the next step."""
    row = int(st[_ROW])
    w = st[_AW]
    ir = st[_IR]
    h, v = _direction(ln, row + 0.5)
    rng = 0.0
    ground = 0.0
    graze = 1.0
    if w > 0.0:
        seg = (st[_R1], st[_Z1], st[_R2], st[_Z2])
        if ir == 0.0:
            # The centre ray is not on the surface (the step's surface ends below it): the
            # signed inverse range along it to the last segment's line continued stands for
            # the step (negative where it would meet the line behind the eye), so a partly
            # covered pixel at an edge or crest interpolates as well as whole ones.
            ir = _inverse_range_on_line(h, v, seg)
        # The surface's range at the step's centre, or that of the last segment's far end.
        rng = 1.0 / ir if ir > 0.0 else math.sqrt(seg[2] * seg[2] + seg[3] * seg[3])
        if st[_DETAIL] != 0.0 and st[_GROUND] != 0.0 and ir > 0.0:
            ground = st[_GROUND]
            nr = seg[1] - seg[3]
            nz = seg[2] - seg[0]
            nn = math.sqrt(nr * nr + nz * nz)
            # guard: _direction never returns (0, 0); nn > 0 checked.
            graze = abs(nr * h + nz * v) / (nn * math.sqrt(h * h + v * v)) if nn > 0.0 else 1.0
    buf[row, _B_R] = st[_AR]
    buf[row, _B_G] = st[_AG]
    buf[row, _B_B] = st[_AB]
    buf[row, _B_A] = min(w, 1.0)
    # 1/z = |(tx, ty, 1)| / range: affine across a plane in screen space, so the pixels
    # between two lines and the samples between pixels interpolate it.
    buf[row, _B_IZ] = math.sqrt(h * h + v * v) * ir
    buf[row, _B_RANGE] = rng
    buf[row, _B_GROUND] = ground
    buf[row, _B_SLOPE] = st[_SLOPE]
    buf[row, _B_GRAZE] = graze
    buf[row, _B_FOREST] = st[_AC] / w if w > 0.0 else 0.0
    st[_AC] = 0.0
    st[_ROW] = row + 1
    st[_AR] = 0.0
    st[_AG] = 0.0
    st[_AB] = 0.0
    st[_AW] = 0.0
    st[_IR] = 0.0


@borrowing
def _through_air(ln, buf, lo, hi, air, detail, pages, st):
    """The cast line's steps lo .. hi - 1 as they show: each step's colour with the land's
    detail where it ends on ground, then through the haze and the fog, in place. Once a line,
    after its cast: the per-segment calls never carry the detail's arrays."""
    hazy = air[0] != 0.0
    foggy = air[F_ON] != 0.0
    for row in range(lo, hi):
        w = buf[row, _B_A]
        if w <= 0.0:
            continue
        r = buf[row, _B_R]
        g = buf[row, _B_G]
        b = buf[row, _B_B]
        h, v = _direction(ln, row + 0.5)
        rng = buf[row, _B_RANGE]
        if buf[row, _B_GROUND] != 0.0:
            r, g, b = _detail(ln, detail, pages, st, h, v, rng, buf[row, _B_GROUND], buf[row, _B_SLOPE],
                              buf[row, _B_GRAZE], buf[row, _B_FOREST], w, r, g, b)
        if hazy or foggy:
            norm = math.sqrt(h * h + v * v)
            sn = v / norm  # guard: _direction never returns (0, 0)
            if hazy:
                hz = haze_amount(air, rng, sn)
                # Premultiplied: the haze covers the share w of the pixel the terrain covers.
                r = r * (1.0 - hz) + air[3] * hz * w
                g = g * (1.0 - hz) + air[4] * hz * w
                b = b * (1.0 - hz) + air[5] * hz * w
            if foggy:
                cos_ax = ln.axh * h / norm + air[F_WORLD_AXIS + 2] * sn
                t = math.exp(-fog_depth(air, rng, cos_ax))
                r = t * r + (1.0 - t) * air[F_RGB] * w
                g = t * g + (1.0 - t) * air[F_RGB + 1] * w
                b = t * b + (1.0 - t) * air[F_RGB + 2] * w
        buf[row, _B_R] = r
        buf[row, _B_G] = g
        buf[row, _B_B] = b


@njit(cache=True, inline="always")
def _hash(i, j):
    """A 32-bit hash of two integers (multiply-xorshift mixing, as in MurmurHash3's finaliser):
    neighbouring cells get unrelated values."""
    h = (i * 0x9E3779B1 + j * 0x85EBCA77 + 0x165667B1) & 0xFFFFFFFF
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & 0xFFFFFFFF
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & 0xFFFFFFFF
    h ^= h >> 16
    return h


@njit(cache=True, inline="always")
def _band_cover(d, half, fp):
    """Share of a footprint fp wide, centred at signed distance d from a line, that a band
    within half of the line covers (a box filter of the band: a sharp edge near the eye, the
    band's mean share far away)."""
    lo = max(d - 0.5 * fp, -half)
    hi = min(d + 0.5 * fp, half)
    return max(hi - lo, 0.0) / fp  # guard: fp > 0 (the caller's footprint floor)


@njit(cache=True, inline="always")
def _level0_z(pages, x, y):
    """The level-0 surface height at database-relative (x, y), metres; NaN off the level or
    where its page is missing."""
    d = pages.spacing
    ix = int(math.floor(x / d))  # guard: spacing > 0
    iy = int(math.floor(y / d))
    if ix < 0 or iy < 0 or ix >= pages.level_nx[0] or iy >= pages.level_ny[0]:
        return math.nan
    page = _page_of(pages, 0, ix, iy)
    if page < 0:
        return math.nan
    mask = (1 << pages.log2_page) - 1
    return _corner_z(pages, page, iy & mask, ix & mask, x / d - ix, y / d - iy)


@njit(cache=True, inline="always")
def _flat_cell(pages, x0, y0, fw, fh, max_slope):
    """Whether the field cell of database-relative corner (x0, y0), fw x fh metres, is gentle
    enough to plough: its corners within max_slope (tangent) of its centre's height, along
    the half-diagonal."""
    zc = _level0_z(pages, x0 + 0.5 * fw, y0 + 0.5 * fh)
    if math.isnan(zc):
        return False
    reach = max_slope * 0.5 * math.sqrt(fw * fw + fh * fh)
    for q in range(4):
        z = _level0_z(pages, x0 + (q & 1) * fw, y0 + (q >> 1) * fh)
        if not abs(z - zc) <= reach:  # NaN (off the database) is not flat either
            return False
    return True


@njit(cache=True, inline="always")
def _shows(t, c, fp, across):
    """Whether any texture of class row c's code still shows at a footprint whose larger side
    is fp and whose side across the line is across (metres): below one of its fade-outs."""
    for k in range(3):
        o = c + T_CLASS_FADE + 2 * k
        if fp < t[o] and across < t[o + 1]:
            return True
    return False


# Inlined into _through_air, its one caller.
@njit(cache=True, inline="always")
def _detail(ln, detail, pages, st, h, v, rng, ground, slope, graze, forest, w, r, g, b):
    """The step's premultiplied colour (r, g, b), coverage w, with the land's detail where its
    centre ray meets the ground (docs/terrain.md "Detail"): the land class's colour and texture
    code over the relief colour, fields and their hedges, and the airfield pads' grass feathered
    into it.

    The texture's footprint is the step's: across the line, the step's angle at the range
    1/ir; along it, that stretched by the ground's slant to the ray (the segment the step ends
    on). Beyond the range where a class's texture code has faded out entirely (its fade-out
    footprint, TerrainDetail.table), no texture is read.
    """
    t = detail.table
    # The store alone goes into the samplers' calls (by value, at every read).
    store = TextureArrays(detail.texels, detail.level, detail.levels, detail.finest)
    norm2 = h * h + v * v  # guard: _direction never returns (0, 0)
    norm = math.sqrt(norm2)
    rc = rng * h / norm
    x = t[T_ORIGIN] + ln.ex + rc * ln.dx
    y = t[T_ORIGIN + 1] + ln.ey + rc * ln.dy
    # The step's angle: the directions at s and s + 1 are affine in s, so their cross product
    # is the constant h0 z1 - z0 h1; over |d|^2 at the step's centre it is the angle's sine.
    across = max(rng * abs(ln.h0 * ln.z1 - ln.z0 * ln.h1) / norm2, 1e-6)  # floor: a footprint
    along = across / max(graze, 1e-3)  # guard: a ray along the ground
    fp = max(along, across)
    canopy = ground >= _CANOPY
    # The pads: weight 1 inside, smoothstep down to 0 over the blend outside (not on trees).
    wp = 0.0
    for k in range(0 if canopy else int(t[T_PADS_N])):
        o = int(t[T_PADS_AT]) + 5 * k
        ddx = max(max(t[o] - x, x - t[o + 2]), 0.0)
        ddy = max(max(t[o + 1] - y, y - t[o + 3]), 0.0)
        if ddx == 0.0 and ddy == 0.0:
            wp = 1.0
            break
        if ddx < t[o + 4] and ddy < t[o + 4]:
            d = math.sqrt(ddx * ddx + ddy * ddy)
            if d < t[o + 4]:
                q = 1.0 - d / t[o + 4]  # guard: d < blend means blend > 0
                wp = max(wp, q * q * (3.0 - 2.0 * q))
    gr = r
    gg = g
    gb = b
    if wp < 1.0:
        c = T_CLASSES + GRASS * T_CLASS_N
        tr = t[c + 1]
        tg = t[c + 2]
        tb = t[c + 3]
        hr = 1.0
        hg = 1.0
        hb = 1.0
        # The texture plane: world (x, y), and the pixel's sides along and across the line.
        u = x
        vv = y
        du = (ln.dx * along, ln.dy * along, -ln.dy * across, ln.dx * across)
        if canopy:
            # A forest's canopy and sides: its code's texture over the pattern's colour (crowns
            # and gaps, foliage and trunks; its mix is 0). A side is read in (x + y, height): it
            # faces along x or y, so the sum runs along it; along the line the height changes.
            c = T_CLASSES + FOREST * T_CLASS_N
            if ground != _CANOPY:
                u = x + y
                vv = t[T_ORIGIN + 2] + ln.ez + rng * v / norm
                du = (0.0, along, across, 0.0)
        elif slope > t[T_ROCK_SLOPE]:
            c = T_CLASSES + ROCK * T_CLASS_N
            tr = t[c + 1]
            tg = t[c + 2]
            tb = t[c + 3]
        elif t[T_FIELDS_N] > 0.0:
            # Fields: cells of the land in columns T_FIELD_W wide, each column's rows shifted by
            # its own offset (a patchwork, not a chequerboard); a cell is a field for a share
            # T_FIELD_SHARE of those gentle enough to plough (_flat_cell), of a kind and a row
            # direction its hash picks. Whole cells, so that fields are rectangles with
            # hedges round them, not the voxels of a slope threshold.
            fw = t[T_FIELD_W]
            fh = t[T_FIELD_H]
            ci = int(math.floor(x / fw))  # guard: the cell sizes are > 0 (terrain.py)
            shift = (_hash(ci, 7919) & 0xFFFF) * (1.0 / 65536.0) * fh
            cj = int(math.floor((y + shift) / fh))
            hsh = _hash(ci, cj)
            if st[_CELL_FIELD] < 0.0 or st[_CELL_I] != ci or st[_CELL_J] != cj:
                # A line crosses a cell in many steps: its verdict is kept for the next.
                st[_CELL_I] = ci
                st[_CELL_J] = cj
                field = (hsh & 0xFFFF) * (1.0 / 65536.0) < t[T_FIELD_SHARE] and _flat_cell(
                    pages, ci * fw - t[T_ORIGIN], cj * fh - shift - t[T_ORIGIN + 1], fw, fh, t[T_FIELD_SLOPE])
                st[_CELL_FIELD] = 1.0 if field else 0.0
            if st[_CELL_FIELD] > 0.0:
                c = T_CLASSES + FIELD * T_CLASS_N
                f = T_FIELDS + 3 * ((hsh >> 16) % int(t[T_FIELDS_N]))
                tr = t[f]
                tg = t[f + 1]
                tb = t[f + 2]
                if (hsh >> 24) & 1:
                    # Rows along x instead of y: the code's u and v swapped.
                    u = y
                    vv = x
                    du = (du[2], du[3], du[0], du[1])
                # Hedges: a band along the cell's edges, filtered to the footprint.
                ex_ = min(x - ci * fw, (ci + 1) * fw - x)
                ey_ = min(y + shift - cj * fh, (cj + 1) * fh - (y + shift))
                cover = max(_band_cover(ex_, t[T_HEDGE_M], fp), _band_cover(ey_, t[T_HEDGE_M], fp))
                hr = 1.0 + cover * (t[T_HEDGE] - 1.0)
                hg = 1.0 + cover * (t[T_HEDGE + 1] - 1.0)
                hb = 1.0 + cover * (t[T_HEDGE + 2] - 1.0)
        mr = 1.0
        mg = 1.0
        mb = 1.0
        look = int(t[c])
        if look >= 0 and _shows(t, c, fp, across):
            # One call site for every class: each inlined copy costs compile time.
            mr, mg, mb = texture_modulation(store, detail.looks[look], detail.texture_filter, u, vv,
                                            du[0], du[1], du[2], du[3])
            if canopy:
                # The forest's share of the step alone: at a stand's edge the rest is meadow,
                # which the canopy's (strong) modulation would light up as a bright rim.
                mr = 1.0 + forest * (mr - 1.0)
                mg = 1.0 + forest * (mg - 1.0)
                mb = 1.0 + forest * (mb - 1.0)
        # The class's colour takes the share mix of the relief colour's hue, keeping its
        # brightness (its hill-shading) relative to the relief's mean.
        mix = t[c + 4]
        if canopy:
            # A forest takes none of the class colours (its mix is 0); the meadow's share of a
            # step at a stand's foot takes the meadow's (the relief's own hue showed there as
            # a rim).
            mix = (1.0 - forest) * t[T_CLASSES + GRASS * T_CLASS_N + 4]
        k = (0.2126 * r + 0.7152 * g + 0.0722 * b) * mix / t[T_LUM_REF]  # guard: terrain.py keeps it > 0
        gr = ((1.0 - mix) * r + k * tr) * hr * mr
        gg = ((1.0 - mix) * g + k * tg) * hg * mg
        gb = ((1.0 - mix) * b + k * tb) * hb * mb
    if wp > 0.0:
        c = T_CLASSES + PAD * T_CLASS_N
        mr = 1.0
        mg = 1.0
        mb = 1.0
        look = int(t[c])
        # Inside a pad the scene's faces cover (the airfield's grass), the terrain is hidden:
        # its colour only, no texture read.
        if look >= 0 and not (wp == 1.0 and t[T_PAD_COVERED] != 0.0) and _shows(t, c, fp, across):
            mr, mg, mb = texture_modulation(store, detail.looks[look], detail.texture_filter, x, y,
                                            ln.dx * along, ln.dy * along, -ln.dy * across, ln.dx * across)
        # The pad's lit colour, premultiplied by the step's coverage like r, g, b.
        gr = (1.0 - wp) * gr + wp * w * t[c + 1] * mr
        gg = (1.0 - wp) * gg + wp * w * t[c + 2] * mg
        gb = (1.0 - wp) * gb + wp * w * t[c + 3] * mb
    return gr, gg, gb


@borrowing
def _emit(st, ln, air, buf, colours, a, b, tb, seg, paint, c_a, c_b):
    """Integrate the visible part a < s < b (positions along the line) of one surface segment
    into the line's steps; tb: the elevation tangent at b, the line's new horizon.

    Each step receives the share of its length on the screen the part covers
    (JP H07-76990's colour integration by the fraction of the pixel a voxel covers: no jagged
    silhouettes), with the mean of the surface colour at the ends of its share: the colour is
    paint's where the step's boundary ray meets the segment, so a voxel spanning many pixels
    is coloured like the surface, not stretched. The segment's end points seg = (r1, z1, r2,
    z2) (ground range and height relative to the eye, metres) give the exact range at a step's
    centre. c_a, c_b: the colours at a and at b, already known to the caller.
    """
    row = int(st[_ROW])
    n = ln.n
    while a < b and row < n:
        top = row + 1.0
        if a >= top:
            # A gap below the part (a horizon rounded up): the step keeps what it has.
            _finish_step(st, ln, air, buf, colours)
            row += 1
            continue
        st[_R1] = seg[0]
        st[_Z1] = seg[1]
        st[_R2] = seg[2]
        st[_Z2] = seg[3]
        if b <= top:
            e = b
            c_e = c_b
        else:
            e = top
            hh, vv = _direction(ln, top)
            c_e = _colour_at(colours, paint, _param_at(hh, vv, seg))
        w = e - a
        st[_AR] += w * 0.5 * (c_a[0] + c_e[0])
        st[_AG] += w * 0.5 * (c_a[1] + c_e[1])
        st[_AB] += w * 0.5 * (c_a[2] + c_e[2])
        st[_AW] += w
        if st[_GROUND] >= _CANOPY:
            st[_AC] += w
        centre = top - 0.5
        if a <= centre < e:
            hh, vv = _direction(ln, centre)
            st[_IR] = _inverse_range_at(hh, vv, seg)
        if e >= top:
            _finish_step(st, ln, air, buf, colours)
            row += 1
        # The rest of the part starts at e with the colour there.
        a = e
        c_a = c_e
    if tb > st[_TANMAX]:
        st[_TANMAX] = tb
        st[_SMAX] = b


@njit(cache=True, inline="always")
def _dda_axis(i, d, e, direction, inv):
    """One axis of the grid walk from cell i (width d) along e + r * direction: the step, the
    ground range between crossings and the range of the next crossing (inf if parallel)."""
    if direction > 0.0:
        return 1, d * inv, ((i + 1) * d - e) * inv
    if direction < 0.0:
        return -1, -d * inv, (i * d - e) * inv
    return 0, math.inf, math.inf


@njit(cache=True, inline="always")
def _slab(e, d, extent, r_lo, r_hi):
    """Clip [r_lo, r_hi] of the line e + r d to the slab [0, extent] (r_lo >= r_hi: missed)."""
    if abs(d) > 1e-15:
        t1 = (0.0 - e) / d  # guard: |d| > 1e-15
        t2 = (extent - e) / d
        return max(r_lo, min(t1, t2)), min(r_hi, max(t1, t2))
    if 0.0 <= e <= extent:
        return r_lo, r_hi
    return 0.0, -1.0  # parallel to the slab and outside it


@njit(cache=True, inline="always")
def ground_ray_span(ex, ey, dx, dy, extent_x, extent_y, r_lo, r_hi):
    """The part [r_lo, r_hi] of the ground ray (ex, ey) + r (dx, dy), r >= 0, inside the
    rectangle [0, extent_x] x [0, extent_y] (slab method; metres); r_lo >= r_hi when it
    misses. Shared with the cloud scan (_cloud_kernels)."""
    r_lo, r_hi = _slab(ex, dx, extent_x, max(r_lo, 0.0), r_hi)
    return _slab(ey, dy, extent_y, r_lo, r_hi)


@njit(cache=True, inline="always")
def _corner_z(pages, page, vy, vx, u, v):
    """Height of voxel (vy, vx) of page at local point (u, v), metres above the origin."""
    z0 = pages.z[page, vy, vx, 0]
    z1 = pages.z[page, vy, vx, 1]
    z2 = pages.z[page, vy, vx, 2]
    z3 = pages.z[page, vy, vx, 3]
    return (1.0 - v) * ((1.0 - u) * z0 + u * z1) + v * ((1.0 - u) * z2 + u * z3)


@njit(cache=True, inline="always")
def _corner_rgb(colours, page, vy, vx, u, v, ch):
    """Linear colour channel ch of voxel (vy, vx) of page at local point (u, v)."""
    lut = colours.lut
    c0 = lut[colours.rgb[page, vy, vx, 0, ch]]
    c1 = lut[colours.rgb[page, vy, vx, 1, ch]]
    c2 = lut[colours.rgb[page, vy, vx, 2, ch]]
    c3 = lut[colours.rgb[page, vy, vx, 3, ch]]
    return (1.0 - v) * ((1.0 - u) * c0 + u * c1) + v * ((1.0 - u) * c2 + u * c3)


@njit(cache=True, inline="always")
def _voxel_rgb(colours, page, vy, vx, u, v):
    """Linear (r, g, b) of voxel (vy, vx) of page at local point (u, v)."""
    return (_corner_rgb(colours, page, vy, vx, u, v, 0),
            _corner_rgb(colours, page, vy, vx, u, v, 1),
            _corner_rgb(colours, page, vy, vx, u, v, 2))


@njit(cache=True, inline="always")
def _page_key(qx, qy, d, log2_page, pages_x):
    """Identity of the page of a level (voxel width d, pages_x pages per row) holding ground
    point (qx, qy) (database-relative metres; points off the grid give off-grid keys)."""
    return (int(math.floor(qy / d)) >> log2_page) * pages_x + (int(math.floor(qx / d)) >> log2_page)


@njit(cache=True, inline="always")
def _page_of(pages, level, ix, iy):
    """The page holding voxel (ix, iy) of a level, or -1 (off the level, or missing)."""
    px = ix >> pages.log2_page
    py = iy >> pages.log2_page
    if px < 0 or py < 0 or px >= pages.pages_x[level] or py >= pages.pages_y[level]:
        return -1
    return pages.page_table[pages.table_offset[level] + py * pages.pages_x[level] + px]


@njit(cache=True, parallel=True)
def cast_kernel(pages, detail, fan, limits, air, frame, sky, out, aux, visits, threads):
    """The terrain of every pixel: one radial scan per line of the fan (JP H07-76990's column
    scan along the screen line of one vertical half-plane), emitted straight into the pixels
    the line owns, over the sky or earth plane (sky: _sky_kernels.SkyTable).

    The ground line is walked outward from the start point, one grid line at a time (an exact
    2-D DDA on the current level's grid, so no voxel is missed). Inside a voxel the surface is
    the bilinear interpolation of its corners. A point's elevation tangent z / r against the
    highest seen so far decides occlusion; what rises above it covers the steps (pixels) it
    spans (_emit).

    Level: the coarsest whose voxel is at most 2**bias projected pixels wide at the slant
    range, i.e. one level coarser each time the range doubles (limits.r_switch); a missing
    page falls back to the next coarser level.

    Args:
        pages: the terrain database (VoxelPages).
        detail: the land's detail (TerrainDetail; detail.on False: none).
        fan: the lines (LineFan, fan.py).
        limits: the eye (database-relative) and the scan's ranges (ScanLimits).
        air: the frame's air array (haze, then fog; contract.py).
        frame: the frame's constants (FrameConstants).
        sky: the sky and earth plane by elevation (SkyTable).
        out: the Background's arrays (BackgroundArrays: rgb and range_m are filled here).
        aux: per-pixel coverage and 1/z for the per-sample depth (CastPixels).
        visits: (lines,) int64 voxels visited by each line.
        threads: numba.get_num_threads() (jit.lanes).
    """
    n_lines = fan.aim.shape[0]
    # Blocks of lines from a queue shared by the threads (jit.lanes): sky lines and ground
    # lines differ in cost, so whichever thread is free casts the next block. A lane casts a
    # block's lines in order and the line on either side of the block, keeping three lines
    # at a time: a pixel is written once the lines on both sides of its centre are cast.
    block = _block_lines(n_lines, threads)
    n_blocks = (n_lines + block - 1) // block
    n_lanes = lanes(threads, n_blocks)
    size = max(frame.width, frame.height) + 1
    queue = new_queue()
    for _lane in prange(n_lanes):
        st = np.empty(_STATE)
        own = np.empty((3, size, 2), np.int64)
        buf = np.empty((3, size, _BUF))
        meta = np.empty((3, _META))
        while True:
            blk = claim(queue)
            if blk >= n_blocks:
                break
            start = blk * block
            end = min(start + block, n_lines)
            lo = start - 1 if fan.prev[start] else start
            hi = end if fan.next[end - 1] else end - 1
            _own(lo, fan, frame, own[lo % 3], meta[lo % 3])
            for j in range(lo, hi + 1):
                if j < hi:
                    _own(j + 1, fan, frame, own[(j + 1) % 3], meta[(j + 1) % 3])
                # Walked over the steps it or a neighbour owns: a neighbour's pixels there
                # interpolate it.
                k_lo = meta[j % 3, _M_FIRST]
                k_hi = meta[j % 3, _M_LAST]
                for nb in (j - 1, j + 1):
                    if lo <= nb <= hi and (fan.prev[j] if nb < j else fan.next[j]):
                        f = meta[nb % 3, _M_FIRST]
                        if f >= 0.0:
                            k_lo = f if k_lo < 0.0 else min(k_lo, f)
                            k_hi = max(k_hi, meta[nb % 3, _M_LAST])
                used = _line(j, int(k_lo), int(k_hi), st, buf[j % 3], meta[j % 3], pages, detail, fan,
                             limits, air, frame)
                if start <= j < end:
                    visits[j] = used
                if start <= j - 1 < end:
                    _write(j - 1, fan, own, buf, meta, frame, air, sky, out, aux)
            if hi == end - 1:
                _write(end - 1, fan, own, buf, meta, frame, air, sky, out, aux)


@borrowing
def _own(i, fan, frame, own, meta):
    """Line i's steps' pixels into own and their range into its record meta (own_steps)."""
    first_k, last_k, n = own_steps(fan, i, frame.width, frame.height, own)
    meta[_M_FIRST] = first_k
    meta[_M_LAST] = last_k
    meta[_M_N] = n


@borrowing
def _line(i, lo_k, hi_k, st, buf, meta, pages, detail, fan, limits, air, frame):
    """Cast line i of cast_kernel over its steps lo_k .. hi_k into its buffer buf, with st as
    its scan state, and note the steps walked in its record meta; returns the voxels
    visited."""
    meta[_M_LO] = lo_k
    meta[_M_HI] = hi_k
    n = int(meta[_M_N])
    if lo_k < 0:
        return 0
    wedge = fan.wedge[i]
    qa = fan.qa[wedge]
    slope = fan.slope[i]
    aim = fan.aim[i]
    # The line's rays: screen point (p, q) of the wedge at s (q = qa - m at step m's centre),
    # its eye ray (tx, ty, 1) and world direction, all affine in s.
    if fan.nadir:
        q0 = qa - (n - 1) - 0.5
        dq_ds = 1.0
    else:
        q0 = qa + 0.5
        dq_ds = -1.0
    wa = _world_at(fan, frame, wedge, aim + (q0 - qa) * slope, q0)
    wb = _world_at(fan, frame, wedge, aim + (q0 + dq_ds - qa) * slope, q0 + dq_ds)
    sphi = fan.sin_phi[i]
    cphi = fan.cos_phi[i]
    h0 = wa[0] * sphi + wa[1] * cphi
    z0 = wa[2]
    h1 = (wb[0] * sphi + wb[1] * cphi) - h0
    z1 = wb[2] - z0
    h_hi = h0 + h1 * n
    # A tiny horizontal component relative to the ray is the vanishing point itself.
    tan_lo = (z0 / h0) if h0 > 1e-12 * (abs(h0) + abs(z0)) else -math.inf
    z_hi = z0 + z1 * n
    tan_hi = (z_hi / h_hi) if h_hi > 1e-12 * (abs(h_hi) + abs(z_hi)) else math.inf
    axh = air[F_WORLD_AXIS] * sphi + air[F_WORLD_AXIS + 1] * cphi
    ln = _Line(h0, h1, z0, z1, n, tan_lo, tan_hi, axh, sphi, cphi, limits.eye[0], limits.eye[1], limits.eye[2])
    colours = _Colours(pages.rgb, pages.lut)
    for q in range(_STATE):
        st[q] = 0.0
    st[_ROW] = lo_k
    st[_DETAIL] = 1.0 if detail.on else 0.0
    hh, vv = _direction(ln, float(lo_k))
    tan_start = _tan_of(hh, vv) if lo_k > 0 else tan_lo
    st[_TANMAX] = tan_start
    st[_SMAX] = float(lo_k)
    used = _walk(st, ln, buf, hi_k, sphi, cphi, pages, colours, limits, tan_start, air)
    # The step the scan stopped in holds what covered it so far (a silhouette).
    if int(st[_ROW]) <= hi_k and st[_AW] > 0.0:
        _finish_step(st, ln, air, buf, colours)
    st[_CELL_FIELD] = -1.0  # no field cell looked at yet on this line
    _through_air(ln, buf, lo_k, int(st[_ROW]), air, detail, pages, st)
    # Steps the scan never reached see no terrain. The first of them keeps the last surface's
    # depth continued (with no coverage): the pixels and samples beside it interpolate
    # between it and the last covered one, exact for planar ground up to the edge.
    row = int(st[_ROW])
    cont = st[_R1] != 0.0 or st[_R2] != 0.0
    for k in range(row, hi_k + 1):
        for c in range(_BUF):
            buf[k, c] = 0.0
        if cont and k == row:
            hh, vv = _direction(ln, k + 0.5)
            buf[k, _B_IZ] = math.sqrt(hh * hh + vv * vv) * _inverse_range_on_line(
                hh, vv, (st[_R1], st[_Z1], st[_R2], st[_Z2]))
    return used


@borrowing
def _write(i, fan, own, buf, meta, frame, air, sky, out, aux):
    """Line i's pixels (cast_kernel): each between the two lines on either side of its
    centre (line i and a neighbour, both cast), interpolated linearly across them (to the
    pixel's own azimuth: its colour, coverage and 1/z, which is affine across a plane), over
    the sky or earth plane at its own centre."""
    a = i % 3
    first_k = int(meta[a, _M_FIRST])
    if first_k < 0:
        return
    last_k = int(meta[a, _M_LAST])
    n = int(meta[a, _M_N])
    wedge = fan.wedge[i]
    aim = fan.aim[i]
    slope = fan.slope[i]
    mapping = frame.mapping
    dz = frame.dz_row
    for k in range(first_k, last_k + 1):
        x = own[a, k, 0]
        if x < 0:
            continue
        y = own[a, k, 1]
        m = (n - 1 - k) if fan.nadir else k
        p = aim - m * slope
        centre = (x if wedge <= DOWN else y) + 0.5
        r = buf[a, k, _B_R]
        g = buf[a, k, _B_G]
        b = buf[a, k, _B_B]
        w = buf[a, k, _B_A]
        iz = buf[a, k, _B_IZ]
        # The neighbour on the other side of the centre, if that side has one.
        j = -1
        if centre < p and fan.prev[i]:
            j = i - 1
        elif centre > p and fan.next[i]:
            j = i + 1
        if j >= 0:
            c = j % 3
            if meta[c, _M_LO] <= k <= meta[c, _M_HI]:
                pj = fan.aim[j] - m * fan.slope[j]
                # Guard: the neighbour lies on the other side of the centre, so pj != p.
                t = (centre - p) / (pj - p)
                r += t * (buf[c, k, _B_R] - r)
                g += t * (buf[c, k, _B_G] - g)
                b += t * (buf[c, k, _B_B] - b)
                w += t * (buf[c, k, _B_A] - w)
                izj = buf[c, k, _B_IZ]
                # A line the terrain never reached at this step holds 0: the other's depth.
                if iz == 0.0:
                    iz = izj
                elif izj != 0.0:
                    iz += t * (izj - iz)
        tx = (x + 0.5 - mapping[1]) / mapping[0]  # guard: scales are nonzero
        ty = (y + 0.5 - mapping[3]) / mapping[2]
        norm = math.sqrt(tx * tx + ty * ty + 1.0)
        nearest = math.inf
        if w < 1.0:
            br, bg, bb, nearest = backdrop_along(frame, air, sky, x, y, norm,
                                                 dz[0] * tx + dz[1] * ty + dz[2])
            keep = 1.0 - w
            r += keep * br
            g += keep * bg
            b += keep * bb
        if w > 0.0 and iz > 0.0:
            nearest = min(nearest, norm / iz)  # guard: iz > 0
        out.rgb[y, x, 0] = r
        out.rgb[y, x, 1] = g
        out.rgb[y, x, 2] = b
        out.range_m[y, x] = nearest
        aux.pixels[y, x, 0] = w
        aux.pixels[y, x, 1] = iz


@borrowing
def own_steps(fan, i, width, height, own):
    """Which pixel each step of line i owns (fan.py): the pixel its point falls in, if the
    pixel's centre lies in the wedge and no neighbouring line's point in the pixel is nearer
    its centre;
    own[k] = (x, y) or (-1, .), for steps k in order of elevation (away from the vanishing
    point when it is the nadir's image). Returns the first and last step it owns (-1 if none)
    and its steps n."""
    wedge = fan.wedge[i]
    qa = fan.qa[wedge]
    vp = fan.vp[wedge]
    vq = fan.vq[wedge]
    vw = fan.vw
    nmaj = fan.nmajor[wedge]
    nmin = fan.nminor[wedge]
    aim = fan.aim[i]
    slope = fan.slope[i]
    has_prev = fan.prev[i]
    has_next = fan.next[i]
    p_prev = fan.aim[i - 1] if has_prev else 0.0
    s_prev = fan.slope[i - 1] if has_prev else 0.0
    p_next = fan.aim[i + 1] if has_next else 0.0
    s_next = fan.slope[i + 1] if has_next else 0.0
    strict = wedge >= LEFT  # LEFT and RIGHT: the column-stepped wedges
    # Steps m = 0, 1, ... from the aimed edge towards the vanishing point; the last is the
    # last whose pixel centres lie on the aimed side of it.
    last = nmaj - 1
    if vw > 0.0:
        last = min(last, int(math.floor(qa - vq / vw)))  # guard: vw > 0
    if last < 0:
        return -1, -1, 0
    n = last + 1
    first_k = -1
    last_k = -1
    for m in range(n):
        k = (n - 1 - m) if fan.nadir else m
        own[k, 0] = -1
        q = qa - m
        p = aim - m * slope
        minor = int(math.floor(p))
        if minor < 0 or minor >= nmin:
            continue
        dp = (minor + 0.5) * vw - vp
        dq = q * vw - vq
        if strict:
            if not dq > abs(dp):
                continue
        elif not (dq >= abs(dp) and (dq > 0.0 or wedge == UP)):
            continue
        # Of the lines whose points fall in this pixel (neighbours in p, the lines sorted),
        # the nearest to its centre takes it: distances to the centre fall then rise along
        # the sorted lines, so the neighbours decide. Distances within _TIE of each other are
        # a tie, the lower line's (at V every line passes through one point, and rounding
        # would otherwise make several local nearest).
        d = abs(p - (minor + 0.5))
        if has_prev:
            pp = p_prev - m * s_prev
            if int(math.floor(pp)) == minor and abs(pp - (minor + 0.5)) <= d + _TIE:
                continue
        if has_next:
            pn = p_next - m * s_next
            if int(math.floor(pn)) == minor and abs(pn - (minor + 0.5)) < d - _TIE:
                continue
        if wedge == UP:
            x, y = minor, m
        elif wedge == DOWN:
            x, y = minor, height - 1 - m
        elif wedge == LEFT:
            x, y = m, minor
        else:
            x, y = width - 1 - m, minor
        own[k, 0] = x
        own[k, 1] = y
        if first_k < 0 or k < first_k:
            first_k = k
        if k > last_k:
            last_k = k
    return first_k, last_k, n


@njit(cache=True)
def ownership_counts(fan, width, height):
    """(height, width) int64 how many lines own each pixel: 1 everywhere (tests)."""
    counts = np.zeros((height, width), np.int64)
    size = max(width, height) + 1
    own = np.empty((size, 2), np.int64)
    for i in range(fan.aim.shape[0]):
        first_k, last_k, _ = own_steps(fan, i, width, height, own)
        for k in range(max(first_k, 0), last_k + 1):
            if own[k, 0] >= 0:
                counts[own[k, 1], own[k, 0]] += 1
    return counts


@borrowing
def _world_at(fan, frame, wedge, p, q):
    """World direction (unnormalised: eye ray (tx, ty, 1)) of the wedge's screen point (p, q)."""
    if wedge == UP:
        sx, sy = p, -q
    elif wedge == DOWN:
        sx, sy = p, q
    elif wedge == LEFT:
        sx, sy = -q, p
    else:
        sx, sy = q, p
    m = frame.mapping
    tx = (sx - m[1]) / m[0]  # guard: screen_mapping's scales are nonzero
    ty = (sy - m[3]) / m[2]
    r = frame.world_to_eye
    return (tx * r[0, 0] + ty * r[1, 0] + r[2, 0], tx * r[0, 1] + ty * r[1, 1] + r[2, 1],
            tx * r[0, 2] + ty * r[1, 2] + r[2, 2])


@borrowing
def _walk(st, ln, buf, last_k, dx, dy, pages, colours, limits, tan_lo, air):
    """Walk the line's ground line (direction (dx, dy), east and north) from the start point,
    emitting into its steps until the last it owns (last_k) is covered; returns the voxels
    visited."""
    ex = limits.eye[0]
    ey = limits.eye[1]
    ez = limits.eye[2]
    r_switch = limits.r_switch
    spacing = pages.spacing
    detail_on = st[_DETAIL] != 0.0
    log2_page = pages.log2_page
    pages_x = pages.pages_x
    level_nx = pages.level_nx
    level_ny = pages.level_ny
    levels = level_nx.shape[0]
    zrel_max = pages.z_max - ez  # highest surface point relative to the eye
    # Start: nothing nearer than where the lowest step's ray descends to the highest surface
    # point can reach above that step (JP H07-76990's column start point, made exact for
    # relief).
    r_lo = 0.0
    if zrel_max < 0.0:
        if tan_lo >= 0.0:
            return 0  # everything lies below the eye and the line looks level or up
        if tan_lo > -math.inf:
            r_lo = zrel_max / tan_lo  # guard: tan_lo < 0 here
    r_lo, r_hi = ground_ray_span(ex, ey, dx, dy, pages.extent_x, pages.extent_y, r_lo,
                                 limits.r_far)
    if r_lo >= r_hi:
        return 0

    visits = 0
    want = 0
    level = 0
    # The last voxel's exit elevation tangent and colour, valid while `cached`.
    cached = False
    t_out = 0.0
    c_out = (0.0, 0.0, 0.0)
    d_l = spacing
    r = r_lo
    z_prev = 0.0
    have_prev = False
    tan_max = st[_TANMAX]
    # Guard: a zero direction component never crosses that family of grid lines.
    inv_dx = 1.0 / dx if dx != 0.0 else 0.0
    inv_dy = 1.0 / dy if dy != 0.0 else 0.0
    mask = (1 << log2_page) - 1
    ix = 0
    iy = 0
    step_x = 0
    step_y = 0
    t_max_x = math.inf
    t_max_y = math.inf
    t_dx = math.inf
    t_dy = math.inf
    page = -1
    page_key = -1
    miss_key = -1  # in fallback: the wanted level's page that was missing
    inv_d = 1.0 / spacing
    restart = True
    while r < r_hi:
        if want < levels - 1 and r >= r_switch[want]:
            while want < levels - 1 and r >= r_switch[want]:
                want += 1
            restart = True
        if restart:
            # (Re)start the DDA at r: the wanted level, or the next coarser one that has this
            # area; the voxel is the one holding the point just past r.
            restart = False
            nudge = r + 1e-7 * spacing + 1e-12 * r
            qx = ex + nudge * dx
            qy = ey + nudge * dy
            level = want
            while True:
                d_l = spacing * (1 << level)
                ix = min(max(int(math.floor(qx / d_l)), 0), level_nx[level] - 1)
                iy = min(max(int(math.floor(qy / d_l)), 0), level_ny[level] - 1)
                page = _page_of(pages, level, ix, iy)
                if page >= 0 or level == levels - 1:
                    break
                level += 1
            if page < 0:
                break  # malformed table (the loader rejects it): stop rather than read garbage
            if level > want:
                miss_key = _page_key(qx, qy, spacing * (1 << want), log2_page, pages_x[want])
            inv_d = 1.0 / d_l  # guard: d_l >= spacing > 0
            page_key = (iy >> log2_page) * pages_x[level] + (ix >> log2_page)
            step_x, t_dx, t_max_x = _dda_axis(ix, d_l, ex, dx, inv_dx)
            step_y, t_dy, t_max_y = _dda_axis(iy, d_l, ey, dy, inv_dy)
        else:
            key = (iy >> log2_page) * pages_x[level] + (ix >> log2_page)
            if key != page_key:
                # A new page: look it up; if this level lacks it, or a finer wanted level may
                # have it again, restart the DDA on the right level.
                page_key = key
                page = _page_of(pages, level, ix, iy)
                if page < 0:
                    restart = True
                    continue
            if level > want:
                # Falling back: back to the wanted level as soon as the line leaves the page
                # it lacked (that level's page, not this coarser one's).
                nudge = r + 1e-7 * spacing + 1e-12 * r
                if _page_key(ex + nudge * dx, ey + nudge * dy, spacing * (1 << want), log2_page,
                             pages_x[want]) != miss_key:
                    restart = True
                    continue
        vx = ix & mask
        vy = iy & mask
        visits += 1
        r_next = min(min(t_max_x, t_max_y), r_hi)
        if r_next <= r:
            # Rounding at a restart can leave the first exit a hair behind r: step past it.
            r_next = r
        # Entry and exit points of this voxel, local coordinates clamped against rounding.
        u0 = min(max((ex + r * dx) * inv_d - ix, 0.0), 1.0)
        v0 = min(max((ey + r * dy) * inv_d - iy, 0.0), 1.0)
        u1 = min(max((ex + r_next * dx) * inv_d - ix, 0.0), 1.0)
        v1 = min(max((ey + r_next * dy) * inv_d - iy, 0.0), 1.0)
        z_in = _corner_z(pages, page, vy, vx, u0, v0) - ez
        if not have_prev:
            # First point of the line. Entering the database from outside, the terrain is a
            # solid: its edge shows as a wall (skirt) down from the surface, not as a gap.
            have_prev = True
            z_prev = z_in
            if z_in > r * tan_max:
                _wall(st, ln, air, buf, colours, r, z_in - _SKIRT_M,
                      z_in, _voxel_rgb(colours, page, vy, vx, u0, v0), 0.0)
                tan_max = st[_TANMAX]
        elif abs(z_in - z_prev) > _WALL_DZ:
            cached = False  # the surface jumps here: nothing of the last voxel carries over
            if z_in > z_prev and z_in > r * tan_max:
                # A step up between voxels (a cliff, a building edge): a vertical wall at r.
                _wall(st, ln, air, buf, colours, r, z_prev, z_in,
                      _voxel_rgb(colours, page, vy, vx, u0, v0), 0.0)
                tan_max = st[_TANMAX]
        k = pages.pattern[page, vy, vx] if level == 0 else 0
        if k > 0:
            # A vertical pattern (JP H07-76990's pattern insertion): its bands stacked as a
            # wall at the voxel's near side, then its top across the voxel.
            cached = False
            k -= 1
            zc = pages.z[page, vy, vx]
            top = z_in
            for q in range(4):
                top = max(top, zc[q] - ez)
            grow = 1.0
            if limits.tree_end > 0.0 and pages.pat_canopy[k]:
                # Near the eye a forest is polygon trees (scene/forest.py): the block rises
                # from the ground to its height across the cross-fade, as the trees fade out.
                # The slant distance to the voxel's centre, as the planting takes it.
                cx = (ix + 0.5) * spacing - ex
                cy = (iy + 0.5) * spacing - ey
                cz = 0.25 * (zc[0] + zc[1] + zc[2] + zc[3]) - ez
                grow = _growth(math.sqrt(cx * cx + cy * cy + cz * cz), limits.tree_start, limits.tree_end)
            z_out = top
            if grow < 1.0:
                z_out = _corner_z(pages, page, vy, vx, u1, v1) - ez
            lo = z_in
            # A stand's side is foliage and trunks, not a painted wall: the forest's detail.
            side = _CANOPY_SIDE if pages.pat_canopy[k] else 0.0
            for band in range(pages.pat_bands[k]):
                hi = z_in + grow * (top + pages.pat_top[k, band] - z_in)
                if hi > lo and hi > r * tan_max:
                    _wall(st, ln, air, buf, colours, r, lo, hi,
                          _rgb64(pages.pat_rgb[k, band]), side)
                    tan_max = st[_TANMAX]
                lo = hi
            last = pages.pat_bands[k] - 1
            c_top = _rgb64(pages.pat_rgb[k, last])
            # The top: flat at full height; while the block rises, between the ground and it.
            far = z_out + grow * (top + pages.pat_top[k, last] - z_out)
            if lo > r * tan_max or far > r_next * tan_max:
                # A tree's canopy takes the forest's detail; a roof none.
                st[_GROUND] = _CANOPY if pages.pat_canopy[k] else 0.0
                _surface(st, ln, air, buf, colours, (r, lo, r_next, far), math.nan,
                         _Paint(-1, 0, 0, 0.0, 0.0, 0.0, 0.0, c_top), c_top, c_top)
                tan_max = st[_TANMAX]
            z_prev = far  # the drop back to the ground beyond is never seen from outside
        else:
            z_out = _corner_z(pages, page, vy, vx, u1, v1) - ez
            if z_out > r_next * tan_max or z_in > r * tan_max:
                # Visible. The entry's elevation tangent and colour are the last voxel's exit
                # ones where the surface runs on continuously, as it nearly always does.
                if cached:
                    t_in = t_out
                    c_in = c_out
                else:
                    t_in = math.nan
                    c_in = _voxel_rgb(colours, page, vy, vx, u0, v0)
                c_out = _voxel_rgb(colours, page, vy, vx, u1, v1)
                seg = (r, z_in, r_next, z_out)
                st[_GROUND] = 1.0
                if detail_on:
                    # The voxel's slope from its corners' bilinear surface (corner q at u = q & 1,
                    # v = q >> 1): its mean gradient. Guard: inv_d = 1 / d_l > 0.
                    zc = pages.z[page, vy, vx]
                    gx = 0.5 * ((zc[1] - zc[0]) + (zc[3] - zc[2])) * inv_d
                    gy = 0.5 * ((zc[2] - zc[0]) + (zc[3] - zc[1])) * inv_d
                    st[_SLOPE] = math.sqrt(gx * gx + gy * gy)
                t2 = _tan_of(r_next, z_out)
                sb = _s_of_tan(ln, t2) if t_in == tan_max and t2 > tan_max else -1.0
                if sb >= 0.0 and sb < st[_ROW] + 1.0:
                    # The surface runs on from the horizon and ends inside the current step,
                    # as most voxels do where the ground is seen at a grazing angle: _emit's
                    # one-step case, without the calls.
                    a = st[_SMAX]
                    w = sb - a
                    st[_AR] += w * 0.5 * (c_in[0] + c_out[0])
                    st[_AG] += w * 0.5 * (c_in[1] + c_out[1])
                    st[_AB] += w * 0.5 * (c_in[2] + c_out[2])
                    st[_AW] += w
                    centre = st[_ROW] + 0.5
                    if a <= centre < sb:
                        hh, vv = _direction(ln, centre)
                        st[_IR] = _inverse_range_at(hh, vv, seg)
                    st[_R1] = r
                    st[_Z1] = z_in
                    st[_R2] = r_next
                    st[_Z2] = z_out
                    st[_TANMAX] = t2
                    st[_SMAX] = sb
                    t_out = t2
                else:
                    t_out = _surface(st, ln, air, buf, colours, seg, t_in,
                                     _Paint(page, vy, vx, u0, v0, u1, v1, c_in), c_in, c_out)
                tan_max = st[_TANMAX]
                cached = True
            else:
                cached = False
            z_prev = z_out
        if int(st[_ROW]) > last_k:
            break  # every step the line owns is covered
        r = r_next
        # Nothing farther can rise above what is seen: the highest point of the database
        # beyond r is below the current horizon (guard: r > 0 once a step was taken).
        if r > 0.0 and zrel_max <= min(r * tan_max, r_hi * tan_max):  # r_hi binds if tan_max < 0
            break
        if t_max_x < t_max_y:
            ix += step_x
            t_max_x += t_dx
            if ix < 0 or ix >= level_nx[level]:
                break
        else:
            iy += step_y
            t_max_y += t_dy
            if iy < 0 or iy >= level_ny[level]:
                break
    return visits


@njit(cache=True, inline="always")
def _growth(d, start, end):
    """A forest block's share of its height at slant distance d: smoothstep from 0 at start to
    1 at end (scene/forest.py's tree_growth, which the planting of the near trees uses)."""
    if d >= end:
        return 1.0
    if d <= start:
        return 0.0
    t = (d - start) / (end - start)  # guard: start < d < end
    return t * t * (3.0 - 2.0 * t)


@njit(cache=True, inline="always")
def _rgb64(rgb):
    """A float32 colour as the float64 tuple every other colour of the scan is: one
    compiled version of the functions it reaches, not one per float width."""
    return (np.float64(rgb[0]), np.float64(rgb[1]), np.float64(rgb[2]))


@borrowing
def _wall(st, ln, air, buf, colours, r, z_lo, z_hi, rgb, ground):
    """A vertical face of one linear colour rgb at ground range r from height z_lo to z_hi
    (relative to the eye, metres); ground: what it is for the land's detail (_GROUND's
    values: 0 none, _CANOPY_SIDE a stand's side)."""
    tb = _tan_of(r, z_hi)
    tmax = st[_TANMAX]
    if tb <= tmax:
        return
    st[_GROUND] = ground
    ta = _tan_of(r, z_lo)
    sa = st[_SMAX] if ta <= tmax else _s_of_tan(ln, ta)
    _emit(st, ln, air, buf, colours, sa, _s_of_tan(ln, tb), tb, (r, z_lo, r, z_hi),
          _Paint(-1, 0, 0, 0.0, 0.0, 0.0, 0.0, rgb), rgb, rgb)


@borrowing
def _surface(st, ln, air, buf, colours, seg, t1, paint, c1, c2):
    """The surface segment seg = (r1, z1, r2, z2): the part rising above the current horizon.

    t1: elevation tangent of (r1, z1) if known (NaN: computed here). Returns that of (r2, z2).
    Colour: paint, whose colour at the near end is c1 and at the far end c2.
    """
    r1, z1, r2, z2 = seg
    if math.isnan(t1):
        t1 = _tan_of(r1, z1)
    t2 = _tan_of(r2, z2)
    lo = t1
    hi = t2
    c_a, c_b = c1, c2
    if t2 < t1:
        # Seen from the eye the segment runs downwards in elevation: only its near end can
        # show (a crest).
        lo = t2
        hi = t1
        c_a, c_b = c2, c1
    tmax = st[_TANMAX]
    if hi <= tmax:
        return t2
    if lo <= tmax:
        # Only the part above the horizon, from where it emerges (its colour there); the
        # horizon's position along the line is known.
        sa = st[_SMAX]
        if lo < tmax:
            c_a = _colour_at(colours, paint, _param_at(1.0, tmax, seg))
    else:
        sa = _s_of_tan(ln, lo)
    _emit(st, ln, air, buf, colours, sa, _s_of_tan(ln, hi), hi, seg, paint, c_a, c_b)
    return t2
