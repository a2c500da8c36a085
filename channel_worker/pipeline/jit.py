"""How the pipeline compiles its kernels beyond numba's defaults.

Hot per-tile and per-row functions are compiled without numba's reference counting
(``borrowing``): they take the contract's grouped values (NamedTuples of arrays) and hand them
to small inlined helpers in their inner loops, and numba increfs every array of a group handed
to an inlined helper, on every call, then cannot prune those increments across the helper's
branches. Measured on the approach scene (1280 x 1024, 16 samples, one core): the fused shading
loop took three times as long with them. A borrowing function only borrows arrays its caller
owns and allocates nothing (numba refuses to compile an allocation without reference counting).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

#: numba's option names for a cached function without reference counting (the CPU target's
#: ``_nrt`` option: not in numba's type stubs, hence passed as a mapping).
_BORROWING: dict[str, Any] = {"cache": True, "_nrt": False}


def borrowing(func: Callable[..., Any]) -> Any:
    """``@njit(cache=True)`` without reference counting, for functions that allocate nothing."""
    return njit(**_BORROWING)(func)


@njit(cache=True, inline="always")
def lanes(threads: int, n: int) -> int:
    """How many lanes a parallel kernel splits n unequal tasks into: one per thread (threads,
    numba.get_num_threads() read by the kernel's caller), at most n. Each lane then takes
    tasks from a shared queue (claim) until none is left.

    numba hands a prange's iterations to its threads in equal contiguous blocks whatever
    chunk size is set (measured with numba 0.68 on both the omp and workqueue layers: 48
    iterations on 2 threads went 0-23 and 24-47 with set_parallel_chunksize(1)), so a
    frame's sky rows fell to one thread and its ground rows to the other. Interleaving the
    tasks over the lanes (k, k + lanes, ...) balanced two threads, but not sixteen: at 16
    threads a 1024 x 768 frame's 48 rows of sub-areas are three per thread, and a thread
    holding two rows of the airfield finished long after the rest (visibility 4.5x over one
    thread on a 16-core machine). A queue hands each task to whichever lane is free, as
    OpenMP's dynamic schedule does, at the cost of one atomic add per task. (The thread count
    is an argument because numba.get_num_threads() inside a kernel makes it uncacheable: it
    reads the threading layer through a pointer.)
    """
    return max(1, min(threads, n))


@intrinsic
def _fetch_add(typingctx: Any, counter: Any, amount: Any) -> Any:
    """LLVM's atomic fetch-and-add on element 0 of a 1-D int64 array; the value before."""
    sig = types.int64(counter, types.int64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        array = context.make_array(signature.args[0])(context, builder, args[0])
        pointer = builder.gep(array.data, [ir.Constant(ir.IntType(64), 0)])
        # Monotonic: the counter orders nothing but itself; the tasks' results are published
        # by the barrier at the end of the parallel loop.
        return builder.atomic_rmw("add", pointer, args[1], "monotonic")

    return sig, codegen


@njit(cache=True, inline="always")
def claim(queue: Any) -> int:
    """The next task of a work queue shared by a parallel loop's lanes: queue is a 1-element
    int64 array holding the next unclaimed task, 0 at the start (new_queue); a lane stops when
    the task it claims is past the last. Each task goes to exactly one lane, whichever asks
    first (dynamic scheduling)."""
    return int(_fetch_add(queue, np.int64(1)))  # type: ignore[call-arg]  # numba's typing call


@njit(cache=True, inline="always")
def new_queue() -> Any:
    """An empty work queue for claim (allocate it before the parallel loop, outside it).

    Only claim reads it: after the loop a plain queue[0] can read the 0 it was created with,
    as LLVM does not see the loop's atomic adds and folds the load."""
    return np.zeros(1, np.int64)


def thread_pool_size() -> int:
    """The threads numba's parallel kernels can use at most in this process
    (NUMBA_NUM_THREADS; its configuration module sets it at run time)."""
    return int(vars(numba.config)["NUMBA_NUM_THREADS"])


@intrinsic
def _cttz64(typingctx: Any, word: Any) -> Any:
    """LLVM's count-trailing-zeros on a uint64 (one tzcnt/bsf instruction)."""
    sig = types.uint64(types.uint64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 0))

    return sig, codegen


@intrinsic
def _ctpop64(typingctx: Any, word: Any) -> Any:
    """LLVM's population count on a uint64 (one popcnt instruction where the CPU has it)."""
    sig = types.uint64(types.uint64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.ctpop(args[0])

    return sig, codegen


@njit(cache=True, inline="always")
def lowest_bit(word: Any) -> int:
    """Index of the lowest set bit of a non-zero uint64 word (64 for 0)."""
    return int(_cttz64(np.uint64(word)))  # type: ignore[call-arg]  # numba's typing call


@njit(cache=True, inline="always")
def bit_count(word: Any) -> int:
    """How many bits of a uint64 word are set."""
    return int(_ctpop64(np.uint64(word)))  # type: ignore[call-arg]  # numba's typing call


@njit(cache=True, inline="always")
def low_bits(n: int) -> Any:
    """uint64 with bits 0 .. n - 1 set, 0 <= n <= 64 (a shift by 64 is undefined in LLVM, so
    64 is its own case)."""
    if n >= 64:
        return ~np.uint64(0)
    return (np.uint64(1) << np.uint64(n)) - np.uint64(1)
