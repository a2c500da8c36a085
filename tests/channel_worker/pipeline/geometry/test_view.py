"""Orientation conventions (docs/conventions.md) and the world -> eye transform."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from channel_worker.pipeline.geometry.view import make_view
from services.rig.frame import ChannelSpec, Eyepoint, hpr_matrix

CH = ChannelSpec.symmetric("c", 64, 48, 60.0)


def axes(h, p, r):
    m = hpr_matrix(h, p, r)
    return m[:, 0], m[:, 1], m[:, 2]  # right, forward, up in world


def test_zero_attitude_looks_north_with_z_up():
    right, fwd, up = axes(0, 0, 0)
    np.testing.assert_allclose(fwd, [0, 1, 0])
    np.testing.assert_allclose(up, [0, 0, 1])
    np.testing.assert_allclose(right, [1, 0, 0])
    view = make_view(CH, Eyepoint.of(0, 0, 0, 0, 0, 0))
    # eye z (forward) is world north, eye y (up) is world up
    np.testing.assert_allclose(view.world_to_eye @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(view.world_to_eye @ [0, 0, 1], [0, 1, 0], atol=1e-15)


def test_heading_is_clockwise_from_north():
    _, fwd, _ = axes(90, 0, 0)
    np.testing.assert_allclose(fwd, [1, 0, 0], atol=1e-15)  # east
    _, fwd, _ = axes(180, 0, 0)
    np.testing.assert_allclose(fwd, [0, -1, 0], atol=1e-15)


def test_pitch_nose_up_and_roll_right_wing_down():
    _, fwd, _ = axes(0, 30, 0)
    assert fwd[2] > 0
    right, _, _ = axes(0, 0, 30)
    assert right[2] < 0
    # heading then pitch then roll: pitch is about the already-turned right axis
    right, fwd, _up = axes(90, 30, 0)
    np.testing.assert_allclose(fwd, [math.cos(math.radians(30)), 0, math.sin(math.radians(30))], atol=1e-15)


def test_heading_359_to_0_is_continuous():
    a, b, c = hpr_matrix(359.0, 5, 3), hpr_matrix(0.0, 5, 3), hpr_matrix(-1.0, 5, 3)
    assert np.abs(a - b).max() < math.radians(1.01)
    np.testing.assert_allclose(a, c, atol=1e-14)
    np.testing.assert_allclose(hpr_matrix(360.0, 5, 3), b, atol=1e-14)


@pytest.mark.parametrize("pitch", [90.0, -90.0, 89.9999, -89.9999])
@pytest.mark.parametrize("heading", [0.0, 359.0, 123.0])
def test_pitch_plus_minus_90_has_no_nan(pitch, heading):
    m = hpr_matrix(heading, pitch, 45.0)
    assert np.isfinite(m).all()
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-14)
    view = make_view(CH, Eyepoint.of(0, 0, 100, heading, pitch, 0))
    assert np.isfinite(view.world_to_eye).all()
    looking = view.world_to_eye[2]
    np.testing.assert_allclose(looking[2], math.copysign(1.0, pitch), atol=1e-6)


@given(st.floats(-720, 720), st.floats(-90, 90), st.floats(-180, 180))
def test_rotation_is_orthonormal_right_handed(h, p, r):
    m = hpr_matrix(h, p, r)
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-12)
    assert np.linalg.det(m) == pytest.approx(1.0, abs=1e-12)


def test_channel_offset_composes_after_aircraft_attitude():
    chan = ChannelSpec.symmetric("left", 64, 48, 60.0, yaw_deg=-60.0)
    view = make_view(chan, Eyepoint.of(0, 0, 0, 90, 0, 0))
    np.testing.assert_allclose(view.world_to_eye[2], [math.cos(math.radians(60)), math.sin(math.radians(60)), 0],
                               atol=1e-15)  # nose east, channel 60 deg left of it: heading 30


def test_roll_180_is_upside_down():
    view = make_view(CH, Eyepoint.of(0, 0, 0, 0, 0, 180))
    np.testing.assert_allclose(view.world_to_eye[1], [0, 0, -1], atol=1e-15)


@pytest.mark.parametrize("field,index", [("position", 0), ("position", 2)])
def test_nan_eyepoint_names_the_field(field, index):
    pos = [0.0, 0.0, 10.0]
    pos[index] = float("nan")
    with pytest.raises(ValueError, match=rf"eyepoint.position\[{index}\]: nan"):
        make_view(CH, Eyepoint.of(*pos, 0, 0, 0))


def test_infinite_attitude_names_the_field():
    with pytest.raises(ValueError, match=r"eyepoint.roll_deg: inf"):
        make_view(CH, Eyepoint.of(0, 0, 1, 0, 0, float("inf")))


def test_bad_frustum_names_the_field():
    bad = ChannelSpec("x", 10, 10, 10.0, -10.0, -5.0, 5.0)
    with pytest.raises(ValueError, match=r"left_deg 10.0 is not < right_deg -10.0"):
        make_view(bad, Eyepoint.of(0, 0, 1, 0, 0, 0))
