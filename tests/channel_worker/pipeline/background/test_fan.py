"""The fan of cast lines (background/fan.py): every pixel belongs to exactly one line, whatever
the view: the vanishing point inside the screen, outside it, at infinity (pitch 0) or exactly
on a pixel centre; any roll; wide, off-axis and yawed channels; odd and even sizes. The
ownership counted is the kernel's own (_cast_kernels.own_steps)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.background._cast_kernels import ownership_counts
from channel_worker.pipeline.background.fan import line_fan
from channel_worker.pipeline.geometry.view import frame_constants, make_view
from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
from services.rig.frame import ChannelSpec, Eyepoint

SCENE = load_scene(bundled_scene_path())
OFFSETS = np.array([[0.5, 0.5]])


def counts(channel: ChannelSpec, eye: Eyepoint) -> np.ndarray:
    frame = frame_constants(make_view(channel, eye), SCENE, OFFSETS)
    return ownership_counts(line_fan(frame), channel.width, channel.height)


CHANNELS = [
    ChannelSpec.symmetric("even", 64, 48, 60.0),
    ChannelSpec.symmetric("odd", 63, 47, 60.0),
    ChannelSpec("wide", 90, 40, -60.0, 60.0, -35.0, 10.0, yaw_deg=35.0),
    ChannelSpec("left", 50, 38, -30.0, 30.0, -22.5, 22.5, yaw_deg=-60.0),
]


@pytest.mark.parametrize("channel", CHANNELS, ids=lambda c: c.name)
@pytest.mark.parametrize("pitch", [-90.0, -89.999, -45.0, -10.0, 0.0, 10.0, 60.0, 90.0])
@pytest.mark.parametrize("roll", [0.0, 30.0, 90.0, 180.0, -135.0])
def test_every_pixel_belongs_to_one_line(channel, pitch, roll):
    c = counts(channel, Eyepoint.of(0.0, 0.0, 100.0, 20.0, pitch, roll))
    assert c.min() == 1 and c.max() == 1, (np.argwhere(c != 1)[:5], c[c != 1][:5])


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(heading=st.floats(-180.0, 180.0), pitch=st.floats(-90.0, 90.0),
       roll=st.floats(-180.0, 180.0), channel=st.sampled_from(CHANNELS))
@example(heading=0.0, pitch=0.0, roll=2.225073858507203e-309, channel=CHANNELS[0])  # V at
# infinity but for a denormal: its homogeneous weight must not make a slope overflow
def test_every_pixel_belongs_to_one_line_at_any_attitude(heading, pitch, roll, channel):
    c = counts(channel, Eyepoint.of(0.0, 0.0, 100.0, heading, pitch, roll))
    assert c.min() == 1 and c.max() == 1


def test_straight_down_on_a_pixel_centre():
    # An odd square channel looking straight down: the vanishing point is the centre pixel's
    # centre, where every line meets; it belongs to one of them.
    channel = ChannelSpec.symmetric("odd-square", 31, 31, 50.0)
    frame = frame_constants(make_view(channel, Eyepoint.of(0.0, 0.0, 100.0, 0.0, -90.0, 0.0)),
                            SCENE, OFFSETS)
    fan = line_fan(frame)
    assert fan.nadir
    vx, vy = fan.vp[0] / fan.vw, -fan.vq[0] / fan.vw
    assert (vx, vy) == pytest.approx((15.5, 15.5))
    c = ownership_counts(fan, 31, 31)
    assert c.min() == 1 and c.max() == 1


def test_level_unrolled_lines_are_the_columns():
    # Pitch 0, roll 0: the vanishing point lies at infinity below the screen and the lines are
    # the screen's columns, aimed at the top row's pixel centres (the classic column renderer).
    channel = ChannelSpec.symmetric("c", 40, 30, 60.0)
    frame = frame_constants(make_view(channel, Eyepoint.of(0.0, 0.0, 100.0, 0.0, 0.0, 0.0)),
                            SCENE, OFFSETS)
    fan = line_fan(frame)
    assert fan.vw == 0.0 and fan.nadir
    owning = fan.wedge == 0
    assert np.allclose(fan.slope[owning], 0.0)
    assert ownership_counts(fan, 40, 30).max() == 1
