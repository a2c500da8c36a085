"""The terrain database on disk: a directory (``NAME.igt``) of one JSON header and four .npy arrays.

::

    NAME.igt/
      terrain.json    format "ig-terrain/1", spacing_m, origin, nx, ny, page_size, levels,
                      pages_x, pages_y, table_offset, z_min, z_max, patterns, info
      z.npy           (N, P, P, 4) float32 corner heights, metres above origin[2]
      rgb.npy         (N, P, P, 4, 3) uint8 sRGB corner colours
      pattern.npy     (N, P, P) uint8 pattern index (0 = plain ground)
      page_table.npy  (sum of pages_x * pages_y,) int32 page index or -1

The arrays are memory-mapped on load (mmap=True): a page is read from disk the first time the
renderer touches it, like JP H07-76990's pages loaded dynamically into the active database as the
view moves. Loading validates everything the renderer relies on, so a malformed database is
refused here with a TerrainError naming the file, the field and the value, never later.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from .database import FORMAT, Pattern, TerrainDatabase, TerrainError, level_count, page_layout

HEADER = "terrain.json"
ARRAYS = ("z", "rgb", "pattern", "page_table")
_KEYS = {"format", "spacing_m", "origin", "nx", "ny", "page_size", "levels", "pages_x", "pages_y",
         "table_offset", "z_min", "z_max", "patterns", "info"}
#: Pages checked per step of the data pass (bounds the memory it needs: 64 pages of 128 x 128
#: voxels are 16 MB of heights).
_CHECK_PAGES = 64
_RGB = re.compile(r"^#[0-9a-fA-F]{6}$")


def save_terrain(db: TerrainDatabase, path: str | Path) -> Path:
    """Write a database as a directory (created if missing; its files replaced).

    Args:
        db: the database.
        path: the directory, by convention ``NAME.igt``.

    Returns:
        The directory.

    Raises:
        TerrainError: info that JSON cannot hold (NaN, objects).
    """
    path = Path(path)
    header = {
        "format": FORMAT, "spacing_m": float(db.spacing_m), "origin": [float(v) for v in db.origin],
        "nx": int(db.nx), "ny": int(db.ny), "page_size": int(db.page_size), "levels": int(db.levels),
        "pages_x": [int(v) for v in db.pages_x], "pages_y": [int(v) for v in db.pages_y],
        "table_offset": [int(v) for v in db.table_offset],
        "z_min": float(db.z_min), "z_max": float(db.z_max),
        "patterns": [{"name": p.name, "top_m": [float(v) for v in p.top_m],
                      "rgb": ["#{:02x}{:02x}{:02x}".format(*(int(c) for c in row)) for row in p.rgb]}
                     for p in db.patterns],
        "info": db.info,
    }
    try:
        # One line per field: the small arrays stay readable, the info stays diffable.
        text = "{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v, allow_nan=False, default=_jsonable)}"
                                   for k, v in header.items()) + "\n}"
    except (TypeError, ValueError) as exc:
        raise TerrainError(f"{path / HEADER}: info: {exc}") from None
    path.mkdir(parents=True, exist_ok=True)
    dtypes = {"z": np.float32, "rgb": np.uint8, "pattern": np.uint8, "page_table": np.int32}
    for name in ARRAYS:
        np.save(path / f"{name}.npy", np.ascontiguousarray(getattr(db, name), dtype=dtypes[name]))
    (path / HEADER).write_text(text + "\n")
    return path


def load_terrain(path: str | Path, *, mmap: bool = True) -> TerrainDatabase:
    """Load and validate a database directory.

    Args:
        path: the ``NAME.igt`` directory.
        mmap: memory-map the arrays (read-only, pages come from disk on first touch); False
            reads them into memory.

    Raises:
        TerrainError: anything missing or inconsistent, naming the file, field and value.
    """
    path = Path(path)
    head_file = path / HEADER
    if not head_file.is_file():
        raise TerrainError(f"{head_file}: no such file (is {str(path)!r} a terrain database?)")
    try:
        head = json.loads(head_file.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise TerrainError(f"{head_file}: not readable JSON: {exc}") from None
    h = _Header(head_file, head)
    arrays = {name: _load_array(path / f"{name}.npy", mmap) for name in ARRAYS}
    n_pages = _check_arrays(path, arrays, h)
    _check_table(path / "page_table.npy", arrays["page_table"], h, n_pages)
    _check_data(path, arrays, h)
    return TerrainDatabase(
        spacing_m=h.spacing_m, origin=h.origin, nx=h.nx, ny=h.ny, page_size=h.page_size, levels=h.levels,
        pages_x=h.pages_x, pages_y=h.pages_y, table_offset=h.table_offset, page_table=arrays["page_table"],
        z=arrays["z"], rgb=arrays["rgb"], pattern=arrays["pattern"], patterns=h.patterns,
        z_min=h.z_min, z_max=h.z_max, info=h.info, source=str(path))


class _Header:
    """The validated fields of terrain.json."""

    def __init__(self, file: Path, doc: Any) -> None:
        self.file = file
        if not isinstance(doc, dict):
            raise self.fail("(top level)", doc, "is not a JSON object")
        if doc.get("format") != FORMAT:
            raise self.fail("format", doc.get("format"), f"is not {FORMAT!r}")
        missing, unknown = _KEYS - doc.keys(), doc.keys() - _KEYS
        if missing:
            raise TerrainError(f"{file}: {min(missing)}: missing")
        if unknown:
            raise self.fail(min(unknown), doc[min(unknown)], "is not a field of " + FORMAT)
        self.spacing_m = self.number(doc, "spacing_m", positive=True)
        origin = doc["origin"]
        if not (isinstance(origin, list) and len(origin) == 3 and all(_is_finite(v) for v in origin)):
            raise self.fail("origin", origin, "is not 3 finite numbers")
        self.origin = np.array(origin, np.float64)
        self.nx, self.ny = self.integer(doc, "nx", 1, 1 << 24), self.integer(doc, "ny", 1, 1 << 24)
        self.page_size = self.integer(doc, "page_size", 1, 4096)
        levels = level_count(self.nx, self.ny, self.page_size)
        self.levels = self.integer(doc, "levels", levels, levels)
        want = dict(zip(("pages_x", "pages_y", "table_offset"), page_layout(self.nx, self.ny, self.page_size),
                        strict=True))
        for name, expected in want.items():
            if doc[name] != [int(v) for v in expected]:
                raise self.fail(name, doc[name], f"is not {[int(v) for v in expected]} "
                                                 f"(nx {self.nx}, ny {self.ny}, page_size {self.page_size})")
        self.pages_x, self.pages_y, self.table_offset = want["pages_x"], want["pages_y"], want["table_offset"]
        self.z_min, self.z_max = self.number(doc, "z_min"), self.number(doc, "z_max")
        if self.z_min > self.z_max:
            raise self.fail("z_max", self.z_max, f"is below z_min {self.z_min!r}")
        self.patterns = self.read_patterns(doc["patterns"])
        if not isinstance(doc["info"], dict):
            raise self.fail("info", doc["info"], "is not a JSON object")
        self.info = doc["info"]

    def fail(self, field: str, value: Any, message: str) -> TerrainError:
        return TerrainError(f"{self.file}: {field}: {_show(value)} {message}")

    def number(self, doc: dict, name: str, *, positive: bool = False) -> float:
        value = doc[name]
        if not _is_finite(value) or (positive and not value > 0):
            raise self.fail(name, value, "is not a finite number" + (" > 0" if positive else ""))
        return float(value)

    def integer(self, doc: dict, name: str, lo: int, hi: int) -> int:
        value = doc[name]
        if not (isinstance(value, int) and not isinstance(value, bool) and lo <= value <= hi):
            raise self.fail(name, value, f"is not a whole number in [{lo}, {hi}]")
        return value

    def read_patterns(self, items: Any) -> tuple[Pattern, ...]:
        if not isinstance(items, list) or len(items) > 255:
            raise self.fail("patterns", items, "is not a list of at most 255 patterns")
        out = []
        for k, item in enumerate(items):
            where = f"patterns[{k}]"
            if not (isinstance(item, dict) and item.keys() == {"name", "top_m", "rgb"}):
                raise self.fail(where, item, "is not {name, top_m, rgb}")
            top, rgb = item["top_m"], item["rgb"]
            if not isinstance(item["name"], str):
                raise self.fail(f"{where}.name", item["name"], "is not a string")
            if not (isinstance(top, list) and top and all(_is_finite(v) for v in top)
                    and top[0] > 0 and all(b > a for a, b in pairwise(top))):
                raise self.fail(f"{where}.top_m", top, "is not a non-empty list of increasing heights > 0")
            if not (isinstance(rgb, list) and len(rgb) == len(top)
                    and all(isinstance(c, str) and _RGB.match(c) for c in rgb)):
                raise self.fail(f"{where}.rgb", rgb, f"is not {len(top)} '#rrggbb' colours (one per band)")
            out.append(Pattern(item["name"], np.array(top, np.float32),
                               np.array([[int(c[i:i + 2], 16) for i in (1, 3, 5)] for c in rgb], np.uint8)))
        return tuple(out)


def _load_array(file: Path, mmap: bool) -> np.ndarray:
    try:
        return np.load(file, mmap_mode="r" if mmap else None, allow_pickle=False)
    except FileNotFoundError:
        raise TerrainError(f"{file}: no such file") from None
    except (OSError, ValueError, EOFError) as exc:
        raise TerrainError(f"{file}: not a readable .npy array: {exc}") from None


def _check_arrays(path: Path, arrays: dict[str, np.ndarray], h: _Header) -> int:
    """Dtypes and shapes against the header; returns the number of stored pages."""
    p = h.page_size
    n = arrays["z"].shape[0] if arrays["z"].ndim else 0
    expect = {"z": (np.float32, (n, p, p, 4)), "rgb": (np.uint8, (n, p, p, 4, 3)),
              "pattern": (np.uint8, (n, p, p)), "page_table": (np.int32, (int((h.pages_x * h.pages_y).sum()),))}
    for name, (dtype, shape) in expect.items():
        a, file = arrays[name], path / f"{name}.npy"
        if a.dtype != np.dtype(dtype):
            raise TerrainError(f"{file}: dtype: {str(a.dtype)!r} is not {np.dtype(dtype).str!r}")
        if a.shape != shape:
            raise TerrainError(f"{file}: shape: {a.shape} is not {shape} (page_size {p}, {n} pages in z.npy)")
        if not a.flags.c_contiguous:
            raise TerrainError(f"{file}: order: Fortran-ordered; the renderer needs C order")
    if n < 1:
        raise TerrainError(f"{path / 'z.npy'}: shape: {arrays['z'].shape} holds no page")
    return n


def _check_table(file: Path, table: np.ndarray, h: _Header, n_pages: int) -> None:
    bad = np.flatnonzero((table < -1) | (table >= n_pages))
    if bad.size:
        raise TerrainError(f"{file}: page_table[{int(bad[0])}]: {int(table[bad[0]])} is not -1 or a page "
                           f"index in [0, {n_pages})")
    top = h.levels - 1
    start, count = int(h.table_offset[top]), int(h.pages_x[top] * h.pages_y[top])
    missing = np.flatnonzero(table[start:start + count] < 0)
    if missing.size:
        k = int(missing[0])
        raise TerrainError(f"{file}: page_table[{start + k}]: -1, but the coarsest level {top} must have "
                           f"every page (page {k % int(h.pages_x[top])}, {k // int(h.pages_x[top])})")


def _check_data(path: Path, arrays: dict[str, np.ndarray], h: _Header) -> None:
    """One pass over the pages: finite heights within [z_min, z_max], known pattern indices."""
    z, pattern = arrays["z"], arrays["pattern"]
    for start in range(0, z.shape[0], _CHECK_PAGES):
        block = np.asarray(z[start:start + _CHECK_PAGES])
        finite = np.isfinite(block)
        if not finite.all():
            page = start + int(np.argwhere(~finite)[0][0])
            raise TerrainError(f"{path / 'z.npy'}: z[{page}]: {_show(float(block[~finite][0]))} is not finite")
        lo, hi = float(block.min()), float(block.max())
        if lo < h.z_min or hi > h.z_max:
            raise TerrainError(f"{path / 'z.npy'}: z: {lo!r} .. {hi!r} is outside z_min .. z_max "
                               f"{h.z_min!r} .. {h.z_max!r} of {h.file.name}")
        top = int(np.asarray(pattern[start:start + _CHECK_PAGES]).max())
        if top > len(h.patterns):
            raise TerrainError(f"{path / 'pattern.npy'}: pattern: {top} is not 0 or one of the "
                               f"{len(h.patterns)} patterns")


def _is_finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _jsonable(value: Any) -> Any:
    """json.dumps default: numpy scalars and arrays, tuples already work."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} {value!r} is not JSON")


def build_cached(target: str | Path, build: Callable[[], TerrainDatabase]) -> Path:
    """A database directory built once: `target` if it is complete, else build() saved into a
    temporary directory beside it and renamed into place, so a reader never sees a half-written
    database and two processes building at once both end with the same complete one.

    Returns:
        The directory.
    """
    target = Path(target)
    if (target / HEADER).is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".build-", dir=target.parent))
    try:
        save_terrain(build(), tmp / "db.igt")
        try:
            os.rename(tmp / "db.igt", target)
        except OSError:
            # Another process renamed its build into place first: keep that one.
            if not (target / HEADER).is_file():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return target
