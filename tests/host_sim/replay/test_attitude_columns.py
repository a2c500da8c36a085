"""Attitude columns one by one (issue 30): a log with heading and roll but no pitch (an ADS-B
derived log) keeps its logged heading and roll; only pitch is estimated from the climb."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from host_sim.replay import load_track
from host_sim.replay.attitude import G_MPS2
from host_sim.replay.report import format_report, replay_report

#: A wind across the track: the nose points off the track by the crab angle, which the
#: track-based estimate cannot know and a logged heading does.
WIND_EAST_MPS = 12.0
AIRSPEED_MPS = 60.0
CLIMB_MPS = 5.0


def turning_climb(n: int = 300):
    """(t, x, y, z, heading, pitch, roll) of a climb at 1 Hz: a right turn at 3 deg/s, a
    straight leg, then a left turn at 2 deg/s, in a wind from the west. Positions are the
    airspeed along the heading plus the wind."""
    rows, x, y, heading = [], 0.0, 0.0, 0.0
    for k in range(n):
        rate = 3.0 if k < 120 else 0.0 if k < 200 else -2.0
        roll = math.degrees(math.atan(AIRSPEED_MPS * math.radians(rate) / G_MPS2))
        pitch = math.degrees(math.atan2(CLIMB_MPS, AIRSPEED_MPS))
        rows.append((float(k), x, y, 300.0 + CLIMB_MPS * k, heading % 360.0, pitch, roll))
        h = math.radians(heading + rate / 2.0)  # the mean heading over the next second
        x += AIRSPEED_MPS * math.sin(h) + WIND_EAST_MPS
        y += AIRSPEED_MPS * math.cos(h)
        heading += rate
    return rows


def write(path: Path, rows, *, heading: bool, roll: bool) -> Path:
    """A world-frame CSV with a heading_deg, pitch_deg and roll_deg column each, the pitch
    column empty in every row and heading and roll empty unless asked for."""
    lines = ["time_s,x_m,y_m,z_m,heading_deg,pitch_deg,roll_deg"]
    for t, x, y, z, h, _p, r in rows:
        lines.append(f"{t:.3f},{x:.3f},{y:.3f},{z:.3f},{f'{h:.4f}' if heading else ''},,"
                     f"{f'{r:.4f}' if roll else ''}")
    path.write_text("\n".join(lines) + "\n")
    return path


def heading_errors(track, rows) -> np.ndarray:
    """|replayed heading - logged heading| at every record, degrees (the short way round)."""
    replayed = np.array([track.sample(t).heading_deg for t in track.t_s])
    logged = np.array([r[4] for r in rows])
    return np.abs((replayed - logged + 180.0) % 360.0 - 180.0)


def test_logged_heading_and_roll_are_kept_when_pitch_has_no_values(tmp_path):
    rows = turning_climb()
    track, _ = load_track(write(tmp_path / "adsb.csv", rows, heading=True, roll=True))
    # Under "all three or none" the empty pitch column made the whole attitude estimated:
    # heading off by the crab angle and the turn's lag (see the figures below).
    assert not track.attitude_estimated
    err = heading_errors(track, rows)
    assert err.max() < 1e-3
    roll = np.array([track.sample(t).roll_deg for t in track.t_s])
    assert np.abs(roll - [r[6] for r in rows]).max() < 1e-3
    # Pitch from the climb: the flight-path angle over the ground (the wind changes the ground
    # speed through the turn), within a degree once the estimate's window is full.
    xy = np.array([r[1:3] for r in rows])
    ground_speed = np.hypot(*np.gradient(xy, axis=0).T)
    path_angle = np.degrees(np.arctan2(CLIMB_MPS, ground_speed))
    pitch = np.array([track.sample(t).pitch_deg for t in track.t_s])
    assert np.abs(pitch - path_angle)[30:-30].max() < 1.0
    assert (track.column_source[:, 1] == "air").all()


def test_the_estimate_the_old_rule_gave_is_far_off_the_logged_heading(tmp_path):
    # The same flight with no attitude column that has values: the whole attitude is
    # estimated, as "all three or none" did for the log above. The crab angle of the wind
    # (about 11 degrees on the straight leg) alone puts it off the logged heading.
    rows = turning_climb()
    track, _ = load_track(write(tmp_path / "none.csv", rows, heading=False, roll=False))
    assert track.attitude_estimated
    assert np.percentile(heading_errors(track, rows), 99) > 5.0


def test_the_report_says_which_column_came_from_where(tmp_path):
    rows = turning_climb()
    path = write(tmp_path / "adsb.csv", rows, heading=True, roll=True)
    track, fmt = load_track(path)
    doc = replay_report(track, path=str(path), format=fmt)
    n = len(rows)
    assert doc["attitude_columns"] == {
        "heading_deg": {"source": "logged", "logged": n, "interpolated": 0, "estimated": 0},
        "pitch_deg": {"source": "estimated", "logged": 0, "interpolated": 0, "estimated": n},
        "roll_deg": {"source": "logged", "logged": n, "interpolated": 0, "estimated": 0},
    }
    assert doc["attitude"] == "per column: heading logged, pitch estimated, roll logged"
    assert doc["attitude_segments"][0]["source"] == "heading logged, pitch estimated in the air, roll logged"
    text = format_report(doc)
    assert "pitch_deg    estimated (estimated 300)" in text


def test_a_long_dropout_of_one_column_is_estimated_in_that_column_only(tmp_path):
    # Heading lost for 60 s in the middle (longer than a gap): those records take the
    # estimated heading; roll stays logged throughout, so the report says "mixed" for heading.
    rows = turning_climb()
    lines = write(tmp_path / "d.csv", rows, heading=True, roll=True).read_text().splitlines()
    for k in range(100, 160):
        cells = lines[1 + k].split(",")
        cells[4] = ""
        lines[1 + k] = ",".join(cells)
    path = tmp_path / "d.csv"
    path.write_text("\n".join(lines) + "\n")
    track, fmt = load_track(path)
    doc = replay_report(track, path=str(path), format=fmt)
    heading = doc["attitude_columns"]["heading_deg"]
    assert heading["source"] == "mixed" and heading["estimated"] == 60
    assert doc["attitude_columns"]["roll_deg"]["source"] == "logged"
    err = heading_errors(track, rows)
    assert err[:100].max() < 1e-3 and err[160:].max() < 1e-3
