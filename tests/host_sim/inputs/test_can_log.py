"""Recorded CAN logs (.asc, .blf, .trc) replayed at recorded timing, damaged records counted and skipped."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host_sim.inputs import canaerospace as ca
from host_sim.inputs import open_source

can = pytest.importorskip("can", reason="python-can is in the devices extra")

#: (log time s, signal, value): a stick moved aft in steps, then the throttle.
RECORDED = [(0.0, "pitch_control_position", 0.0), (0.1, "pitch_control_position", 0.25),
            (0.2, "pitch_control_position", 0.5), (0.3, "throttle_1_lever_position", 0.75),
            (0.5, "pitch_control_position", -0.5)]


def write_log(path, records=RECORDED, t0=1000.0):
    with can.Logger(str(path)) as logger:
        for k, (t, name, value) in enumerate(records):
            can_id, data = ca.encode(name, value, message_code=k)
            logger.on_message_received(can.Message(timestamp=t0 + t, arbitration_id=can_id, data=data,
                                                   is_extended_id=False))
    return path


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".trc"])
def test_frames_are_delivered_at_their_recorded_times(tmp_path, suffix):
    src = open_source(f"canlog://{write_log(tmp_path / ('flight' + suffix))}")
    seen = []
    for k in range(8):
        now = 50.0 + k * 0.1  # the caller's clock: any origin; the log starts at the first poll
        src.poll(now)
        c = src.latest()
        seen.append((round(c.pitch, 3), round(c.throttle, 3)))
    assert seen == [(0.0, 0.0), (0.25, 0.0), (0.5, 0.0), (0.5, 0.75), (0.5, 0.75), (-0.5, 0.75), (-0.5, 0.75),
                    (-0.5, 0.75)]
    assert src.finished and src.status().accepted == len(RECORDED)


def test_the_end_of_the_log_makes_the_source_stale_on_the_callers_clock(tmp_path):
    src = open_source(f"canlog://{write_log(tmp_path / 'f.asc')}?stale_after=1")
    src.poll(0.0)
    src.poll(0.5)
    assert not src.status().stale
    src.poll(1.49)
    assert not src.status().stale
    src.poll(1.51)
    assert src.status().stale and src.status().rejected["stale"] == 1
    assert src.latest().pitch == -0.5  # held


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
def test_damaged_text_records_are_counted_and_the_rest_is_read(tmp_path, suffix):
    path = write_log(tmp_path / ("f" + suffix))
    lines = path.read_text().splitlines(keepends=True)
    records = [i for i, line in enumerate(lines) if line.strip()[:1].isdigit() and "Start" not in line]
    second = lines[records[1]]
    # a record with bad hex, a truncated record, and a line of noise
    lines[records[1]] = second.replace(second.split()[-1], "ZZ", 1) if suffix == ".asc" else \
        second[: len(second) // 2] + " QQ QQ\n"
    lines.insert(records[3], "1.0 garbage here \x00\x01\n" if suffix == ".asc" else "   9  x  DT  zz\n")
    path.write_text("".join(lines))
    src = open_source(f"canlog://{path}")
    for k in range(10):
        src.poll(k * 0.1)
    status = src.status()
    assert status.accepted == len(RECORDED) - 1
    assert status.rejected["bad_frame"] == 2  # the damaged record and the noise
    assert f"{path.name} line {records[3] + 1}: " in status.last_rejection  # the noise, by its line
    assert src.latest().pitch == -0.5 and src.latest().throttle == 0.75


def test_a_damaged_binary_log_ends_at_the_damage(tmp_path):
    # Enough frames for several of the log's compressed containers: the first stays whole.
    path = write_log(tmp_path / "f.blf", RECORDED * 2000)
    data = bytearray(path.read_bytes())
    data[len(data) // 2:] = bytes(len(data) - len(data) // 2)  # zeros over the second half
    path.write_bytes(bytes(data))
    src = open_source(f"canlog://{path}")
    src.poll(0.0)
    src.poll(100.0)
    status = src.status()
    assert src.finished
    assert 0 < status.accepted < len(RECORDED) * 2000
    assert status.rejected["device_error"] == 1 and "the rest of the log is skipped" in status.last_rejection


def replay_all(src):
    """Deliver every frame, whatever its time stamp; the status and the refusals other than stale
    (an infinite time since the last good input)."""
    src.poll(0.0)
    src.poll(math.inf)
    assert src.finished
    status = src.status()
    return status, {k: v for k, v in status.rejected.items() if v and k != "stale"}


def record_lines(path):
    """Indices of the lines of a written log that hold frames."""
    lines = path.read_text().splitlines(keepends=True)
    return lines, [i for i, line in enumerate(lines) if re.match(r"\s*\d", line) and "Start" not in line]


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
@pytest.mark.parametrize("body", ["hello world\nthis is not a log\n1.0 2 3\n\x00\x01\x02\n",
                                  "0.5 1 190 Rx d 8 00 00 00 00 00 00 00 00\n", ""])
def test_a_log_without_a_usable_frame_is_refused_naming_the_counts(tmp_path, suffix, body):
    path = tmp_path / ("junk" + suffix)
    path.write_text(body)
    with pytest.raises(ValueError) as exc:
        open_source(f"canlog://{path}")
    message = str(exc.value)
    assert message.startswith(f"canlog://{path}: junk{suffix} has no usable CANaerospace control frame")
    if body.startswith("hello"):
        assert "refused: 4 bad_frame" in message and "line 1: not a CAN frame record: 'hello world'" in message
    elif body and suffix == ".asc":
        assert "1 CAN frame(s) read; refused: 1 wrong_data_type" in message
    elif not body:
        assert "refused: nothing" in message


def test_a_binary_log_that_is_not_one_is_refused(tmp_path):
    path = tmp_path / "junk.blf"
    path.write_bytes(b"not a blf file at all\n" * 10)
    with pytest.raises(ValueError, match=r"junk.blf has no usable CANaerospace control frame .*1 device_error"):
        open_source(f"canlog://{path}")


def test_ig_host_refuses_a_log_of_garbage_with_exit_2(tmp_path, capsys):
    from services.cli import main

    path = tmp_path / "junk.asc"
    path.write_text("garbage\n" * 5)
    assert main(["host", "--controls", f"canlog://{path}"]) == 2
    err = capsys.readouterr().err
    assert "ig host: error: " in err and "junk.asc has no usable CANaerospace control frame" in err
    assert "5 bad_frame" in err


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
def test_format_lines_are_not_counted_and_every_other_line_is(tmp_path, suffix):
    path = write_log(tmp_path / ("f" + suffix))
    lines, records = record_lines(path)
    comment = "// a comment\n" if suffix == ".asc" else ";   a comment\n"
    noise = ["no digits at all\n", "  \t  \n", "Rx d 8 00\n", comment, "12.5\n", "0x190 8 00 00\n"]
    for k, line in enumerate(noise):
        lines.insert(records[1] + k, line)
    lines.append(comment)
    path.write_text("".join(lines))
    status, refused = replay_all(open_source(f"canlog://{path}"))
    assert status.accepted == len(RECORDED)
    assert refused == {"bad_frame": 4}  # not the blank line or the comments
    assert status.counters["frames"] == len(RECORDED)


def test_frames_that_are_not_controls_are_counted_by_cause(tmp_path):
    path = write_log(tmp_path / "f.asc")
    lines, records = record_lines(path)
    first = lines[records[0]]
    extra = [first.replace(" 190 ", " 7FF ", 1),  # an identifier not in the table
             first.replace(" 190 ", " 190x", 1),  # a 29-bit identifier
             re.sub(r"d 8 (\S+ ){3}\S+", "d 4 00 00 00 00", first),  # too short for a float
             first.replace(" 190 ", " 190 ", 1).replace(" Rx   d 8 ", " Rx   r 8 ", 1),  # remote frame
             "   0.400000 1  190             Rx   d 8 01 0A 00 00 3F 80 00 00\n",  # UCHAR for a FLOAT
             "   0.400000 1  190             Rx   d 8 01 02 00 00 7F C0 00 00\n",  # NaN
             "   0.400000 1  190             Rx   d 8 01 02 00 00 40 00 00 00\n"]  # 2.0
    lines[records[-1] + 1:records[-1] + 1] = extra
    path.write_text("".join(lines))
    status, refused = replay_all(open_source(f"canlog://{path}"))
    assert status.accepted == len(RECORDED)
    assert refused == {
        "unknown_identifier": 2, "bad_length": 1, "bad_frame": 1, "wrong_data_type": 1, "not_finite": 1,
        "out_of_range": 1}


def test_a_frame_with_a_time_stamp_that_is_not_finite_is_counted(tmp_path):
    path = write_log(tmp_path / "f.trc")
    lines, records = record_lines(path)
    lines[records[2]] = re.sub(r"^(\s*\d+\s+)\S+", r"\1nan", lines[records[2]])
    path.write_text("".join(lines))
    src = open_source(f"canlog://{path}")
    for k in range(8):
        src.poll(k * 0.1)
    status = src.status()
    assert status.accepted == len(RECORDED) - 1 and status.rejected["bad_frame"] == 1
    assert "time stamp nan is not finite" in status.last_rejection


# --- garbage, generated ------------------------------------------------------------------------

#: Characters of garbage lines: printable text and control characters, but no line breaks.
_CHARS = st.characters(blacklist_characters="\n\r", blacklist_categories=("Cs",))
#: A line that no log format takes as a header, comment or event: it starts with a letter or a
#: digit other than those that begin header words.
_GARBAGE_LINE = st.tuples(st.sampled_from("acfghjkmopqrsuvwxyzACFGHJKMOPQRSUVWXYZ0123456789#!"),
                          st.text(_CHARS, max_size=60)).map("".join)


def _mutate(line: str, edits: list[tuple[int, int, str]]) -> str:
    """line with each (kind, position, character) edit applied after its first non-blank character
    (so that it stays a record: a mutation does not make a comment of it)."""
    body = line.rstrip("\n")
    lead = len(body) - len(body.lstrip()) + 1
    for kind, pos, char in edits:
        if len(body) <= lead:
            break
        i = lead + pos % (len(body) - lead)
        if kind == 0:
            body = body[:i] + char + body[i + 1:]
        elif kind == 1:
            body = body[:i] + body[i + 1:]
        elif kind == 2:
            body = body[:i] + char + body[i:]
        else:
            body = body[:i]
    return body + "\n"


_EDITS = st.lists(st.tuples(st.integers(0, 3), st.integers(0, 200),
                            st.sampled_from("0123456789abcdefABCDEFxXrRdD .-+;/eEnN\t\x00")), min_size=1,
                  max_size=3)


@pytest.fixture(scope="module")
def written_logs(tmp_path_factory):
    directory = tmp_path_factory.mktemp("logs")
    return {suffix: write_log(directory / ("good" + suffix)).read_text() for suffix in (".asc", ".trc")}


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_lines_among_good_ones_are_each_counted_and_the_good_ones_kept(tmp_path, written_logs, suffix,
                                                                             data):
    lines = written_logs[suffix].splitlines(keepends=True)
    records = [i for i, line in enumerate(lines) if re.match(r"\s*\d", line) and "Start" not in line]
    garbage = data.draw(st.lists(st.tuples(st.integers(0, len(records)), _GARBAGE_LINE), min_size=1,
                                 max_size=8))
    out = list(lines)
    for at, line in sorted(garbage, reverse=True):
        where = records[at] if at < len(records) else len(out)
        out.insert(where, line + "\n")
    path = tmp_path / ("g" + suffix)
    path.write_text("".join(out))
    status, refused = replay_all(open_source(f"canlog://{path}"))
    # A garbage line may by chance be a frame (counted as a frame, then refused by cause).
    assert status.accepted == len(RECORDED)
    assert sum(refused.values()) == len(garbage)
    assert status.counters["frames"] >= len(RECORDED)


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_mutated_records_are_each_accepted_or_counted(tmp_path, written_logs, suffix, data):
    lines = written_logs[suffix].splitlines(keepends=True)
    records = [i for i, line in enumerate(lines) if re.match(r"\s*\d", line) and "Start" not in line]
    chosen = data.draw(st.sets(st.sampled_from(records), min_size=1, max_size=len(records) - 1))
    for i in chosen:
        lines[i] = _mutate(lines[i], data.draw(_EDITS))
    path = tmp_path / ("m" + suffix)
    path.write_text("".join(lines))
    status, refused = replay_all(open_source(f"canlog://{path}"))
    # Every record gives an accepted value or a refusal; the records left alone are all accepted.
    assert status.accepted + sum(refused.values()) == len(records)
    assert status.accepted >= len(records) - len(chosen)


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(st.characters(blacklist_categories=("Cs",)), max_size=400))
def test_any_text_is_a_log_or_a_clear_error(tmp_path, suffix, text):
    path = tmp_path / ("t" + suffix)
    path.write_text(text, errors="replace")
    try:
        src = open_source(f"canlog://{path}")
    except ValueError as exc:
        assert "has no usable CANaerospace control frame" in str(exc)
    else:  # pragma: no cover - random text holding a valid control frame
        replay_all(src)


@pytest.fixture(scope="module")
def written_blf(tmp_path_factory):
    return write_log(tmp_path_factory.mktemp("blf") / "good.blf", RECORDED * 400).read_bytes()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_damaged_blf_is_replayed_up_to_the_damage_or_refused_clearly(tmp_path, written_blf, data):
    # Bytes overwritten anywhere (headers, compressed containers) or the file cut short: the
    # frames before the damage are replayed and the damage counted once, or the log is refused
    # with a clear message when nothing usable comes before it; never another exception.
    blf = bytearray(written_blf)
    for at, value in data.draw(st.lists(st.tuples(st.integers(0, len(blf) - 1), st.integers(0, 255)),
                                        max_size=6)):
        blf[at] = value
    cut = data.draw(st.integers(1, len(blf)))
    path = tmp_path / "d.blf"
    path.write_bytes(bytes(blf[:cut]))
    try:
        src = open_source(f"canlog://{path}")
    except ValueError as exc:
        assert "has no usable CANaerospace control frame" in str(exc)
        return
    status, refused = replay_all(src)
    assert status.accepted + sum(refused.values()) >= 1
    assert status.accepted <= len(RECORDED) * 400
