"""How a process's malloc treats frame-sized blocks: kept for reuse (a worker) or handed back at
once (the compositor).

Keeping the frame's large arrays off the kernel's page-fault path (the worker).

A frame allocates tens of megabytes of arrays (the background's colour, per-sample depth,
range and cloud images alone are 35 MB at 1024 x 768 x 4) and frees them at its end. glibc's
malloc serves blocks above its mmap threshold with fresh mappings and returns them to the
system when freed, so every frame touches its arrays' pages for the first time again: a page
fault per 4 KiB, taken under the process's memory lock, which serialises the threads. Measured
on the demo frame's terrain warp (the background's design until 2026-11; 1024 x 768 x 4,
2 cores): 75.2 ms with reused arrays, 78.6 ms with fresh ones on one thread; 41.8 against
46.0 ms on two. With the thresholds raised, a freed block stays in malloc's heap and the next
frame's array of the same size reuses its pages (73.0 and 40.7 ms). The heap then holds what
one frame needs at its largest, which a worker needs anyway.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

#: glibc's mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
#: Blocks up to this size come from the heap and stay there when freed. glibc caps the mmap
#: threshold at 32 MiB on 64-bit systems (HEAP_MAX_SIZE / 2); larger blocks are still mapped.
_THRESHOLD = 32 * 1024 * 1024
#: Freed memory at the top of the heap returned to the system only beyond this.
_TRIM = 1 << 30


def _mallopt():
    """glibc's mallopt, or None (not Linux, not glibc)."""
    if not sys.platform.startswith("linux"):
        return None
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        mallopt = ctypes.CDLL(name).mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt)
        return None
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return mallopt


#: The compositor's fixed mmap threshold: blocks above it are mapped and unmapped when freed.
_RETURN_THRESHOLD = 256 * 1024


def return_freed_memory() -> bool:
    """Make malloc hand freed large blocks (images) back to the system at once (glibc only).

    glibc's mmap threshold is dynamic: after the first mapped block of a size is freed, blocks
    up to that size come from the heap, and a heap fragmented by the images of frames held
    open while a channel was down did not shrink when the channel came back (the compositor
    stayed at 4.6 GB). A fixed threshold keeps every image a mapping of its own. Returns
    whether the setting took.
    """
    mallopt = _mallopt()
    return mallopt is not None and bool(mallopt(_M_MMAP_THRESHOLD, _RETURN_THRESHOLD))


def keep_freed_memory() -> bool:
    """Make malloc keep freed frame-sized blocks for reuse (glibc on Linux only; elsewhere
    nothing is changed). Process-wide: called by a process that renders frame after frame
    (the channel worker, the frame benchmark). Returns whether the setting took."""
    mallopt = _mallopt()
    return (mallopt is not None and bool(mallopt(_M_MMAP_THRESHOLD, _THRESHOLD))
            and bool(mallopt(_M_TRIM_THRESHOLD, _TRIM)))
