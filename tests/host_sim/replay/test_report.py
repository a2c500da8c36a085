"""`ig host --replay LOG --report`: what the replay made of a log, and its plot."""

from __future__ import annotations

import json
import math

import numpy as np

from host_sim.replay import load_track
from host_sim.replay.report import format_report, plot_replay, replay_report
from services.cli import main
from services.rig import geodetic

from .logs import ORIGIN, csv_cells, flight, igc_b, straight, write_csv


def _messy_csv(tmp_path):
    rows = flight(40)
    path = tmp_path / "messy.csv"
    lines = ["time_s,lat_deg,lon_deg,alt_m,heading_deg,pitch_deg,roll_deg",
             *csv_cells(rows, blanks={(5, 5), (6, 5), (12, 6), (20, 1), (20, 2), (20, 3)})]
    lines.insert(15, "1e300,46.5,7.0,700,0,0,0")          # out of physics: refused, line named
    lines.insert(25, "27.5,46.5,7.0,700,0,95,0")           # pitch 95: that cell refused
    path.write_text("\n".join(lines) + "\n")
    return path


def test_the_report_counts_what_was_read_used_filled_and_dropped(tmp_path):
    path = _messy_csv(tmp_path)
    track, fmt = load_track(path)
    doc = replay_report(track, path=str(path), format=fmt)
    assert doc["records_read"] == 42 and doc["records_used"] == len(track.t_s)
    assert doc["dropped"].get("out_of_range", 0) >= 2
    assert doc["interpolated"]["pitch_deg"] >= 2 and doc["interpolated"]["roll_deg"] >= 1
    assert 0.9 < doc["coverage"]["pitch_deg"] < 1.0 and doc["coverage"]["heading_deg"] == 1.0
    assert doc["attitude"] == "logged"
    # The records whose pitch or roll cell was empty are told apart from the logged ones.
    segments = doc["attitude_segments"]
    assert {s["source"] for s in segments} == {"logged", "logged, interpolated across short dropouts"}
    assert sum(s["records"] for s in segments) == len(track.t_s)
    assert sum(s["records"] for s in segments if s["source"] != "logged") == 3
    assert doc["largest_gap"]["seconds"] >= 1.0
    json.dumps(doc)  # JSON-able as it stands
    text = format_report(doc)
    assert "records read 42" in text and "out_of_range" in text and "pitch_deg" in text


def test_a_taxi_then_take_off_reports_its_ground_segment_and_assumptions(tmp_path):
    # IGC (no attitude): 60 s of taxi at 8 m/s with metres of altitude noise, then a climb.
    rng = np.random.default_rng(3)
    lines = ["AXXX001 test logger", "HFDTE010725"]
    north = 0.0
    for k in range(180):
        speed = 8.0 if k < 60 else min(60.0, 8.0 + (k - 60) * 2.0)
        north += speed
        climb = 0.0 if k < 80 else (k - 80) * 3.0
        h = ORIGIN[2] + climb + rng.uniform(-3.0, 3.0)
        lines.append(igc_b(12 * 3600 + k, ORIGIN[0] + north / 111_200.0, ORIGIN[1], h) + "000")
    path = tmp_path / "taxi.igc"
    path.write_text("\n".join(lines) + "\n")
    track, fmt = load_track(path)
    doc = replay_report(track, path=str(path), format=fmt)
    sources = [s["source"] for s in doc["attitude_segments"]]
    assert sources[0] == "estimated on the ground" and "estimated in the air" in sources
    assert doc["attitude"] == "estimated" and doc["assumptions"]
    ground = np.asarray(track.attitude_source) == "ground"
    pitch = np.array([track.sample(t).pitch_deg for t in track.t_s[ground]])
    assert np.abs(pitch).max() < 2.0  # not the +-50 degrees of neighbouring noisy fixes
    assert "the estimate assumes:" in format_report(doc)


def test_the_plot_is_written(tmp_path):
    track, _ = load_track(_messy_csv(tmp_path))
    out = plot_replay(track, tmp_path / "plots" / "messy.png", title="messy.csv")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_ig_host_report_prints_plots_and_exits_without_serving(tmp_path, capsys):
    path = _messy_csv(tmp_path)
    png = tmp_path / "r.png"
    assert main(["host", "--replay", str(path), "--report", str(png)]) == 0
    out = capsys.readouterr().out
    assert "replay report:" in out and "records read 42" in out and str(png) in out
    assert png.is_file()


def test_report_needs_a_replay(capsys):
    assert main(["host", "--report"]) == 2
    assert "--report only applies with --replay" in capsys.readouterr().err


def test_logged_attitude_far_from_the_origin_is_turned_into_the_world_frame(tmp_path):
    # Level flight due north 600 km north of the origin, logged against the local horizontal:
    # in the origin's tangent plane the local horizontal is tilted by the change of vertical.
    rows = [(t, lat, lon, h, 0.0, 0.0, 0.0) for t, lat, lon, h, *_ in straight(30)]
    far = [(t, lat + 600_000.0 / 111_200.0, lon, h, 0.0, 0.0, 0.0) for t, lat, lon, h, *_ in rows]
    path = write_csv(tmp_path / "far.csv", far)
    track, _ = load_track(path, origin=ORIGIN)
    eye = track.sample(10.0)
    tilt = geodetic.vertical_angle_deg(far[10][1], far[10][2], ORIGIN)
    assert 5.0 < tilt < 5.8
    assert math.isclose(eye.pitch_deg, -tilt, abs_tol=0.05)
    # At the origin nothing turns.
    near, _ = load_track(write_csv(tmp_path / "near.csv", rows), origin=ORIGIN)
    assert abs(near.sample(10.0).pitch_deg) < 1e-3
