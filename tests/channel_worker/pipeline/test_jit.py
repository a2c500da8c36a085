"""The pipeline's compile helpers (channel_worker/pipeline/jit.py)."""

from __future__ import annotations

import numpy as np
from numba import njit

from channel_worker.pipeline.jit import lanes, prefetch


@njit(cache=False)
def _sum_with_prefetch(a, step):
    """The sum of a's elements, each cache line asked for ahead of its reads."""
    flat = a.ravel()
    total = 0.0
    for i in range(0, flat.size, step):
        prefetch(a, min(i + 64, flat.size - 1))
        for k in range(i, min(i + step, flat.size)):
            total += flat[k]
    return total


def test_prefetch_compiles_for_every_array_kind_and_changes_nothing():
    # The hint must reach LLVM under the name this LLVM knows, for the element types and
    # ranks the kernels use, and leave the values read alone.
    rng = np.random.default_rng(3)
    for a in (rng.random((7, 5, 5)).astype(np.float32), rng.random(1000),
              rng.integers(0, 100, (3, 4)).astype(np.int32)):
        assert _sum_with_prefetch(a, 16) == np.float64(a.astype(np.float64).ravel().cumsum()[-1])


def test_lanes_split_tasks_over_threads_at_most_one_per_task():
    assert lanes(2, 48) == 2
    assert lanes(4, 3) == 3
    assert lanes(1, 0) == 1
