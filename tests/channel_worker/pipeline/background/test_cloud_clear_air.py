"""The cloud overlay's clear-air shortcut (_cloud_over_kernels.clear_air): a block whose pixels
could read a cloudy texel, or a quad sampled finer, must never be taken for clear air, wherever
that texel or quad lies, with the columns clamped or wrapping round a full circle."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.background._cloud_over_kernels import clear_air
from channel_worker.pipeline.background._groups import CLOUD_CHANNELS, CloudImage
from channel_worker.pipeline.background.clouds import REFINE

NCOLS, NROWS = 12, 9


def _image(texels: np.ndarray, full: bool, refined: tuple[int, int] | None = None) -> CloudImage:
    """The coarse texels, and no quad sampled finer or the one quad `refined` (its fine
    samples: cloud between clear corners, as a quad the edge reached can hold)."""
    quad = np.full((NCOLS, NROWS), -1, np.int32)
    fine = np.zeros((0 if refined is None else 1, REFINE + 1, REFINE + 1, CLOUD_CHANNELS), np.float32)
    if refined is not None:
        quad[refined] = 0
        fine[0, 1:REFINE, 1:REFINE, 3] = 0.5
    return CloudImage(texels, full, 0.0, 0.01, -0.1, 0.01, NCOLS * 0.01, quad, fine)


def _texels_read(cols, rows, full: bool) -> set[tuple[int, int]]:
    """Every (column, row) _cloud_over reads for the pixel centres of an interpolated block
    with these corner coordinates, found point by point on a dense grid of its interior."""
    c00, c10, c01, c11 = cols
    r00, r10, r01, r11 = rows
    read = set()
    for fy in np.linspace(0.0, 1.0, 33):
        for fx in np.linspace(0.0, 1.0, 33):
            c = (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11)
            r = (1 - fy) * ((1 - fx) * r00 + fx * r10) + fy * ((1 - fx) * r01 + fx * r11)
            ci, ri = math.floor(c), math.floor(r)
            for col in (ci, ci + 1):
                col = col % NCOLS if full else min(max(col, 0), NCOLS - 1)
                for row in (ri, ri + 1):
                    read.add((col, min(max(row, 0), NROWS - 1)))
    return read


def _quads_read(cols, rows, full: bool) -> set[tuple[int, int]]:
    """Every quad (CloudImage.quad) _cloud_over reads for the pixel centres of an interpolated
    block with these corner coordinates, on the same dense grid as _texels_read: the quad at
    each point's floor, if it lies in the image (_cloud_over_kernels._quad)."""
    c00, c10, c01, c11 = cols
    r00, r10, r01, r11 = rows
    read = set()
    for fy in np.linspace(0.0, 1.0, 33):
        for fx in np.linspace(0.0, 1.0, 33):
            c = (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11)
            r = (1 - fy) * ((1 - fx) * r00 + fx * r10) + fy * ((1 - fx) * r01 + fx * r11)
            ci, ri = math.floor(c), math.floor(r)
            if full:
                ci %= NCOLS
            if 0 <= ci < (NCOLS if full else NCOLS - 1) and 0 <= ri < NROWS - 1:
                read.add((ci, ri))
    return read


corner = st.floats(-4.0, 16.0, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(cols=st.tuples(corner, corner, corner, corner), rows=st.tuples(corner, corner, corner, corner),
       full=st.booleans())
def test_a_block_that_can_read_a_cloudy_texel_is_never_clear(cols, rows, full):
    empty = np.zeros((NCOLS, NROWS, CLOUD_CHANNELS), np.float32)
    # One cloudy texel at a time, at every texel the block's pixels can read.
    for col, row in _texels_read(cols, rows, full):
        cloudy = empty.copy()
        cloudy[col, row, 3] = 0.25
        assert not clear_air(_image(cloudy, full), cols, rows), (col, row)


@settings(max_examples=150, deadline=None)
@given(cols=st.tuples(corner, corner, corner, corner), rows=st.tuples(corner, corner, corner, corner),
       full=st.booleans())
def test_a_block_that_can_read_a_refined_quad_is_never_clear(cols, rows, full):
    empty = np.zeros((NCOLS, NROWS, CLOUD_CHANNELS), np.float32)
    # One quad sampled finer at a time (cloud between its clear corners), at every quad the
    # block's pixels can read (_cloud_over: the quad whose corner is the texel at their floor).
    for quad in _quads_read(cols, rows, full):
        assert not clear_air(_image(empty, full, quad), cols, rows), quad


def test_a_corner_a_hair_below_a_texel_row_still_guards_the_row_above():
    # Found by the property above in one CI run: rows -1 and -5e-324 interpolate to -0.0
    # inside the block, whose pixels then read rows 0 and 1; the box of the corners' floors
    # alone ended at row 0.
    cloudy = np.zeros((NCOLS, NROWS, CLOUD_CHANNELS), np.float32)
    cloudy[0, 1, 3] = 0.25
    assert (0, 1) in _texels_read((0.0, 0.0, 0.0, 0.0), (-1.0, -1.0, -5e-324, -5e-324), False)
    assert not clear_air(_image(cloudy, False), (0.0, 0.0, 0.0, 0.0), (-1.0, -1.0, -5e-324, -5e-324))


def test_a_small_block_under_clear_air_is_clear_and_a_wide_one_is_left_to_its_pixels():
    empty = _image(np.zeros((NCOLS, NROWS, CLOUD_CHANNELS), np.float32), False)
    assert clear_air(empty, (1.0, 2.0, 1.0, 2.0), (2.0, 2.0, 3.0, 3.0))
    assert not clear_air(empty, (0.0, 11.0, 0.0, 11.0), (2.0, 2.0, 3.0, 3.0))  # 8+ texels across
