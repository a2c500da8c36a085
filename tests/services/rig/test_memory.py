import platform
import sys

import numpy as np
import pytest

from services.rig.memory import keep_freed_memory


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc",
                    reason="mallopt is glibc's")
def test_glibc_keeps_freed_frame_arrays_for_reuse():
    assert keep_freed_memory() is True
    # Frame-sized arrays still allocate, fill and free as before.
    for _ in range(3):
        a = np.empty((768, 1024, 4), np.float32)
        a.fill(1.0)
        assert float(a.sum()) == 768 * 1024 * 4
        del a


def test_elsewhere_it_changes_nothing_and_says_so(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    assert keep_freed_memory() is False
