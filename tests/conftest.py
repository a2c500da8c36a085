"""What the whole suite shares: a bytecode cache for the processes the tests start.

The suite starts a few hundred Python processes (`python -m services.cli ...`: the rigs of the
fault and integration tests, the compile groups, the command-line tests). Where the environment
says PYTHONDONTWRITEBYTECODE (as on the 2-core development VM), none of them may write a .pyc,
so every one of them compiled numba's, grpc's, numpy's and the rig's sources afresh: about a
second of a core for a host, more for a worker. For the session, the children get a bytecode
cache of their own instead, in a temporary directory (PYTHONPYCACHEPREFIX: nothing is written
beside any source file, in the checkout or the virtual environment), removed at the end. What
the processes run is the same; only their start is shorter. A session whose environment writes
bytecode already, or names its own PYTHONPYCACHEPREFIX, is left as it is.
"""

from __future__ import annotations

import os
import shutil
import tempfile

_PYCACHE: str | None = None


def pytest_configure(config):
    global _PYCACHE
    if os.environ.get("PYTHONDONTWRITEBYTECODE") and not os.environ.get("PYTHONPYCACHEPREFIX"):
        _PYCACHE = tempfile.mkdtemp(prefix="ig-tests-pycache-")
        os.environ["PYTHONPYCACHEPREFIX"] = _PYCACHE
        del os.environ["PYTHONDONTWRITEBYTECODE"]


def pytest_unconfigure(config):
    global _PYCACHE
    if _PYCACHE is not None:
        os.environ["PYTHONDONTWRITEBYTECODE"] = "1"
        os.environ.pop("PYTHONPYCACHEPREFIX", None)
        shutil.rmtree(_PYCACHE, ignore_errors=True)
        _PYCACHE = None


#: The test that compiles every kernel into a cold cache (tests/channel_worker/test_compile.py):
#: run first, while the suite's own kernel cache is still as the session found it, so that on a
#: cold one (a fresh clone, CI) its compile is the session's only one (cold_kernel_cache there).
COLD_COMPILE = "test_compile.py::test_compile_jobs_fill_a_cold_cache_that_a_worker_then_loads_every_kernel_from"


def pytest_collection_modifyitems(session, config, items):
    first = [item for item in items if item.nodeid.endswith(COLD_COMPILE)]
    if first:
        items[:] = first + [item for item in items if item not in first]
