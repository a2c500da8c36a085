"""Logs shaped like real recordings: empty cells, misdated records, duplicates, values outside
physics, and garbage between good records (docs/replay-formats.md "Cleaning")."""

from __future__ import annotations

import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host_sim.replay import load_track
from host_sim.replay.track import MAX_SPEED_MPS, RawLog, build_track

from .logs import ORIGIN, csv_cells, flight, igc_b, straight, write_fdr, write_igc, write_ulog

HEAD = "time_s,lat_deg,lon_deg,alt_m,heading_deg,pitch_deg,roll_deg"
FRAME_HZ = 30.0


def write_lines(path: Path, lines) -> Path:
    path.write_text("\n".join([HEAD, *lines]) + "\n")
    return path


def enu(row):
    from services.rig.geodetic import enu as to_enu
    return to_enu(np.array([row[1]]), np.array([row[2]]), np.array([row[3]]), ORIGIN)[0]


def largest_frame_step(track) -> float:
    """The longest way the eye moves between two frames at FRAME_HZ, metres."""
    times = np.arange(0.0, track.duration_s, 1.0 / FRAME_HZ)
    pos = np.array([track.sample(t).position for t in times])
    return float(np.max(np.linalg.norm(np.diff(pos, axis=0), axis=1)))


# -- empty cells ---------------------------------------------------------------------------

def test_empty_cells_are_interpolated_per_column_and_the_rest_of_the_row_is_kept(tmp_path):
    rows = flight(40)
    # pitch missing at row 5, roll at 6-7, heading at 1 (between 0 and 357: through north),
    # the whole position at 10, only the longitude at 20.
    blanks = {(5, 5), (6, 6), (7, 6), (1, 4), (10, 1), (10, 2), (10, 3), (20, 2)}
    track, _ = load_track(write_lines(tmp_path / "f.csv", csv_cells(rows, blanks)), origin=ORIGIN)
    assert len(track.t_s) == 40 and not any(track.problems.values())
    assert track.coverage == {"position": 38 / 40, "heading_deg": 39 / 40, "pitch_deg": 39 / 40, "roll_deg": 38 / 40}
    assert track.interpolated == {"position": 2, "heading_deg": 1, "pitch_deg": 1, "roll_deg": 2}
    assert track.records_read == 40
    # the filled cells: positions on the flight within the chord of a 573 m turn, angles as flown
    for k in (10, 20):
        np.testing.assert_allclose(track.sample(float(k)).position, enu(rows[k]), atol=2.0)
    e = track.sample(1.0)
    assert e.heading_deg == pytest.approx(357.0, abs=0.01)  # the short way through 0/360
    # the row's own values are kept: heading, roll and the position of row 5 (pitch missing)
    e = track.sample(5.0)
    assert (e.heading_deg, e.pitch_deg, e.roll_deg) == pytest.approx((345.0, 2.0, -17.0), abs=0.01)
    np.testing.assert_allclose(e.position, enu(rows[5]), atol=1e-3)
    assert track.logged_hpr is not None and np.isnan(track.logged_hpr[5, 1]) and np.isnan(track.logged_hpr[6, 2])
    assert track.logged_hpr[5, 2] == pytest.approx(-17.0)


def test_a_wholly_empty_attitude_column_is_estimated_alone(tmp_path):
    # Pitch empty in every row: heading and roll stay as logged, only pitch is estimated.
    rows = flight(20)
    track, _ = load_track(write_lines(tmp_path / "f.csv", csv_cells(rows, {(i, 5) for i in range(20)})))
    assert not track.attitude_estimated and track.logged_hpr is not None
    assert track.coverage["pitch_deg"] == 0.0 and track.coverage["heading_deg"] == 1.0
    assert any("pitch_deg has no value" in n for n in track.notes)
    assert (track.column_source[:, 0] == "logged").all() and (track.column_source[:, 2] == "logged").all()
    assert set(track.column_source[:, 1]) <= {"air", "ground"}
    assert set(track.attitude_source) == {"mixed"}
    e = track.sample(5.0)
    assert (e.heading_deg, e.roll_deg) == pytest.approx((rows[5][4], -17.0), abs=0.05)


def test_rows_without_a_position_beyond_the_first_and_last_fix_are_counted(tmp_path):
    rows = flight(20)
    lines = ["-1.0,,,,0,2,-17", *csv_cells(rows), "25.0,,,,0,2,-17", "26.0,,,,,,"]
    track, _ = load_track(write_lines(tmp_path / "f.csv", lines))
    assert track.problems["no_position"] == 3 and len(track.t_s) == 20 and track.records_read == 23


def test_a_non_numeric_cell_is_refused_alone(tmp_path):
    rows = flight(20)
    lines = csv_cells(rows)
    lines[7] = lines[7].rsplit(",", 1)[0] + ",n/a"  # roll of the row at 7 s, line 9 of the file
    track, _ = load_track(write_lines(tmp_path / "f.csv", lines))
    assert track.problems["corrupt"] == 1 and len(track.t_s) == 20
    assert any("line 9: roll_deg = 'n/a' is not a number" in n for n in track.notes)
    assert track.interpolated["roll_deg"] == 1


def test_a_position_column_without_any_value_is_named(tmp_path):
    rows = flight(5)
    with pytest.raises(ValueError, match="column lon_deg has no value in any row"):
        load_track(write_lines(tmp_path / "f.csv", csv_cells(rows, {(i, 2) for i in range(5)})))


# -- values outside physics ----------------------------------------------------------------

@pytest.mark.parametrize("cell,value,field", [(0, "-1e300", "time_s"), (5, "95", "pitch_deg"),
                                              (6, "-181", "roll_deg"), (3, "250000", "alt_m"),
                                              (4, "inf", "heading_deg")])
def test_values_outside_physics_are_refused_with_field_value_and_line(tmp_path, cell, value, field):
    rows = flight(20)
    lines = csv_cells(rows)
    cells = lines[10].split(",")
    cells[cell] = value
    lines[10] = ",".join(cells)  # line 12 of the file
    track, _ = load_track(write_lines(tmp_path / "f.csv", lines))
    assert track.problems["out_of_range"] == 1
    assert len(track.t_s) == (19 if field == "time_s" else 20)  # a row needs its time; else kept
    note = next(n for n in track.notes if n.startswith("out_of_range"))
    assert f"line 12: {field} = " in note and (value.lstrip("-") in note or "e+300" in note or "not finite" in note)


def test_other_readers_refuse_values_outside_physics(tmp_path):
    rows = flight(20)
    fdr = write_fdr(tmp_path / "f.fdr", rows, extra=[
        (15, "DATA,3.5,15,7.0,46.5,2000,0,0,0,0,95,0,0"),  # pitch 95
        (16, "DATA,-1e300,15,7.0,46.5,2000,0,0,0,0,5,0,0")])
    track, _ = load_track(fdr)
    assert track.problems["out_of_range"] == 2 and len(track.t_s) == 20
    assert any("line 16: pitch_deg = 95 outside [-90, 90]" in n for n in track.notes)
    assert any("line 17: time_s = -1e+300 outside" in n for n in track.notes)
    igc = write_igc(tmp_path / "f.igc", rows, extra=[(9, "B1200049030000N00700000EA0070000700000")])
    track, _ = load_track(igc)  # latitude 90 degrees 30 minutes
    assert track.problems["out_of_range"] == 1 and len(track.t_s) == 20
    assert any("line 10: lat_deg = 90.5 outside [-90, 90]" in n for n in track.notes)


def test_ulog_positions_outside_physics_are_refused(tmp_path):
    pytest.importorskip("pyulog")
    rows = flight(20)
    rows[4] = (rows[4][0], 1000.0, *rows[4][2:])
    track, _ = load_track(write_ulog(tmp_path / "f.ulg", rows))
    assert track.problems["out_of_range"] == 1 and len(track.t_s) == 19 and track.records_read == 20
    assert any("position 5: lat_deg = 1000 outside" in n for n in track.notes)


# -- misdated records ----------------------------------------------------------------------

def test_a_clock_step_record_is_dropped_and_the_eye_never_jumps(tmp_path):
    rows = straight()
    k = 250
    rows[k] = (50.5, *rows[k][1:])  # the fix of 250 s stamped 50.5 s: 12 km from its neighbours
    track, _ = load_track(write_lines(tmp_path / "f.csv", csv_cells(rows)))
    assert track.problems["misdated"] == 1 and len(track.t_s) == 299
    assert track.problems["out_of_order"] == 0 and track.problems["impossible_motion"] == 0
    assert 50.5 not in track.t_s
    note = next(n for n in track.notes if n.startswith("misdated"))
    assert f"line {k + 2} at t=50.500 s lies a gap away" in note
    # the eye moves no further in a frame than the aircraft flies (60 m/s), well under the limit
    assert largest_frame_step(track) <= 1.01 * 60.0 / FRAME_HZ < MAX_SPEED_MPS / FRAME_HZ


def test_a_misdated_igc_fix_that_is_first_of_a_duplicate_is_the_one_dropped(tmp_path):
    rows = straight()
    bad = rows[50]
    rows[50] = (150.0, *bad[1:])  # written where the fix of 50 s belongs, stamped 150 s
    track, _ = load_track(write_igc(tmp_path / "f.igc", rows), origin=ORIGIN)
    # Its time is a gap away from the fixes around it in the file: misdated, before it can be
    # taken for a duplicate of the good fix of 150 s.
    assert track.problems["misdated"] == 1 and track.problems["duplicate"] == 0 and len(track.t_s) == 299
    np.testing.assert_allclose(track.sample(150.0).position, enu(straight()[150]), atol=3.0)
    assert largest_frame_step(track) <= 1.2 * 60.0 / FRAME_HZ
    note = next(n for n in track.notes if n.startswith("misdated"))
    assert "line 55 at t=" in note  # 4 header lines before the fixes


def test_a_duplicate_time_keeps_the_record_that_fits_its_neighbours(tmp_path):
    rows = straight()
    # A second record at 150 s, 3 km off the line (a glitch of the receiver, not a wrong time),
    # written first: the good one after it is kept.
    glitch = (150.0, rows[150][1] + 0.03, *rows[150][2:])
    lines = csv_cells(rows)
    lines.insert(150, csv_cells([glitch])[0])
    track, _ = load_track(write_lines(tmp_path / "f.csv", lines), origin=ORIGIN)
    assert track.problems["duplicate"] == 1 and len(track.t_s) == 300
    np.testing.assert_allclose(track.sample(150.0).position, enu(straight()[150]), atol=3.0)


def test_a_date_rollover_beyond_the_end_of_the_log_does_not_stretch_the_replay(tmp_path):
    rows = straight(60)
    rows[30] = (30.0 + 23 * 86400.0, *rows[30][1:])  # the date rolled over: 23 days late
    track, _ = load_track(write_lines(tmp_path / "f.csv", csv_cells(rows)))
    assert track.problems["misdated"] == 1 and len(track.t_s) == 59
    assert track.duration_s == 59.0 and track.problems["gap"] == 0


def test_a_real_pause_and_a_log_written_out_of_order_lose_nothing(tmp_path):
    rows = straight(60)
    paused = [(t + (3600.0 if t >= 30 else 0.0), *r) for t, *r in rows]  # an hour's pause
    track, _ = load_track(write_lines(tmp_path / "p.csv", csv_cells(paused)))
    assert track.problems["misdated"] == 0 and len(track.t_s) == 60 and track.problems["gap"] == 1
    swapped = paused[30:] + paused[:30]  # two parts of a log concatenated the wrong way round
    track, _ = load_track(write_lines(tmp_path / "s.csv", csv_cells(swapped)))
    assert track.problems["misdated"] == 0 and len(track.t_s) == 60 and track.problems["out_of_order"] == 30


def test_the_duplicate_that_fits_the_neighbours_is_kept_wherever_it_is_in_the_file():
    t = [0.0, 1.0, 2.0, 2.0, 3.0, 4.0]
    for bad_first in (True, False):
        pos = [(50.0 * x, 0.0, 100.0) for x in t]
        pos[2 if bad_first else 3] = (9000.0, 0.0, 100.0)
        track = build_track(RawLog(times=t, coords=pos, geodetic=False))
        assert track.problems["duplicate"] == 1 and track.sample(2.0).position[0] == pytest.approx(100.0)


@pytest.mark.parametrize("k", [2, 8, 50, 97])
@pytest.mark.parametrize("step_s", [12.5, -12.5])
def test_a_small_clock_step_is_misdated_wherever_it_is_in_the_file(k, step_s):
    # Just past the tolerance (5 s gap threshold + 5 intervals): a window of eleven records
    # that holds the record off its centre (near an end, or on the side its time went) has its
    # median nearer the wrong time by the offset, and must not vouch for it.
    t = np.arange(100.0)
    t[k] += step_s
    track = build_track(RawLog(times=list(t), coords=[(20.0 * x, 0.0, 500.0) for x in range(100)],
                               geodetic=False))
    assert track.problems["misdated"] == 1 and len(track.t_s) == 99


def test_good_records_around_a_bad_one_are_kept():
    t = np.arange(30.0)
    pos = np.stack([80.0 * t, 10.0 * np.sin(t / 3.0), 500.0 + t], axis=1)
    for bad in (0, 1, 15, 28, 29):
        p = pos.copy()
        p[bad] += (13_000.0, -4_000.0, 0.0)
        track = build_track(RawLog(times=list(t), coords=[tuple(r) for r in p], geodetic=False))
        assert track.problems["impossible_motion"] == 1, bad
        assert len(track.t_s) == 29 and (t[bad] - t[0] - track.start_time + t[0]) not in track.t_s + track.start_time


def test_two_adjacent_misdated_records_are_both_dropped():
    t = np.arange(30.0)
    pos = np.stack([60.0 * t, 0 * t, 500.0 + 0 * t], axis=1)
    pos[[12, 13]] += (11_000.0, 0.0, 0.0)
    track = build_track(RawLog(times=list(t), coords=[tuple(r) for r in pos], geodetic=False))
    assert track.problems["impossible_motion"] == 2 and len(track.t_s) == 28


def test_a_log_that_is_fast_throughout_is_kept_and_reported():
    t = np.arange(20.0)
    pos = np.stack([600.0 * t, 0 * t, 500.0 + 0 * t], axis=1)  # 600 m/s: not the rig's aircraft
    track = build_track(RawLog(times=list(t), coords=[tuple(r) for r in pos], geodetic=False))
    assert len(track.t_s) == 20 and track.problems["impossible_motion"] == 0
    assert any("none dropped" in n for n in track.notes)


def test_a_partial_position_far_off_is_dropped(tmp_path):
    rows = straight(40)
    lines = csv_cells(rows)
    lines.insert(21, "20.5,46.9,,,,,")  # only a latitude, 44 km north
    track, _ = load_track(write_lines(tmp_path / "f.csv", lines))
    assert track.problems["impossible_motion"] == 1 and len(track.t_s) == 40


# -- garbage between good records ----------------------------------------------------------

CELL = st.one_of(st.just(""), st.just("nan"), st.text(max_size=6),
                 st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.floats(-200.0, 200.0).map(lambda v: f"{v:.4f}"))
GOOD = flight(20)
T0 = 100.0  # the good records' times from T0 (garbage times shrink towards 0: before them)


def good_rows():
    return [(T0 + r[0], *r[1:]) for r in GOOD]


def assert_good_records_kept(track, tol_m: float) -> None:
    times = track.start_time + track.t_s
    for row in good_rows():
        k = int(np.argmin(np.abs(times - row[0])))
        assert times[k] == pytest.approx(row[0], abs=1e-6), f"record at {row[0]} lost"
        e = track.sample(float(times[k] - track.start_time))
        np.testing.assert_allclose(e.position, enu_at(track, row), atol=tol_m)


def enu_at(track, row):
    from services.rig.geodetic import enu as to_enu
    return to_enu(np.array([row[1]]), np.array([row[2]]), np.array([row[3]]), track.origin)[0]


def load_or_refuse(path: Path):
    try:
        return load_track(path)[0]
    except ValueError as exc:
        assert path.name in str(exc) or "column" in str(exc)
        return None


FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.lists(st.tuples(st.integers(0, 20), st.one_of(st.text(max_size=40),
                                                         st.lists(CELL, max_size=9).map(",".join))),
                max_size=6))
def test_csv_garbage_never_crashes_and_never_costs_good_records(garbage):
    lines = csv_cells(good_rows())
    for at, text in sorted(garbage, reverse=True):
        lines.insert(at, text.replace("\n", " ").replace("\r", " "))
    with tempfile.TemporaryDirectory() as d:
        track = load_or_refuse(write_lines(Path(d) / "g.csv", lines))
    assert track is not None  # twenty good records are always enough
    assert_good_records_kept(track, tol_m=2.0)


def test_csv_garbage_around_the_first_good_record_cannot_outvote_it(tmp_path):
    # The CSV form of the IGC case below (the cleaning is the same): a garbage row at t=0
    # written twice before the first good record and once after it made the first good
    # record's narrow centred window mostly garbage, and it was dropped as misdated.
    junk = "0.0000,0.0000,0.0000,0.0000"
    lines = csv_cells(good_rows())
    for at in (1, 0, 0):
        lines.insert(at, junk)
    track, _ = load_track(write_lines(tmp_path / "g.csv", lines))
    assert_good_records_kept(track, tol_m=2.0)
    assert track.problems["misdated"] == 0


IGC_GARBAGE = st.one_of(
    st.text(max_size=40).map(lambda s: "B" + s),
    st.builds(lambda t, lat, lon, h: igc_b(t, lat, lon, h) + "000", st.integers(0, 86399),
              st.floats(-89.9, 89.9), st.floats(-179.9, 179.9), st.integers(0, 9999)))


@FUZZ
@given(st.lists(st.tuples(st.integers(4, 24), IGC_GARBAGE), max_size=6))
def test_igc_garbage_never_crashes_and_never_costs_good_records(garbage):
    with tempfile.TemporaryDirectory() as d:
        path = write_igc(Path(d) / "g.igc", GOOD, start_s=int(12 * 3600 + T0),
                         extra=[(at, text.replace("\n", " ").replace("\r", " ")) for at, text in
                                sorted(garbage, reverse=True)])
        track = load_or_refuse(path)
    assert track is not None
    times = track.start_time + track.t_s
    for row in GOOD:  # IGC times are the time of day
        assert np.min(np.abs(times - (12 * 3600 + T0 + row[0]))) < 1e-6


def test_repeated_garbage_near_the_start_cannot_outvote_the_good_records(tmp_path):
    # Found by the fuzz test above on a fresh clone: one garbage fix written three times among
    # the first five records made the window around the second good record mostly garbage,
    # and that record was dropped as misdated. It agrees in time with the first good record,
    # which is not judged, so it stays; the repeats are duplicates of one another.
    junk = igc_b(0, 0.0, 0.0, 0) + "000"
    path = write_igc(tmp_path / "r.igc", GOOD, start_s=int(12 * 3600 + T0),
                     extra=[(6, junk), (6, junk), (4, junk)])
    track, _ = load_track(path)
    times = track.start_time + track.t_s
    for row in GOOD:
        assert np.min(np.abs(times - (12 * 3600 + T0 + row[0]))) < 1e-6
    assert track.problems["duplicate"] == 2


def test_a_record_agreeing_with_its_neighbour_is_not_misdated_among_wrong_times(tmp_path):
    # Three garbage fixes of different times, all before the log, around its first two good
    # records: the narrow windows near the start are mostly wrong times, but the second good
    # record agrees with the first, which is not judged, so it stays.
    junk = [igc_b(t, 1.0, 1.0, 100) + "000" for t in (5000, 20000, 30000)]
    path = write_igc(tmp_path / "d.igc", GOOD, start_s=int(12 * 3600 + T0),
                     extra=[(6, junk[2]), (6, junk[1]), (4, junk[0])])
    track, _ = load_track(path)
    times = track.start_time + track.t_s
    for row in GOOD:
        assert np.min(np.abs(times - (12 * 3600 + T0 + row[0]))) < 1e-6


def test_garbage_around_the_first_good_record_cannot_outvote_it(tmp_path):
    # Found by the fuzz test above: one garbage fix at 00:00:00 (0 degrees N, 0 E) written
    # three times, twice before the first good fix and once between it and the second. The
    # first good fix is third in the file, so its centred window was the first five records,
    # three of them garbage: their time was the window's median and the good fix was "far";
    # its file neighbours are both garbage, so none vouched for it, and the longest run in
    # time order, a tie between the three zeros and the log after it and two zeros and the
    # whole log, was taken as the former: out of order, it was dropped as misdated. A window
    # of eleven records that holds it (the first eleven) is mostly good records.
    junk = igc_b(0, 0.0, 0.0, 0) + "000"
    path = write_igc(tmp_path / "f.igc", GOOD, start_s=int(12 * 3600 + T0),
                     extra=[(5, junk), (4, junk), (4, junk)])
    assert path.read_text().splitlines()[4:9] == [junk, junk, igc_b(12 * 3600 + T0, *GOOD[0][1:4]) + "000",
                                                   junk, igc_b(12 * 3600 + T0 + 1, *GOOD[1][1:4]) + "000"]
    track, _ = load_track(path)
    times = track.start_time + track.t_s
    for row in GOOD:
        assert np.min(np.abs(times - (12 * 3600 + T0 + row[0]))) < 1e-6
    assert track.problems["misdated"] == 0 and track.problems["duplicate"] == 2


@FUZZ
@given(st.lists(st.tuples(st.integers(11, 31), st.one_of(st.text(max_size=40).map(lambda s: "DATA," + s),
                                                          st.lists(CELL, max_size=14).map(
                                                              lambda c: "DATA," + ",".join(c)))),
                max_size=6))
def test_fdr_garbage_never_crashes_and_never_costs_good_records(garbage):
    with tempfile.TemporaryDirectory() as d:
        path = write_fdr(Path(d) / "g.fdr", good_rows(),
                         extra=[(at, text.replace("\n", " ").replace("\r", " ")) for at, text in
                                sorted(garbage, reverse=True)])
        track = load_or_refuse(path)
    assert track is not None
    assert_good_records_kept(track, tol_m=2.0)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 255)), min_size=1, max_size=8))
def test_ulog_damage_never_crashes(flips):
    pytest.importorskip("pyulog")
    with tempfile.TemporaryDirectory() as d:
        path = write_ulog(Path(d) / "g.ulg", GOOD)
        data = bytearray(path.read_bytes())
        for at, byte in flips:
            data[at % len(data)] = byte
        path.write_bytes(bytes(data))
        load_or_refuse(path)


def test_a_damaged_attitude_format_is_read_without_a_numpy_warning(tmp_path):
    # Found by the fuzzing above (and a 20000-case search): these four bytes retype the
    # attitude's fields, whose values then warn "invalid value encountered in cast" on their
    # way to float64 (an error under this suite's filterwarnings) before they are dropped.
    pytest.importorskip("pyulog")
    path = write_ulog(tmp_path / "g.ulg", GOOD)
    data = bytearray(path.read_bytes())
    assert len(data) == 1478  # the flips below are positions in this file
    for at, byte in ((295, 10), (963, 159), (485, 255), (281, 247)):
        data[at] = byte
    path.write_bytes(bytes(data))
    load_or_refuse(path)


def test_ulog_reader_refuses_a_non_ulog_with_a_value_error(tmp_path):
    pytest.importorskip("pyulog")
    path = tmp_path / "g.ulg"
    path.write_bytes(b"ULog\x01\x12\x35" + struct.pack("<Q", 0) + b"\xff" * 40)
    assert load_or_refuse(path) is None


# -- encodings and damaged text ------------------------------------------------------------

@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_spreadsheet_encodings_are_read(tmp_path, encoding):
    # Excel's "CSV UTF-8" starts with a byte order mark; "Unicode text" is UTF-16.
    text = "time_s,x_m,y_m,z_m\n0,0,0,10\n1,0,40,10\n2,0,80,12\n"
    path = tmp_path / "s.csv"
    path.write_text(text, encoding=encoding)
    track, _ = load_track(path)
    assert len(track.t_s) == 3 and track.problems["corrupt"] == 0


@pytest.mark.parametrize("name,what", [("b.csv", "CSV log"), ("b.igc", "IGC log"), ("b.fdr", "X-Plane FDR log")])
def test_random_bytes_are_refused_as_no_text_log_by_every_text_reader(tmp_path, name, what):
    # Read as text, random bytes were lines of garbage: the IGC reader found no fix and ended
    # in "0 usable record(s), need at least 2 (no problems)".
    binary = tmp_path / name
    binary.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(ValueError, match=rf"{name}: not a text {what} \(\d+ of its first 4096 bytes are control"):
        load_track(binary)


@pytest.mark.parametrize("name,text,message", [
    ("h.igc", "AXXX001 logger\nHFDTE010725\n", "h.igc: no B record (fix) in its 2 line(s): not an IGC flight log"),
    ("e.igc", "", "e.igc: no B record (fix) in its 0 line(s): not an IGC flight log"),
    ("h.fdr", "A\n4\nACFT,a.acf,\n", "h.fdr: no DATA line in its 3 line(s): not an X-Plane FDR log"),
])
def test_a_text_log_without_records_says_so(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError) as exc:
        load_track(path)
    assert str(exc.value) == message


def test_a_binary_file_is_refused_as_such_and_a_few_nul_bytes_are_not(tmp_path):
    rng = np.random.default_rng(0)
    binary = tmp_path / "b.csv"
    binary.write_bytes(rng.integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(ValueError, match=r"b.csv: not a text CSV log \(\d+ of its first 4096 bytes are control"):
        load_track(binary)
    # A logger that lost power mid-line: NUL bytes where a line was; the rest is kept.
    lines = csv_cells(good_rows())
    lines.insert(8, "\x00" * 40)
    damaged = write_lines(tmp_path / "n.csv", lines)
    track, _ = load_track(damaged)
    assert len(track.t_s) == len(GOOD)


def test_a_long_attitude_dropout_is_estimated_from_the_track_not_held(tmp_path):
    # An AHRS that fails after 60 s of a 3 deg/s turn: holding its last values would freeze
    # the picture for the rest of the turn; the estimate from the track keeps turning.
    rows = flight(300)
    lines = csv_cells(rows, blanks={(i, j) for i in range(60, 300) for j in (4, 5, 6)})
    track, _ = load_track(write_lines(tmp_path / "a.csv", lines), origin=ORIGIN)
    assert track.problems["corrupt"] == 0
    source = np.asarray(track.attitude_source)
    assert (source[:60] == "logged").all() and (source[62:] == "air").all()
    assert any(n.startswith("attitude: 1 dropout(s) longer than") for n in track.notes)
    headings = np.array([track.sample(t).heading_deg for t in (100.0, 200.0)])
    true = np.array([rows[100][4], rows[200][4]])
    assert np.all(np.abs((headings - true + 180.0) % 360.0 - 180.0) < 5.0)
    assert track.assumptions  # the estimate says what it assumed
