"""Where numba keeps the pipeline's compiled kernels, and why the place is named after their
sources.

numba's on-disk cache (``cache=True``) checks a compiled kernel against the time stamp of the
kernel's own source file only. The pipeline's kernels inline helpers from other modules (the fog
look-up, the haze, the shading of a sample), so an edit to a helper would leave stale machine
code in every kernel that inlined it. The pipeline is therefore cached as a whole, in a
directory named after a hash of every source file of the pipeline package and numba's version:
an edit anywhere gives a new directory, whose kernels compile afresh, and nothing is deleted
behind anyone's back. All processes of a machine that run the same sources share one
directory, so the kernels compile once per machine and checkout (numba keys its entries by the
source files' paths and time stamps, so another clone of the same sources compiles again):
`ig compile` does it ahead of a run (`ig demo` runs it before it starts the workers), and
`ig compile --prune` removes the directories of other sources.

The directory is ``$IG_CACHE_DIR/numba/<key>`` (IG_CACHE_DIR defaults to ~/.cache/ig-rig, where
the bundled terrain is cached too). It is chosen by setting NUMBA_CACHE_DIR when the pipeline
package is imported, before any kernel is defined (numba reads it when a kernel is decorated).

Several processes may write the one directory at once (`ig compile`'s compile processes,
workers started on a cold cache), and numba saves a kernel without a lock: it reads the
kernel's index, takes the first data file name the index does not use, and writes index and
data back. Two processes saving two specialisations of one kernel at once can both take the
same name, and the index then points one specialisation at the other's machine code.
serialise_cache_writes() makes a process's saves hold a lock; `ig compile` calls it in each of
its processes (it is not called on import: importing the pipeline package does not load numba,
which tools such as `ig terrain info` never need).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

#: The lock file numba's saves take, in each directory of kernels (serialise_cache_writes).
LOCK_NAME = ".ig-save.lock"

#: The package whose sources key the cache.
_PIPELINE = Path(__file__).resolve().parent


def cache_root() -> Path:
    """$IG_CACHE_DIR/numba, IG_CACHE_DIR defaulting to ~/.cache/ig-rig."""
    base = os.environ.get("IG_CACHE_DIR")
    return (Path(base) if base else Path.home() / ".cache" / "ig-rig") / "numba"


def sources_key() -> str:
    """16 hex digits of a hash of every pipeline source file (path and bytes) and numba's and
    Python's versions."""
    digest = hashlib.sha256()
    for path in sorted(_PIPELINE.rglob("*.py")):
        digest.update(path.relative_to(_PIPELINE).as_posix().encode())
        digest.update(path.read_bytes())
    digest.update(metadata.version("numba").encode())
    digest.update(sys.version.encode())
    return digest.hexdigest()[:16]


def sources_stamp() -> str:
    """16 hex digits of a hash of what numba itself checks a cached kernel against: the
    absolute path of every pipeline source file (its index lives under a directory named after
    the path) and the file's modification time and size. The same sources in another clone, or
    checked out again, share kernel_cache_dir() but none of numba's entries there: each clone
    compiles afresh, and `ig compile` must know it will (compile_jobs.compiled_before)."""
    digest = hashlib.sha256()
    for path in sorted(_PIPELINE.rglob("*.py")):
        st = path.stat()
        digest.update(f"{path}\0{st.st_mtime_ns}\0{st.st_size}\0".encode())
    return digest.hexdigest()[:16]


def kernel_cache_dir() -> Path:
    """The cache directory of the pipeline as its sources are now."""
    return cache_root() / sources_key()


def use_kernel_cache() -> Path:
    """Point numba's cache at kernel_cache_dir() for this process and its children.

    Called once, by the pipeline package's __init__, before any kernel module is imported.
    """
    path = kernel_cache_dir()
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    if "numba" in sys.modules:
        # numba was imported already (by another package's kernel): its configuration is read
        # again so that the pipeline's kernels, decorated from now on, see the directory.
        from numba.core import config
        config.reload_config()
    return path


def serialise_cache_writes() -> None:
    """Make every numba cache save of this process hold an exclusive lock (module doc).

    An advisory flock on LOCK_NAME in the directory of the kernel's index, held while numba
    reads the index, picks a data file name and writes both; loads need no lock (numba
    replaces each file atomically). Every process that may compile while another writes the
    same cache should call it before it compiles. Without flock (not POSIX) saves stay
    unlocked.
    """
    try:
        import fcntl
    except ImportError:
        return
    from numba.core import caching

    cache_file = caching.IndexDataCacheFile
    if getattr(cache_file.save, "ig_locked", False):
        return  # wrapped by an earlier call
    unlocked_save = cache_file.save

    def save(self: Any, key: Any, data: Any) -> None:
        with open(os.path.join(self._cache_path, LOCK_NAME), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            unlocked_save(self, key, data)

    save.ig_locked = True  # type: ignore[attr-defined]
    cache_file.save = save  # type: ignore[method-assign]


def prune(keep: Path) -> list[Path]:
    """Remove every cache directory but keep (those of other sources); returns the removed."""
    root = keep.parent
    removed = []
    if root.is_dir():
        for other in root.iterdir():
            if other.is_dir() and other != keep:
                shutil.rmtree(other, ignore_errors=True)
                removed.append(other)
    return removed
