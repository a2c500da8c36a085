"""Juxtaposed channels: the horizon and an object straddling a seam continue across it."""

import math

import numpy as np
import pytest

from channel_worker.pipeline.render import render_frame
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

W, H = 96, 72


def rig():
    """The default rig's left and centre channels (60 x 45 degrees, yaw -60 and 0), small."""
    return [ChannelSpec("left", W, H, -30.0, 30.0, -22.5, 22.5, yaw_deg=-60.0),
            ChannelSpec("centre", W, H, -30.0, 30.0, -22.5, 22.5, yaw_deg=0.0)]


def sky_rows(img, column, sky, earth):
    """Sub-pixel horizon position in a column: the number of pixel-heights of sky above it.

    With a sky above earth and many samples per pixel, each pixel's colour is a coverage
    weighted mix, so the sum of the sky fractions down the column is the horizon's row.
    """
    g = img.rgb[:, column, 1].astype(np.float64)
    frac = (g - earth[1]) / (sky[1] - earth[1])
    return float(np.clip(frac, 0.0, 1.0).sum())


@pytest.mark.parametrize("roll", [0.0, 15.0, -25.0])
@pytest.mark.parametrize("pitch", [0.0, 5.0])
def test_horizon_continues_across_the_seam(make_scene, box_model_factory, roll, pitch):
    db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, -1000, 0]}])
    eye = Eyepoint.of(0.0, 0.0, 50.0, 10.0, pitch, roll)
    left, centre = (render_frame(db, ch, eye, RenderOptions(samples=16)) for ch in rig())
    a = sky_rows(left, W - 1, db.sky_colour, db.earth_colour)
    b = sky_rows(centre, 0, db.sky_colour, db.earth_colour)
    # the two columns are one pixel apart across the seam: the horizon may move by its slope
    slope = abs(math.tan(math.radians(roll))) + 0.05
    assert 0 < a < H and 0 < b < H
    assert abs(a - b) <= max(1.0, slope + 0.25), (a, b)


@pytest.mark.parametrize("roll", [0.0, 20.0])
def test_object_straddling_the_seam_continues(make_scene, box_model_factory, roll):
    # a wide hangar wall centred on the seam between left and centre (30 degrees left of the
    # nose), facing the eye, so its top edge crosses the seam
    dist = 200.0
    az = math.radians(-30.0)
    pos = [dist * math.sin(az), dist * math.cos(az), 0.0]
    db = make_scene({"wall": box_model_factory(60, 6, 40, "#ff0000")},
                    [{"model": "wall", "position": pos, "hpr": [-30.0, 0.0, 0.0]}])
    eye = Eyepoint.of(0.0, 0.0, 20.0, 0.0, 0.0, roll)
    left, centre = (render_frame(db, ch, eye, RenderOptions(samples=16)) for ch in rig())

    def wall_top(img, column):
        # the top edge, to sub-pixel precision from the coverage of the first covered pixel
        red = img.rgb[:, column, 0].astype(np.float64)
        frac = np.clip(red / red.max(), 0, 1) if red.max() > 0 else red
        rows = np.nonzero(frac > 0.02)[0]
        assert rows.size, "wall not visible in this column"
        return rows[0] + (1.0 - frac[rows[0]])

    a = wall_top(left, W - 1)
    b = wall_top(centre, 0)
    slope = abs(math.tan(math.radians(roll))) + 0.05
    assert abs(a - b) <= max(1.0, slope + 0.25), (a, b)
    # the wall is split: part of it in each channel
    assert (left.range_m[:, -3:] < 300).any() and (centre.range_m[:, :3] < 300).any()
