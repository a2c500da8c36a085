"""The pipeline's compile helpers (channel_worker/pipeline/jit.py)."""

from __future__ import annotations

from channel_worker.pipeline.jit import lanes


def test_lanes_split_tasks_over_threads_at_most_one_per_task():
    assert lanes(2, 48) == 2
    assert lanes(4, 3) == 3
    assert lanes(1, 0) == 1


def test_a_work_queue_hands_every_task_to_exactly_one_lane():
    import numpy as np
    from numba import njit, prange

    from channel_worker.pipeline.jit import claim, new_queue, thread_pool_size

    @njit(parallel=True)
    def share(n, threads):
        queue = new_queue()
        taken = np.zeros(n, np.int64)
        lane_of = np.full(n, -1, np.int64)
        for lane in prange(lanes(threads, n)):
            while True:
                task = claim(queue)
                if task >= n:
                    break
                taken[task] += 1
                lane_of[task] = lane
        # Read through the queue: a plain queue[0] here is folded by LLVM to the 0 it was
        # set to (the atomic adds inside the parallel loop are invisible to it).
        return taken, lane_of, claim(queue)

    for n in (0, 1, 7, 5000):
        taken, lane_of, after = share(n, thread_pool_size())
        assert (taken == 1).all()
        assert (lane_of >= 0).all()
        # Every lane stops at its first claim past the end: one per lane, then this one.
        assert after == n + lanes(thread_pool_size(), n)
