"""`ig demo` stops every process it started when interrupted with Ctrl-C (SIGINT)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parent.parent.parent


def processes_mentioning(text: str) -> list[int]:
    """PIDs whose command line contains text (Linux /proc)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if text in (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace"):
                    pids.append(int(entry.name))
            except OSError:
                continue
    return pids


@pytest.mark.skipif(not Path("/proc/self/cmdline").exists(), reason="needs Linux /proc to find the children")
def test_ctrl_c_stops_every_process(tmp_path):
    out = tmp_path / "demo"
    demo = subprocess.Popen([sys.executable, "-m", "services.cli", "demo", "--duration", "60", "--rate", "5",
                             "--width", "48", "--height", "36", "--samples", "1", "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    rig = str(out / "rig.toml")
    deadline = time.monotonic() + 180
    # wait until host, compositor and the three workers are all running and frames flow
    while time.monotonic() < deadline and len(processes_mentioning(rig)) < 5:
        time.sleep(0.2)
    assert len(processes_mentioning(rig)) == 5
    while time.monotonic() < deadline and not list((out / "latest" / "frames").glob("frame_*.png")):
        time.sleep(0.2)
    demo.send_signal(signal.SIGINT)
    output, _ = demo.communicate(timeout=60)
    assert demo.returncode == 130, output
    assert "interrupted" in output
    leftover = processes_mentioning(rig)
    assert leftover == [], f"still running: {leftover}"


def test_a_failing_worker_stops_the_demo_at_once(tmp_path):
    """A worker that cannot load its scene ends the demo with its exit code and its message,
    instead of the host waiting out its timeouts for a channel that will never come."""
    scene = tmp_path / "bad.json"
    scene.write_text('{"format": "ig-scene/1", "sky": {"colour": "#zzzzzz"}, "earth": {"colour": "#000000"},'
                     ' "models": {}, "instances": []}')
    out = tmp_path / "demo"
    proc = subprocess.run([sys.executable, "-m", "services.cli", "demo", "--scene", str(scene), "--width", "32",
                           "--height", "24", "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "exited with code 2" in proc.stderr
    assert "sky.colour" in proc.stderr and "#zzzzzz" in proc.stderr  # the worker's own message
    assert processes_mentioning(str(out / "rig.toml")) == []


def test_the_host_is_paced_by_the_rig_and_recording_never_holds_it_up(tmp_path):
    """--rate auto (the default) flies paced by the rig from the start, with no run before it to
    measure the rate; the PNGs due (--record-every auto: one a simulated second, by the frames'
    time stamps) are written or counted as left out, never waited for."""
    import json

    out = tmp_path / "demo"
    proc = subprocess.run([sys.executable, "-m", "services.cli", "demo", "--width", "48", "--height", "36",
                           "--samples", "1", "--duration", "2.5", "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "measuring the rate" not in proc.stdout and not (out / "calibration").exists()
    assert ("the host paced by the rig (at most 60 Hz), 1 PNG(s) a simulated second, EXR every 30"
            in proc.stdout), proc.stdout
    assert "the host paced by the rig: the flight ran in real time" in proc.stdout
    report = json.loads((out / "latest" / "report.json").read_text())
    # Paced by the rig, the count is the rig's: the first frame at 0 s and the last at 2.5 s, at least.
    frames = report["frames_published"]
    assert report["frames_complete"] == frames >= 2
    assert report["record_per_s"] == 1.0
    # One PNG due in each simulated second the flight reached (0, 1, 2): written, or left out
    # and counted.
    pngs = list((out / "latest" / "frames").glob("frame_*.png"))
    assert len(pngs) + report["frames_not_recorded"] == 3, (pngs, report["frames_not_recorded"])
    assert "frame_000000.png" in {p.name for p in pngs} or report["frames_not_recorded"]
    assert report["composite_rate_hz"] > 0
    # The demo's own numbers, added to the report and printed: the first frame counts from the
    # program's start, after the compile and the rig's start; the flight from its first composite.
    times = report["demo"]
    assert times["compile_s"] > 0 and times["rig_start_s"] > 0
    assert times["compile_s"] + times["rig_start_s"] <= times["first_frame_s"] <= times["total_s"]
    assert 0 < times["flight_wall_s"] <= times["total_s"] - times["first_frame_s"]
    assert times["flight_frames"] == frames and times["flight_rate_hz"] > 0 and times["flight_simulated_s"] == 2.5
    assert f"first stitched frame {times['first_frame_s']:.1f} s after ig demo started" in proc.stdout
    assert f"the flight: {frames} stitched frames in {times['flight_wall_s']:.1f} s wall-clock" in proc.stdout
