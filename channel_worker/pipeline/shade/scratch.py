"""A sub-area's sample store as the visibility stage fills it and the box filter reads it:
per-sample identities and depths, the translucent lists, and the coverage masks."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Scratch(NamedTuple):
    """One thread's sample store for a sub-area (sample s of pixel (x, y) of the sub-area is
    i = ((y - ty0) * S + s) * tw + (x - tx0): a sample row of the sub-area is contiguous, so a
    feature takes a run of pixels with contiguous writes): the nearest opaque feature's 1/z
    and identity, the nearer translucent ones (nearest first: 1/z, identity, layer) and their
    count; the coverage masks (MaskLayout:
    word r * wpr + w of row r) of the samples that hold an opaque feature (covered) and of the
    feature being read (cw); per row, a lower bound of the stored opaque 1/z (row_far); and the
    current feature's edges that cross the sub-area (act: edge rows, e_step: their steps,
    e_inv: 1 / e_step); per row, the pixel columns whose samples may not all see one thing
    (mixed: the others see one opaque feature, or nothing, with every sample). o_id is -1
    where no opaque feature is held only once the list is read (_mark_uncovered): the masks
    say which samples hold one."""

    o_iz: np.ndarray
    o_id: np.ndarray
    t_iz: np.ndarray
    t_id: np.ndarray
    t_lay: np.ndarray
    t_cnt: np.ndarray
    e_step: np.ndarray
    e_inv: np.ndarray
    act: np.ndarray
    covered: np.ndarray
    cw: np.ndarray
    row_far: np.ndarray
    mixed: np.ndarray


class MaskLayout(NamedTuple):
    """How a sub-area's samples are held as bit masks (N. Greene, "Hierarchical polygon tiling
    with coverage masks", SIGGRAPH 96: coverage as words, combined 64 samples at a time).

    One sample of one row of a sub-area is `size` bits (bit x for pixel column x of the
    sub-area); a 64-bit word holds `spw` such sample rows of the same pixel row, so a row of
    the sub-area is `wpr` words, sample s in word s // spw at bit (s % spw) * size + x.
    size <= 64 (RenderOptions.subarea).

    Attributes:
        size, spw, wpr: as above.
        rep: (wpr,) uint64 with bit slot * size set for every sample slot word w holds: a
            pixel-column mask times rep[w] is that column range at every sample of the word.
        extent: (4,) int64 the smallest and largest x offset, then y offset, of the pattern's
            samples (1/SUBPIXEL units from the pixel's corner).
    """

    size: int
    spw: int
    wpr: int
    rep: np.ndarray
    extent: np.ndarray


def mask_layout(size: int, off_fixed: np.ndarray) -> MaskLayout:
    """The MaskLayout of sub-areas of `size` pixels and the pattern off_fixed ((S, 2) int64).

    Raises:
        ValueError: size outside 1..64 (a sample row of a sub-area must fit one word).
    """
    if not 1 <= size <= 64:
        raise ValueError(f"subarea: must be 1..64 pixels (one sample row in a 64-bit mask), "
                         f"got {size}")
    s_count = off_fixed.shape[0]
    spw = max(1, min(s_count, 64 // size))
    wpr = -(-s_count // spw)
    rep = np.zeros(wpr, np.uint64)
    for s in range(s_count):
        rep[s // spw] |= np.uint64(1) << np.uint64((s % spw) * size)
    extent = np.array([off_fixed[:, 0].min(), off_fixed[:, 0].max(), off_fixed[:, 1].min(),
                       off_fixed[:, 1].max()], np.int64)
    return MaskLayout(size, spw, wpr, rep, extent)
