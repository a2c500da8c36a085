"""Edge blending between adjacent channels, and the check that their frusta meet where the rig
file says they do (docs/edge-blending.md).

Channels are stitched side by side in rig order, so the right edge of one channel must meet the
left edge of the next: at the same horizontal angle (abutting), or a configured angle inside it
(overlapping, `[blend] overlap_deg`), and at the same elevation on every row. seam_check
measures both from the ChannelSpecs alone; blend_plan turns the overlap into columns, weights
and offsets once per rig, so stitching a frame is a copy and, over the overlaps only, a
cross-fade.

Frames (docs/conventions.md): a channel's frame relative to the aircraft body is
``hpr_matrix(yaw, pitch, roll)`` with x right, y forward, z up; a point of the channel's image
is the ray (tan h, 1, tan v) in that frame, h and v being the tangent-plane angles its
left_deg/right_deg and bottom_deg/top_deg bound (as the renderer's view does).

The blend ramp is P. Bourke's, *Edge blending using commodity projectors* (2004): f(x) =
0.5 (2x)^p below x = 0.5, 1 - 0.5 (2 (1 - x))^p above, so f(x) + f(1 - x) = 1: the two
channels' weights in linear light sum to one across the overlap, and a projector applying the
mask in signal space needs f^(1 / gamma).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import numpy as np

from services.rig.colour import srgb_to_linear
from services.rig.frame import ChannelSpec, check_channel, hpr_matrix
from services.rig.image_io import write_image
from services.rig.rigfile import BlendSpec

#: Rays sampled along each seam, bottom to top (every 1/64 of the edge's height, both ends).
SEAM_SAMPLES = 65

#: Weights are multiples of this (2^-24), so 1 - w is exact in float32 and a seam's two
#: weights sum to exactly 1, not to 1 within a rounding.
_WEIGHT_QUANTUM = 2.0 ** -24


@dataclass(frozen=True)
class Seam:
    """How the right edge of one channel lies against the left edge of the next.

    Angles in degrees, pixels of the left channel at the seam (its local pixel pitch there).

    Attributes:
        left: the left channel's name.
        right: the right channel's name.
        overlap_min_deg: least horizontal angle by which the left channel's right edge lies
            inside the right channel's left edge, over the seam's elevations (negative: a gap).
        overlap_max_deg: the greatest.
        horizontal_error_deg: max abs of measured overlap - the configured overlap_deg.
        vertical_error_deg: max abs of the elevation mismatch: a ray of the seam's elevation
            above the right channel's horizontal plane minus its elevation above the left
            channel's (a pitch or roll between them: rows that would not line up stitched side
            by side).
        horizontal_error_px: horizontal_error_deg in pixels of the left channel at the seam.
        vertical_error_px: vertical_error_deg in pixels (rows) of the left channel at the seam.
        ok: both errors within the blend's tolerance_deg.
    """

    left: str
    right: str
    overlap_min_deg: float
    overlap_max_deg: float
    horizontal_error_deg: float
    vertical_error_deg: float
    horizontal_error_px: float
    vertical_error_px: float
    ok: bool

    def as_dict(self) -> dict[str, str | float | bool]:
        """The seam as a JSON-ready dict (the report's "seams" entries), rounded to 1e-6."""
        doc: dict[str, str | float | bool] = {"left": self.left, "right": self.right}
        for name in ("overlap_min_deg", "overlap_max_deg", "horizontal_error_deg", "vertical_error_deg",
                     "horizontal_error_px", "vertical_error_px"):
            doc[name] = round(float(getattr(self, name)), 6)
        doc["ok"] = bool(self.ok)
        return doc


def _frame(spec: ChannelSpec) -> np.ndarray:
    """Channel -> body rotation (3, 3): columns are the channel's right, forward, up axes."""
    return hpr_matrix(spec.yaw_deg, spec.pitch_deg, spec.roll_deg)


def _tans(spec: ChannelSpec) -> tuple[float, float, float, float]:
    """tan of left, right, bottom, top."""
    tl, tr, tb, tt = (math.tan(math.radians(a)) for a in (spec.left_deg, spec.right_deg, spec.bottom_deg,
                                                           spec.top_deg))
    return tl, tr, tb, tt


def _in_right(left: ChannelSpec, right: ChannelSpec, tx: np.ndarray, ty: np.ndarray) -> tuple[np.ndarray, ...]:
    """Rays (tx, 1, ty) of the left channel's frame as (x, forward, up) of the right channel's."""
    rays = np.stack([tx, np.ones_like(tx), ty])
    return tuple(_frame(right).T @ _frame(left) @ rays)


def _check_pair(left: ChannelSpec, right: ChannelSpec) -> None:
    check_channel(left)
    check_channel(right)


def measure_seam(left: ChannelSpec, right: ChannelSpec, blend: BlendSpec, *,
                 samples: int = SEAM_SAMPLES) -> Seam:
    """Measure one seam from the two ChannelSpecs (see Seam).

    Args:
        left: the channel on the left of the seam.
        right: the channel on its right.
        blend: the configured overlap_deg and tolerance_deg.
        samples: rays along the left channel's right edge, evenly spaced in image rows from the
            bottom edge to the top edge.

    Raises:
        ValueError: a channel cannot make a frustum (check_channel), or samples < 2.
    """
    _check_pair(left, right)
    if samples < 2:
        raise ValueError(f"samples: {samples} must be >= 2")
    tl, tr, tb, tt = _tans(left)
    # Evenly spaced in tan (image rows), top row first as the image is.
    ty = np.linspace(tt, tb, samples)
    tx = np.full_like(ty, tr)
    x, fwd, up = _in_right(left, right, tx, ty)
    # atan2 instead of atan(x / fwd): a ray at or behind the right channel's image plane
    # (fwd <= 0) gets an angle beyond +-90 degrees, a large error, never a division by zero.
    azimuth = np.degrees(np.arctan2(x, fwd))
    overlap = azimuth - right.left_deg
    # Elevation: the ray's angle above each channel's horizontal (right, forward) plane. A yaw
    # between channels keeps it and a pitch or roll error changes it, wherever on the seam.
    # Not the tangent-plane angle atan(up / forward): planar images off their axes scale rows by
    # 1 / cos(azimuth), so overlapping channels (the ray at 35 degrees in one, 25 in the other)
    # would differ by degrees at the corners with nothing misaligned. atan2 again, no division:
    # a ray straight along the right channel's up axis (x = forward = 0) is 90 degrees.
    norm_left = np.hypot(tx, 1.0)
    vertical = np.degrees(np.arctan2(up, np.hypot(x, fwd)) - np.arctan2(ty, norm_left))
    horizontal = overlap - blend.overlap_deg
    h_err = float(np.max(np.abs(horizontal)))
    v_err = float(np.max(np.abs(vertical)))
    # Pixels per radian of the left image at the seam: column = x_scale' * tan(azimuth) and
    # row = y_scale' * tan(elevation) * hypot(tan right, 1) plus offsets, so the derivatives
    # carry sec^2 of the angle (tan' = 1 + tan^2); the scales divide by tr - tl and tt - tb,
    # both > 0 by check_channel.
    x_scale = left.width / (tr - tl) * (1.0 + tr * tr)
    tan_el = ty / norm_left
    y_scale = left.height / (tt - tb) * norm_left * (1.0 + tan_el * tan_el)
    h_px = float(np.max(np.abs(np.radians(horizontal)) * x_scale))
    v_px = float(np.max(np.abs(np.radians(vertical)) * y_scale))
    ok = h_err <= blend.tolerance_deg and v_err <= blend.tolerance_deg
    return Seam(left.name, right.name, float(np.min(overlap)), float(np.max(overlap)), h_err, v_err,
                h_px, v_px, ok)


def seam_check(channels: Sequence[ChannelSpec], blend: BlendSpec) -> list[Seam]:
    """Every seam of a rig: channel i's right edge against channel i + 1's left edge.

    Args:
        channels: the rig's channels in display order, left to right.
        blend: the configured overlap and tolerance (the rig file's ``[blend]``).

    Returns:
        len(channels) - 1 seams, left to right (none for one channel).

    Raises:
        ValueError: a channel cannot make a frustum (names the channel and the field).
    """
    return [measure_seam(a, b, blend) for a, b in pairwise(channels)]


def seams_report(seams: Sequence[Seam]) -> dict[str, object]:
    """JSON-ready summary: {"ok": every seam ok, "seams": [Seam.as_dict(), ...]}."""
    return {"ok": all(s.ok for s in seams), "seams": [s.as_dict() for s in seams]}


def bourke_ramp(x: np.ndarray, power: float) -> np.ndarray:
    """Bourke's edge-blending curve (*Edge blending using commodity projectors*, 2004).

    f(x) = 0.5 (2x)^p for x < 0.5, 1 - 0.5 (2 (1 - x))^p otherwise: rises from 0 at x = 0 to 1
    at x = 1 through 0.5 at the middle, and f(x) + f(1 - x) = 1.

    Args:
        x: positions across the overlap, 0 at the start of the fade-in, 1 at its end.
        power: p > 0 (1: linear; larger: flatter at the middle, steeper near the ends).
    """
    if not power > 0.0:
        raise ValueError(f"power: {power} must be > 0")
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    low = 0.5 * np.power(2.0 * x, power)
    high = 1.0 - 0.5 * np.power(2.0 * (1.0 - x), power)
    return np.where(x < 0.5, low, high)


def ramp_weights(n: int, power: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear-light weights across an overlap of n columns, left to right.

    Column k's centre sits at x = (k + 0.5) / n of the overlap.

    Returns:
        (fade_out, fade_in) float32 (n,): the left channel's weights (1 -> 0) and the right
        channel's (0 -> 1); fade_out + fade_in is exactly 1 in every column.

    Raises:
        ValueError: n < 0 or power <= 0.
    """
    if n < 0:
        raise ValueError(f"n: {n} must be >= 0")
    fade_in = bourke_ramp((np.arange(n) + 0.5) / max(n, 1), power)
    fade_in = np.round(fade_in / _WEIGHT_QUANTUM) * _WEIGHT_QUANTUM
    fade_in32 = fade_in.astype(np.float32)
    return (np.float32(1.0) - fade_in32).astype(np.float32), fade_in32


@dataclass(frozen=True, eq=False)
class BlendPlan:
    """How to stitch one rig's frames: overlaps, offsets and column weights, made once.

    Attributes:
        names: channel names in display order.
        widths: each channel's width, pixels.
        heights: each channel's height, pixels.
        overlaps: per seam (len(names) - 1), the columns shared by its two channels
            (overlap_columns: counted in the left channel).
        overlaps_right: per seam, overlap_columns_right (counted in the right channel; a
            report only: it differs from overlaps when the pitch at the seam differs).
        offsets: each channel's first column in the stitched image.
        stitched_width: the stitched image's width, pixels.
        left_weights: per channel, float32 (its left overlap,): linear-light weights fading it in
            over its first columns (empty for the first channel or an abutting seam).
        right_weights: per channel, float32 (its right overlap,): weights fading it out over its
            last columns.
        gamma: the projectors' gamma (for channel_masks).
        seams: the seam check the plan was built with.
    """

    names: tuple[str, ...]
    widths: tuple[int, ...]
    heights: tuple[int, ...]
    overlaps: tuple[int, ...]
    overlaps_right: tuple[int, ...]
    offsets: tuple[int, ...]
    stitched_width: int
    left_weights: tuple[np.ndarray, ...]
    right_weights: tuple[np.ndarray, ...]
    gamma: float
    seams: tuple[Seam, ...]

    @property
    def blends(self) -> bool:
        """True if any seam has overlap columns (else stitching is a plain concatenation)."""
        return any(self.overlaps)

    def report(self) -> dict[str, object]:
        """JSON-ready: the seam check (as seams_report) plus each seam's overlap columns counted
        in either channel, and the stitched width."""
        seams = []
        for seam, n, n_right in zip(self.seams, self.overlaps, self.overlaps_right, strict=True):
            seams.append({**seam.as_dict(), "overlap_columns": n, "overlap_columns_right": n_right})
        return {"ok": all(s.ok for s in self.seams), "seams": seams, "stitched_width": self.stitched_width}


def _columns_inside(src: ChannelSpec, dst: ChannelSpec, *, from_right: bool) -> int:
    """Columns of src, counted from its right (or left) edge inwards, whose centre ray on the
    middle row lies between dst's left and right edges (tangent-plane azimuth in dst)."""
    _check_pair(src, dst)
    tl, tr, tb, tt = _tans(src)
    cols = np.arange(src.width - 1, -1, -1) if from_right else np.arange(src.width)
    tx = tl + (cols + 0.5) / src.width * (tr - tl)
    ty = np.full_like(tx, 0.5 * (tt + tb), dtype=np.float64)
    x, fwd, _ = _in_right(src, dst, tx.astype(np.float64), ty)
    azimuth = np.degrees(np.arctan2(x, fwd))  # guard as in measure_seam: behind is far outside
    inside = (azimuth > dst.left_deg) & (azimuth < dst.right_deg)
    return src.width if inside.all() else int(np.argmin(inside))


def overlap_columns(left: ChannelSpec, right: ChannelSpec) -> int:
    """Columns of the left channel whose centre ray falls inside the right channel.

    Counted from the left channel's right edge inwards while inside, on the left image's middle
    row: on an aligned rig the overlap is the same on every row (the seam check says how far a
    rig is from that), and a stitch needs one count per seam. Inside means between the right
    channel's left and right edges in the same tangent-plane azimuth the seam check measures;
    a column centre is half a pixel inside the edge, so an abutting seam gives 0 with room to
    spare for rounding.
    """
    return _columns_inside(left, right, from_right=True)


def overlap_columns_right(left: ChannelSpec, right: ChannelSpec) -> int:
    """The same from the other side: columns of the right channel, from its left edge, whose
    centre ray falls inside the left channel. Equal to overlap_columns (to a column) when the
    two have the same pixel pitch at the seam; the stitch cross-fades overlap_columns of each."""
    return _columns_inside(right, left, from_right=False)


def blend_plan(channels: Sequence[ChannelSpec], blend: BlendSpec) -> BlendPlan:
    """The stitching plan of a rig: overlap columns per seam, offsets, weights, seam check.

    The right channel's first n columns are cross-faded with the left channel's last n
    (n = overlap_columns), which assumes the two show the same rays there: the same pixel pitch
    at the seam. The plan's report gives both sides' counts (overlap_columns_right), which then
    agree to a column; where they do not, the widths do not match the frusta and the cross-fade
    ghosts (docs/edge-blending.md).

    Args:
        channels: the rig's channels in display order (rig.channels' specs, at the size the
            workers render: after Rig.with_size if the run resizes them).
        blend: the rig's ``[blend]`` table (power, gamma; overlap_deg and tolerance_deg for the
            seam check).

    Raises:
        ValueError: no channels; a channel that cannot make a frustum; an overlap wider than
            the right channel; a channel whose left and right overlaps together exceed its width.
    """
    if not channels:
        raise ValueError("channels: empty; a rig has at least one channel")
    seams = seam_check(channels, blend)
    overlaps = []
    for a, b in pairwise(channels):
        n = overlap_columns(a, b)
        if n > b.width:
            raise ValueError(f"channel {b.name!r}: overlap of {n} columns with {a.name!r} is wider than "
                             f"its width {b.width}")
        overlaps.append(n)
    left_n = [0, *overlaps]
    right_n = [*overlaps, 0]
    for ch, nl, nr in zip(channels, left_n, right_n, strict=True):
        if nl + nr > ch.width:
            raise ValueError(f"channel {ch.name!r}: overlaps {nl} + {nr} columns exceed its width {ch.width}")
    offsets, x = [], 0
    for ch, nr in zip(channels, right_n, strict=True):
        offsets.append(x)
        x += ch.width - nr
    ramps = [ramp_weights(n, blend.power) for n in overlaps]
    empty = np.zeros(0, np.float32)
    return BlendPlan(
        names=tuple(ch.name for ch in channels), widths=tuple(ch.width for ch in channels),
        heights=tuple(ch.height for ch in channels), overlaps=tuple(overlaps),
        overlaps_right=tuple(overlap_columns_right(a, b) for a, b in pairwise(channels)),
        offsets=tuple(offsets),
        stitched_width=x,
        left_weights=(empty, *(fade_in for _, fade_in in ramps)),
        right_weights=(*(fade_out for fade_out, _ in ramps), empty),
        gamma=float(blend.gamma), seams=tuple(seams))


def channel_masks(plan: BlendPlan, *, full: bool = False) -> dict[str, np.ndarray]:
    """Per channel, the signal-space mask a projector multiplies its image by.

    The linear-light weight w of a column becomes w^(1 / gamma) in signal space (a projector
    turns a signal s into light s^gamma); 1 where the channel overlaps nothing.

    Args:
        plan: the rig's blend plan.
        full: (height, width) masks instead of one row (width,).

    Returns:
        {channel name: float32 mask}, in display order.
    """
    out = {}
    for i, name in enumerate(plan.names):
        row = np.ones(plan.widths[i], np.float32)
        nl, nr = plan.left_weights[i].size, plan.right_weights[i].size
        inv = 1.0 / plan.gamma  # gamma >= 1 in a rig file (rigfile checks 1..4)
        row[:nl] = np.power(plan.left_weights[i], inv)
        row[plan.widths[i] - nr:] = np.power(plan.right_weights[i], inv)
        out[name] = np.broadcast_to(row, (plan.heights[i], plan.widths[i])).copy() if full else row
    return out


def write_masks(plan: BlendPlan, out_dir: str | Path) -> list[Path]:
    """Write each channel's mask as ``mask_<name>.png`` (8-bit grey RGB) into out_dir.

    The PNG holds the signal-space mask itself (code = mask * 255): write_image sRGB-encodes
    what it is given, so the mask goes in sRGB-decoded and comes out as written.

    Returns:
        The paths written, in display order.

    Raises:
        OSError: a file could not be written.
    """
    paths = []
    for name, mask in channel_masks(plan, full=True).items():
        path = Path(out_dir) / f"mask_{name}.png"
        rgb = np.repeat(srgb_to_linear(mask.astype(np.float64))[..., None], 3, axis=2)
        write_image(path, rgb, attributes={"channel": name, "gamma": plan.gamma})
        paths.append(path)
    return paths
