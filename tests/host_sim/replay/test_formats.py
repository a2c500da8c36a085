"""Every replay format reads the same flight; damaged records are counted and skipped."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host_sim.replay import detect_format, load_track

from .logs import ORIGIN, flight, igc_b, write_csv, write_fdr, write_igc, write_ulog

pytest.importorskip("pyulog", reason="pyulog is in the devices extra")

ROWS = flight()


def expected_position(t):
    """The flight's ENU position at a record time (the logs store positions at ~1e-9 deg)."""
    from services.rig.geodetic import enu
    row = ROWS[int(t)]
    return enu(np.array([row[1]]), np.array([row[2]]), np.array([row[3]]), ORIGIN)[0]


@pytest.mark.parametrize("name,writer,fmt,tol_m", [
    ("f.csv", write_csv, "csv", 1e-3),
    ("f.igc", write_igc, "igc", 2.0),  # IGC stores thousandths of minutes (~1.85 m) and whole metres
    ("f.fdr", write_fdr, "fdr", 1e-3),
    ("f.ulg", write_ulog, "ulog", 0.5),  # float32 altitude
])
def test_each_format_reads_the_flight(tmp_path, name, writer, fmt, tol_m):
    path = writer(tmp_path / name, ROWS)
    assert detect_format(path) == fmt
    track, got = load_track(path, origin=ORIGIN)
    assert got == fmt and len(track.t_s) == len(ROWS) and not any(track.problems.values())
    for t in (0.0, 7.0, 19.0):
        np.testing.assert_allclose(track.sample(t).position, expected_position(t), atol=tol_m)
    e = track.sample(10.0)
    if fmt == "igc":  # no attitude in IGC: estimated from the track
        assert track.attitude_estimated
        assert e.heading_deg == pytest.approx(330.0, abs=1.0)
        assert e.roll_deg == pytest.approx(-math.degrees(math.atan(30.0 * math.radians(3.0) / 9.80665)), abs=1.0)
    else:
        assert not track.attitude_estimated
        # (ULog attitudes are logged 5 ms after the positions: 0.015 degrees of turn)
        assert (e.heading_deg, e.pitch_deg, e.roll_deg) == pytest.approx((330.0, 2.0, -17.0), abs=0.02)


def test_the_first_fix_is_the_default_origin(tmp_path):
    track, _ = load_track(write_csv(tmp_path / "f.csv", ROWS))
    np.testing.assert_array_equal(track.sample(0.0).position, [0.0, 0.0, 0.0])
    assert track.origin == pytest.approx(ROWS[0][1:4])


def test_world_frame_csv_is_used_as_is(tmp_path):
    path = tmp_path / "w.csv"
    path.write_text("x_m,y_m,z_m,time_s,other\n0,-900,3,0.0,a\n0,-860,3,1.0,b\n0,-800,5,2.0,c\n")
    track, _ = load_track(path)
    assert track.origin is None and track.attitude_estimated
    np.testing.assert_allclose(track.sample(1.0).position, [0.0, -860.0, 3.0])


def test_csv_with_damaged_rows(tmp_path):
    # Lines 6-10 of the file: a row with attitude only, no time, refused cells, blank, comment.
    path = write_csv(tmp_path / "f.csv", ROWS, extra_lines=[
        (5, "3.5,,,,340.5,2,-17"), (6, "not,a,row"), (7, "4.5,95.0,,,,95,-17"), (8, ""),
        (9, "# a comment in the middle")])
    track, _ = load_track(path)
    assert track.problems["corrupt"] == 1 and track.problems["out_of_range"] == 2
    assert len(track.t_s) == len(ROWS) + 2  # the rows at 3.5 and 4.5 s are kept for their attitude
    assert any("line 7: time_s = 'not' is not a number" in n for n in track.notes)
    assert any("line 8: lat_deg = 95 outside [-90, 90]" in n for n in track.notes)
    assert any("line 8: pitch_deg = 95 outside [-90, 90]" in n for n in track.notes)
    assert track.records_read == len(ROWS) + 3


def test_csv_header_problems_are_named(tmp_path):
    for text, words in [("", "empty CSV log"), ("a,b\n1,2\n", "has neither lat_deg"),
                        ("lat_deg,lon_deg,alt_m\n1,2,3\n", "has no time_s")]:
        path = tmp_path / "h.csv"
        path.write_text(text)
        with pytest.raises(ValueError, match=words):
            load_track(path)


def test_igc_damage_no_fix_and_midnight(tmp_path):
    rows = flight(30)
    path = write_igc(tmp_path / "f.igc", rows, start_s=23 * 3600 + 59 * 60 + 50, extra=[
        (8, "B1200xx4630000N00700000EA0070000700"),  # damaged digits
        (9, igc_b(0, 46.5, 7.0, 700, valid="V")),  # no fix
        (10, "B12"),  # cut short
        (11, "B2500004630000N00700000EA0070000700"),  # hour 25
    ])
    track, _ = load_track(path)
    assert track.problems["corrupt"] == 2 and track.problems["no_fix"] == 1
    assert track.problems["out_of_range"] == 1
    assert any("line 12: hours = 25 outside 0 .. 23" in n for n in track.notes)
    assert track.duration_s == pytest.approx(29.0)  # across midnight UTC without a jump
    assert track.problems["out_of_order"] == 0 and track.problems["gap"] == 0


def test_igc_without_gnss_altitude_uses_pressure_altitude(tmp_path):
    path = write_igc(tmp_path / "f.igc", ROWS)
    text = path.read_text().splitlines()
    text = [line[:30] + "00000" + line[35:] if line.startswith("B") else line for line in text]
    path.write_text("\r\n".join(text) + "\r\n")
    track, _ = load_track(path, origin=(ORIGIN[0], ORIGIN[1], ORIGIN[2] + 90.0))
    assert track.sample(0.0).position[2] == pytest.approx(0.0, abs=1.0)  # pressure alt = GNSS - 30 in logs.py


def test_fdr_damaged_lines(tmp_path):
    path = write_fdr(tmp_path / "f.fdr", ROWS, extra=[(15, "DATA,1.5,15,7.0"), (16, "DATA,x,y,z,1,2,3,4,5,6,7,8,9"),
                                                      (17, "DATA,2.5,15,200.0,46.5,1000,0,0,0,0,0,0,0"),
                                                      (18, "COMM,comments are skipped")])
    track, _ = load_track(path)
    assert track.problems["corrupt"] == 2 and track.problems["out_of_range"] == 1 and len(track.t_s) == len(ROWS)
    assert any("line 18: lon_deg = 200 outside [-180, 180]" in n for n in track.notes)


def test_ulog_damage_and_missing_attitude(tmp_path):
    track, _ = load_track(write_ulog(tmp_path / "d.ulg", ROWS, damage=True))
    assert track.problems["corrupt"] == 1 and len(track.t_s) == len(ROWS)
    track, _ = load_track(write_ulog(tmp_path / "n.ulg", ROWS, attitude=False))
    assert track.attitude_estimated


def test_unknown_formats_and_files_are_named(tmp_path):
    path = tmp_path / "f.log"
    path.write_text("hello")
    with pytest.raises(ValueError, match=r"f.log: cannot tell the log format .* --replay-format"):
        load_track(path)
    with pytest.raises(ValueError, match="format 'kml' is not one of"):
        load_track(path, format="kml")
    with pytest.raises(ValueError, match="no such file"):
        load_track(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="not a readable ULog"):
        load_track(path, format="ulog")
    ulog = write_ulog(tmp_path / "u.bin", ROWS)
    assert detect_format(ulog) == "ulog"  # by its magic bytes
