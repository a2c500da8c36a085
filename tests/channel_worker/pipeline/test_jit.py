"""The pipeline's compile helpers (channel_worker/pipeline/jit.py)."""

from __future__ import annotations

from channel_worker.pipeline.jit import lanes


def test_lanes_split_tasks_over_threads_at_most_one_per_task():
    assert lanes(2, 48) == 2
    assert lanes(4, 3) == 3
    assert lanes(1, 0) == 1
