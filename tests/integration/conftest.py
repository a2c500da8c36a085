"""Starting and waiting for the rig's processes, shared by the end-to-end tests."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent


def start(argv, log):
    """`ig ARGV...` as a child process with one numba thread, its output to log."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    return subprocess.Popen([sys.executable, "-m", "services.cli", *argv], stdout=log, stderr=subprocess.STDOUT,
                            env=env, cwd=ROOT)


def wait_all(procs, timeout_s=300.0):
    """Exit codes once every process has ended; a process that fails ends the run at once."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        codes = {name: p.poll() for name, p in procs.items()}
        if all(c is not None for c in codes.values()) or any(c not in (None, 0) for c in codes.values()):
            return codes
        time.sleep(0.2)
    return {name: p.poll() for name, p in procs.items()}


def kill_all(procs, logs):
    """Whatever a test asserted: kill every process still running, close every log."""
    for proc in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    for f in logs.values():
        f.close()
