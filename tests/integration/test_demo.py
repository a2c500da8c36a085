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
    while time.monotonic() < deadline and not list((out / "frames").glob("frame_*.png")):
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
