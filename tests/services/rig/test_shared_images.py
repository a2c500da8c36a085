"""Channel images through shared memory: the ring a worker writes, the reader the compositor
copies out with, and what each refuses."""

import os
import subprocess
import sys

import numpy as np
import pytest

from services.rig import shared_images
from services.rig.shared_images import (
    SharedImageError,
    SharedImageReader,
    SharedImageRing,
    is_local_address,
    remove_stale_segments,
    shared_memory_supported,
)

pytestmark = pytest.mark.skipif(not shared_memory_supported(), reason="no /dev/shm")


def test_round_trip_copies_out_of_the_slot():
    ring = SharedImageRing("t-centre", 4 * 5 * 3)
    reader = SharedImageReader()
    try:
        slot, seq, pixels = ring.reserve((4, 5, 3), np.uint8)
        pixels[:] = np.arange(60, dtype=np.uint8).reshape(4, 5, 3)
        ring.commit(slot, seq)
        out = reader.read("centre", ring.name, slot, seq, (4, 5, 3), np.uint8)
        np.testing.assert_array_equal(out, np.arange(60).reshape(4, 5, 3))
        pixels[:] = 0  # the worker reuses the slot: the compositor's image is its own copy
        assert out[3, 4, 2] == 59
        # Half floats in the same slots.
        slot, seq, halves = ring.reserve((2, 5, 3), "<f2")
        halves[:] = 0.25
        ring.commit(slot, seq)
        np.testing.assert_array_equal(reader.read("centre", ring.name, slot, seq, (2, 5, 3), "<f2"), 0.25)
    finally:
        reader.close()
        ring.close()
    assert not (shared_images.SHM_DIR / ring.name).exists()


def test_a_stale_slot_is_refused_by_sequence():
    ring = SharedImageRing("t-left", 12, slots=2)
    reader = SharedImageReader()
    try:
        first = ring.reserve((2, 2, 3), np.uint8)
        ring.commit(first[0], first[1])
        for _ in range(2):  # the ring wraps: slot of the first image now holds the third
            slot, seq, _pixels = ring.reserve((2, 2, 3), np.uint8)
            ring.commit(slot, seq)
        with pytest.raises(SharedImageError, match=r"shared.sequence: 1, but slot 1 .* holds 3 \(a stale reference"):
            reader.read("left", ring.name, first[0], first[1], (2, 2, 3), np.uint8)
        slot, seq, _pixels = ring.reserve((2, 2, 3), np.uint8)  # reserved, not committed yet
        with pytest.raises(SharedImageError, match=r"holds 0 \(a stale reference"):
            reader.read("left", ring.name, slot, seq, (2, 2, 3), np.uint8)
        with pytest.raises(SharedImageError, match=r"shared.slot: 7 is not a slot .* \(it has 2\)"):
            reader.read("left", ring.name, 7, seq, (2, 2, 3), np.uint8)
        with pytest.raises(SharedImageError, match=r"shared.slot: 48 bytes of pixels do not fit .* 12-byte slots"):
            reader.read("left", ring.name, 0, seq, (4, 4, 3), np.uint8)
    finally:
        reader.close()
        ring.close()


def test_a_missing_segment_is_unavailable_and_a_path_is_not_a_name():
    reader = SharedImageReader()
    with pytest.raises(SharedImageError, match=r"shared.segment: 'ig-x-1-0123abcd' cannot be opened") as err:
        reader.read("x", "ig-x-1-0123abcd", 0, 1, (1, 1, 3), np.uint8)
    assert err.value.unavailable
    with pytest.raises(SharedImageError, match=r"shared.segment: '../etc/passwd' is not a segment name") as err:
        reader.read("x", "../etc/passwd", 0, 1, (1, 1, 3), np.uint8)
    assert not err.value.unavailable


def test_a_worker_back_with_a_new_segment_replaces_the_old_one():
    reader = SharedImageReader()
    old, new = SharedImageRing("t-right", 3), SharedImageRing("t-right", 3)
    try:
        for ring, value in ((old, 1), (new, 2)):
            slot, seq, pixels = ring.reserve((1, 1, 3), np.uint8)
            pixels[:] = value
            ring.commit(slot, seq)
            assert reader.read("right", ring.name, slot, seq, (1, 1, 3), np.uint8)[0, 0, 0] == value
        old.close()  # the dead worker's segment: gone, and nothing of the compositor holds it
        assert [o.name for o in reader._open.values()] == [new.name]
    finally:
        reader.close()
        new.close()


def test_the_segment_of_a_killed_worker_is_removed_at_the_next_start():
    # A process that creates a ring and dies without cleaning up (SIGKILL skips every finaliser).
    code = ("import os, signal; from services.rig.shared_images import SharedImageRing; "
            "r = SharedImageRing('t-dead', 8); print(r.name, flush=True); os.kill(os.getpid(), signal.SIGKILL)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=os.environ, timeout=60)
    name = done.stdout.strip()
    assert (shared_images.SHM_DIR / name).exists()
    alive = SharedImageRing("t-dead", 8)
    try:
        assert remove_stale_segments("t-dead") == [name]
        assert not (shared_images.SHM_DIR / name).exists() and (shared_images.SHM_DIR / alive.name).exists()
    finally:
        alive.close()


def test_local_addresses():
    assert is_local_address("127.0.0.1:50151") and is_local_address("localhost:1")
    assert not is_local_address("192.0.2.1:50151")  # TEST-NET-1: never this machine's
    assert not is_local_address("no-such-host.invalid:1")
