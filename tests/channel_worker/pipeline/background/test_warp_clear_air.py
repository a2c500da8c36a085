"""The warp's clear-air shortcut (_warp_kernels._clear_air): a block whose pixels could read a
cloudy texel must never be taken for clear air, wherever that texel lies, with the columns
clamped or wrapping round a full circle."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.background._groups import CLOUD_CHANNELS, CloudImage
from channel_worker.pipeline.background._warp_kernels import _Block, _clear_air

NCOLS, NROWS = 12, 9


def _texels_read(cloud: CloudImage, full: bool, blk: _Block) -> set[tuple[int, int]]:
    """Every (column, row) _cloud_over reads for the pixel centres of an interpolated block,
    found point by point on a dense grid of its interior."""
    c00, c10, c01, c11 = blk.cols
    r00, r10, r01, r11 = blk.rows
    read = set()
    for fy in np.linspace(0.0, 1.0, 33):
        for fx in np.linspace(0.0, 1.0, 33):
            c = (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11)
            r = (1 - fy) * ((1 - fx) * r00 + fx * r10) + fy * ((1 - fx) * r01 + fx * r11)
            cc = (c + 0.5) / cloud.col_ratio - 0.5
            rr = (r + 0.5) / cloud.row_ratio - 0.5
            ci, ri = math.floor(cc), math.floor(rr)
            for col in (ci, ci + 1):
                col = col % NCOLS if full else min(max(col, 0), NCOLS - 1)
                for row in (ri, ri + 1):
                    read.add((col, min(max(row, 0), NROWS - 1)))
    return read


corner = st.floats(-30.0, 130.0, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(cols=st.tuples(corner, corner, corner, corner), rows=st.tuples(corner, corner, corner, corner),
       ratio=st.sampled_from([4.0, 7.97, 8.0]), full=st.booleans())
def test_a_block_that_can_read_a_cloudy_texel_is_never_clear(cols, rows, ratio, full):
    empty = np.zeros((NCOLS, NROWS, CLOUD_CHANNELS), np.float32)
    blk = _Block(0, 0, 8, 1.0 / 8, False, cols, rows)
    # One cloudy texel at a time, at every texel the block's pixels can read.
    for col, row in _texels_read(CloudImage(True, empty, ratio, ratio), full, blk):
        cloudy = empty.copy()
        cloudy[col, row, 3] = 0.25
        assert not _clear_air(CloudImage(True, cloudy, ratio, ratio), full, blk), (col, row)

def test_a_small_block_under_clear_air_is_clear_and_a_wide_one_is_left_to_its_pixels():
    empty = np.zeros((NCOLS, NROWS, CLOUD_CHANNELS), np.float32)
    cloud = CloudImage(True, empty, 8.0, 8.0)
    small = _Block(0, 0, 8, 1.0 / 8, False, (10.0, 18.0, 10.0, 18.0), (20.0, 20.0, 28.0, 28.0))
    wide = _Block(0, 0, 8, 1.0 / 8, False, (0.0, 90.0, 0.0, 90.0), (20.0, 20.0, 28.0, 28.0))
    assert _clear_air(cloud, False, small)
    assert not _clear_air(cloud, False, wide)  # more than 8 cloud texels across
