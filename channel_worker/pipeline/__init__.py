"""The channel pipeline (docs/pipeline.md).

numba's on-disk cache (``cache=True``) checks only the source file of the function it caches, not
of the functions it inlines from other modules: a kernel that inlines fog.fog_depth keeps its
old machine code after fog.py changes. On import, the cache files in this package's
__pycache__ are dropped whenever any module of the package changed since they were written
(a hash of the sources is kept beside them), so a pulled change never runs stale kernels. A
fresh checkout compiles anyway.
"""

from __future__ import annotations

import hashlib
from pathlib import Path


def _drop_stale_kernel_cache() -> None:
    here = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(here.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    stamp = here / "__pycache__" / "kernel-sources.sha256"
    key = digest.hexdigest()
    try:
        if stamp.read_text() == key:
            return
    except OSError:
        pass
    try:
        for cached in stamp.parent.glob("*.nb[ic]"):
            cached.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(key)
    except OSError:
        # A read-only install: numba then caches under its user-wide directory, which this
        # does not reach (an upgrade there should clear it; docs/pipeline.md).
        pass


_drop_stale_kernel_cache()
