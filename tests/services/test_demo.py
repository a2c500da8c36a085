"""`ig demo`'s own numbers: the time to its first stitched frame and the flight apart from the
compile and the calibration (the whole demo runs in tests/integration/test_demo.py)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from services.demo import Timeline, demo_times, format_times, process_start_time

#: When this module was imported: the pytest process had started before.
IMPORTED = time.time()


def test_the_first_frame_counts_from_the_start_and_the_flight_from_its_first_composite():
    timeline = Timeline(started=1000.0, compile_s=30.0, calibration_s=8.0)
    doc = {"first_composite_time": 1041.5, "last_composite_time": 1061.5, "frames_complete": 31}
    times = demo_times(timeline, doc, ended=1064.0, simulated_s=20.0)
    assert times == {"first_frame_s": 41.5, "total_s": 64.0, "compile_s": 30.0, "calibration_s": 8.0,
                     "flight_wall_s": 20.0, "flight_frames": 31, "flight_rate_hz": 1.5, "flight_simulated_s": 20.0}
    text = format_times(times)
    assert text.splitlines() == [
        "first stitched frame 41.5 s after ig demo started (before the flight: kernels 30.0 s, the workers' start "
        "and the calibration 8.0 s)",
        "the flight: 31 stitched frames in 20.0 s wall-clock (1.50 Hz) for 20 simulated seconds",
        "64 s in all"]


def test_without_a_composite_the_demo_says_so():
    times = demo_times(Timeline(started=10.0), {"first_composite_time": None, "last_composite_time": None,
                                                "frames_complete": 0}, ended=15.0, simulated_s=20.0)
    assert times["first_frame_s"] is None and times["flight_wall_s"] is None and times["flight_rate_hz"] is None
    assert format_times(times).splitlines() == ["no stitched frame", "5 s in all"]


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="reads the start time from Linux /proc")
def test_the_process_start_is_the_process_s_not_the_call_s():
    # The pytest process started before it imported this module, and after the machine booted.
    started = process_start_time()
    uptime_s = float(Path("/proc/uptime").read_text().split()[0])
    assert time.time() - uptime_s <= started <= IMPORTED

