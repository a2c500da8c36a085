"""Recorded CAN logs (.asc, .blf, .trc) replayed at recorded timing, damaged records skipped."""

from __future__ import annotations

import pytest

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
    path = write_log(tmp_path / "f.blf", RECORDED * 20)
    data = bytearray(path.read_bytes())
    data[len(data) // 2:] = bytes(len(data) - len(data) // 2)  # zeros over the second half
    path.write_bytes(bytes(data))
    src = open_source(f"canlog://{path}")
    src.poll(0.0)
    src.poll(100.0)
    status = src.status()
    assert src.finished
    assert status.accepted < len(RECORDED) * 20
    assert status.rejected["device_error"] == 1 and "the rest of the log is skipped" in status.last_rejection
