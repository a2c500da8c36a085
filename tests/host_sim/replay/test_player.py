"""Replay speed, start time and loop; a replay is deterministic frame by frame."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host_sim.replay import Replay, load_track

from .logs import flight, write_csv

RATE = 30.0


@pytest.fixture
def track(tmp_path):
    return load_track(write_csv(tmp_path / "f.csv", flight(21)))[0]  # 20 s long


def frames(replay, n):
    out = []
    for k in range(n):
        e = replay.eyepoint_at(k / RATE)
        out.append((*e.position, e.heading_deg, e.pitch_deg, e.roll_deg))
    return np.array(out)


def test_deterministic_frame_by_frame(track):
    a = frames(Replay(track, speed=1.7, start_s=2.0), 200)
    b = frames(Replay(track, speed=1.7, start_s=2.0), 200)
    assert np.array_equal(a, b)
    r = Replay(track)
    late = r.eyepoint_at(10.0)
    r.eyepoint_at(3.0)  # a pure function of simulation time: order does not matter
    assert np.array_equal(r.eyepoint_at(10.0).position, late.position)


def test_speed_and_start(track):
    r = Replay(track, speed=2.0, start_s=4.0)
    assert r.duration_s == pytest.approx(8.0)
    assert np.array_equal(r.eyepoint_at(3.0).position, track.sample(10.0).position)
    assert np.array_equal(r.eyepoint_at(100.0).position, track.sample(20.0).position)  # holds the end
    assert r.status().log_time_s == 20.0 and r.status().loops == 0


def test_loop_goes_back_to_the_start(track):
    r = Replay(track, start_s=5.0, loop=True)
    assert math.isinf(r.duration_s)
    assert np.array_equal(r.eyepoint_at(15.0 + 2.5).position, track.sample(7.5).position)
    s = r.status()
    assert s.loops == 1 and s.log_time_s == pytest.approx(7.5) and s.records == 21


@pytest.mark.parametrize("kw,words", [(dict(speed=0.0), "speed: 0.0 must be"), (dict(speed=math.nan), "speed"),
                                     (dict(start_s=20.0), r"start: 20.0 s is outside the log \(0 .. 20.000 s\)"),
                                     (dict(start_s=-1.0), "start")])
def test_bad_options_are_named(track, kw, words):
    with pytest.raises(ValueError, match=words):
        Replay(track, **kw)


def test_heading_across_north_in_a_replay(tmp_path):
    path = tmp_path / "n.csv"
    path.write_text("time_s,x_m,y_m,z_m,heading_deg,pitch_deg,roll_deg\n"
                    "0,0,0,10,350,0,0\n1,0,10,10,359,0,0\n2,0,20,10,1,0,0\n3,0,30,10,10,0,0\n")
    r = Replay(load_track(path)[0])
    hs = frames(r, int(3 * RATE) + 1)[:, 3]
    assert all(min(h, 360.0 - h) <= 10.0 + 1e-9 for h in hs)  # never anywhere near 180
    steps = np.abs((np.diff(hs) + 180.0) % 360.0 - 180.0)
    assert steps.max() < 0.5
