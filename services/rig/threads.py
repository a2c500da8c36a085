"""How many threads a rendering process runs, fixed before numba starts its pool.

numba sizes its thread pool once, from NUMBA_NUM_THREADS, the first time a parallel kernel
runs; numba.set_num_threads can lower the count later but never raise it. A worker therefore
reads its thread count (RenderOptions.threads: the rig file's [render] threads, or --threads)
and sets NUMBA_NUM_THREADS before anything imports numba, so that the count the operator
asked for is the pool it gets. A count the machine cannot honour is refused here, as a one-line
error naming the setting, not discovered at the first frame.

This module imports nothing of numba: importing it must not start the pool it is sizing.
"""

from __future__ import annotations

import os
import sys


def usable_cores() -> int:
    """The CPUs this process may run on (its affinity: a container's or taskset's share, not
    the machine's count)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def share_of_cores(processes: int) -> int:
    """Threads for each of `processes` rendering processes sharing this machine: the usable
    cores divided among them, at least one each (a 16-core machine running three workers gives
    each 5; the one left over serves the host, the compositor and the operating system)."""
    return max(1, usable_cores() // max(1, processes))


def check_threads(threads: int, setting: str) -> int:
    """The usable cores, after checking that `threads` (0: all of them) is a count this
    machine can honour.

    Raises:
        ValueError: threads is negative or more than the usable cores, naming setting.
    """
    cores = usable_cores()
    if threads < 0:
        raise ValueError(f"{setting}: {threads} is negative (0 takes every core)")
    if threads > cores:
        # More threads than cores only time-slice: every parallel loop then waits for its
        # slowest, descheduled thread, and the frame is slower than with one per core.
        raise ValueError(f"{setting}: {threads} is more than the {cores} cores this process may use")
    return cores


def size_thread_pool(threads: int, *, setting: str = "[render] threads") -> int:
    """Fix numba's pool for `threads` threads and return its size.

    0 takes NUMBA_NUM_THREADS where the environment sets it (a container's CPU limit, passed
    down by its orchestrator: deploy/k8s/worker.yaml), else one thread per usable core.

    Call before numba is imported. setting names where the count came from, for the error.

    Raises:
        ValueError: threads is negative, more than the usable cores, or more than the pool of
            a numba already started (its NUMBA_NUM_THREADS) in this process.
    """
    cores = check_threads(threads, setting)
    wanted = threads or _environment_threads(cores)
    if "numba" in sys.modules:
        import numba  # already loaded: the pool it was configured with is the limit

        pool = int(vars(numba.config)["NUMBA_NUM_THREADS"])
        if wanted > pool:
            raise ValueError(f"{setting}: {wanted} is more than the {pool} threads numba was started with "
                             f"(NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', pool)})")
        return pool
    os.environ["NUMBA_NUM_THREADS"] = str(wanted)
    return wanted


def _environment_threads(cores: int) -> int:
    """NUMBA_NUM_THREADS from the environment, within 1..cores; cores where it is unset or not
    a whole number."""
    try:
        return min(cores, max(1, int(os.environ.get("NUMBA_NUM_THREADS", cores))))
    except ValueError:
        return cores
