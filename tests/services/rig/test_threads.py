"""Sizing numba's pool before it starts (services/rig/threads.py), and the demo's share of cores."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from services.demo import worker_threads
from services.rig.rigfile import default_rig_path, load_rig
from services.rig.threads import share_of_cores, size_thread_pool, usable_cores

ROOT = Path(__file__).resolve().parents[3]


def _in_fresh_process(code: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """code run by a new interpreter, where numba is not imported yet."""
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          env={**os.environ, **(env or {})})


def test_the_pool_numba_starts_is_the_count_asked_for():
    if usable_cores() < 2:
        pytest.skip("one usable core: a pool of 2 would be refused")
    # An inherited NUMBA_NUM_THREADS=1 (a shell's, a test harness's) is replaced by the setting.
    result = _in_fresh_process(
        "from services.rig.threads import size_thread_pool\n"
        "print(size_thread_pool(2))\n"
        "import numba\n"
        "print(numba.config.NUMBA_NUM_THREADS, numba.get_num_threads())\n",
        env={"NUMBA_NUM_THREADS": "1"})
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["2", "2", "2"]


def test_zero_takes_the_environments_count_else_every_usable_core():
    code = ("from services.rig.threads import size_thread_pool\n"
            "size_thread_pool(0)\n"
            "import numba\n"
            "print(numba.config.NUMBA_NUM_THREADS)\n")
    result = _in_fresh_process(code, env={"NUMBA_NUM_THREADS": "1"})
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) == 1
    unset = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                            env=unset)
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) == usable_cores()


def test_more_threads_than_cores_is_refused_naming_the_setting():
    with pytest.raises(ValueError, match=rf"^\[render\] threads: {usable_cores() + 1} is more than the "
                                         rf"{usable_cores()} cores this process may use$"):
        size_thread_pool(usable_cores() + 1)
    with pytest.raises(ValueError, match=r"^--threads: -1 is negative"):
        size_thread_pool(-1, setting="--threads")


def test_a_started_pool_smaller_than_asked_is_refused():
    # This test process has numba imported already: its pool is the limit.
    import numba

    pool = int(vars(numba.config)["NUMBA_NUM_THREADS"])
    if pool >= usable_cores():
        assert size_thread_pool(usable_cores()) == pool
    else:
        with pytest.raises(ValueError, match="threads numba was started with"):
            size_thread_pool(pool + 1)


def test_share_of_cores_gives_every_process_at_least_one():
    assert share_of_cores(1) == usable_cores()
    assert share_of_cores(10_000) == 1
    assert share_of_cores(0) == usable_cores()


def test_demo_workers_share_the_cores_unless_told():
    rig = load_rig(default_rig_path())
    assert worker_threads(rig, None) == share_of_cores(len(rig.channels))
    assert worker_threads(rig, 1) == 1
    with pytest.raises(ValueError, match=rf"^--threads: {usable_cores() + 1} is more than the {usable_cores()} cores"):
        worker_threads(rig, usable_cores() + 1)
    told = replace(rig, render=rig.render.replace(threads=usable_cores() + 1))
    with pytest.raises(ValueError, match=r"^\[render\] threads: "):
        worker_threads(told, None)


def test_worker_with_too_many_threads_in_its_rig_file_exits_2_with_one_line(tmp_path):
    rig = tmp_path / "rig.toml"
    default = default_rig_path().read_text()
    rig.write_text(default + f"\n[render]\nthreads = {usable_cores() + 4}\n")
    result = subprocess.run([sys.executable, "-m", "services.cli", "worker", "--rig", str(rig), "--channel", "left"],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"ig worker: error: [render] threads: {usable_cores() + 4} is more than the {usable_cores()} cores this "
        f"process may use"]
