"""The voxel terrain database of JP H07-76990: pages of voxels at several resolution levels.

Layout (docs/terrain-database.md):

- A 2-D ground grid of square voxels. Level 0 voxels are ``spacing_m`` wide; level L voxels are
  ``spacing_m * 2**L`` wide and are the 2 x 2 average of level L - 1.
- Every voxel holds its four corner heights and four corner colours (JP H07-76990: "these four
  intensity and height values are stored with each voxel to avoid multiple database access at
  run time"); except at discontinuities they copy the neighbours' corners. Corner order is
  south-west, south-east, north-west, north-east (CORNERS).
- Voxels are stored in fixed-size pages of ``page_size`` x ``page_size`` voxels. Each level has a
  page table: page (px, py) of level L covers voxels [px P, (px + 1) P) x [py P, (py + 1) P) of
  that level and is stored at ``page_table[table_offset[L] + py * pages_x[L] + px]`` (an index
  into the page arrays, or -1 when the level lacks that page: the renderer then takes the next
  coarser level). The coarsest level has every page.
- Heights are float32 metres above ``origin[2]``; the world position (float64) of voxel corner
  (i, j) of level L is ``origin + (i, j, 0) * spacing_m * 2**L`` plus the stored height.
- Colours are sRGB-encoded uint8 (decoded to linear by the renderer with a 256-entry table).
- A voxel may call a vertical pattern (JP H07-76990 "pattern insertion": trees, buildings): its
  ``pattern`` entry is 0 for plain ground or k >= 1 for ``patterns[k - 1]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

FORMAT = "ig-terrain/1"

#: Corner order inside a voxel: (dx, dy) offsets in voxels.
CORNERS = ((0, 0), (1, 0), (0, 1), (1, 1))

DEFAULT_PAGE_SIZE = 128


class TerrainError(ValueError):
    """A terrain database or source that cannot be used; the message names the field and value."""


@dataclass(frozen=True)
class Pattern:
    """A vertical pattern called by marked voxels: opaque bands stacked from the ground up.

    Attributes:
        name: shown in reports.
        top_m: (B,) float32 strictly increasing heights above the voxel's ground of each band's
            top; band 0 starts at the ground, band k at top_m[k - 1].
        rgb: (B, 3) uint8 sRGB colour of each band (the last band's colour is also the top's).
    """

    name: str
    top_m: np.ndarray
    rgb: np.ndarray


@dataclass(frozen=True)
class TerrainDatabase:
    """A loaded (possibly memory-mapped) terrain database.

    Attributes:
        spacing_m: level-0 voxel width, metres.
        origin: (3,) float64 world position of the south-west corner of voxel (0, 0); heights
            are relative to origin[2].
        nx, ny: level-0 voxels east and north.
        page_size: voxels per page side (P).
        levels: number of resolution levels (level levels - 1 is the coarsest).
        pages_x, pages_y: (levels,) int64 page-table size per level.
        table_offset: (levels,) int64 start of each level's table in page_table.
        page_table: (sum pages_x * pages_y,) int32 page index or -1.
        z: (N, P, P, 4) float32 corner heights, metres above origin[2]; [page, vy, vx, corner].
        rgb: (N, P, P, 4, 3) uint8 sRGB corner colours.
        pattern: (N, P, P) uint8 0 or 1 + index into patterns.
        patterns: the vertical patterns.
        z_min, z_max: lowest and highest stored corner (over every level, patterns' tops
            included in z_max), metres above origin[2].
        info: free metadata (source, licence, geodetic origin, build options).
        source: where it was loaded from (for messages).
    """

    spacing_m: float
    origin: np.ndarray
    nx: int
    ny: int
    page_size: int
    levels: int
    pages_x: np.ndarray
    pages_y: np.ndarray
    table_offset: np.ndarray
    page_table: np.ndarray
    z: np.ndarray
    rgb: np.ndarray
    pattern: np.ndarray
    patterns: tuple[Pattern, ...] = ()
    z_min: float = 0.0
    z_max: float = 0.0
    info: dict = field(default_factory=dict)
    source: str = ""

    @property
    def extent_m(self) -> tuple[float, float]:
        """(east, north) size of the covered area, metres."""
        return self.nx * self.spacing_m, self.ny * self.spacing_m

    def level_size(self, level: int) -> tuple[int, int]:
        """(voxels east, voxels north) of a level: ceil(n / 2**level)."""
        return -(-self.nx // (1 << level)), -(-self.ny // (1 << level))

    def page_index(self, level: int, px: int, py: int) -> int:
        """Index of page (px, py) of a level in the page arrays, or -1 if the level lacks it."""
        if not (0 <= px < self.pages_x[level] and 0 <= py < self.pages_y[level]):
            return -1
        return int(self.page_table[self.table_offset[level] + py * self.pages_x[level] + px])


def level_count(nx: int, ny: int, page_size: int) -> int:
    """Number of levels of an nx x ny voxel database: levels are added until one page holds a level.

    Level L is ceil(n / 2**L) voxels wide, so the count is the smallest L + 1 with both
    ceil(nx / 2**L) and ceil(ny / 2**L) <= page_size (1 when level 0 already fits).

    Raises:
        TerrainError: nx, ny or page_size below 1 (the loop would never end: a level is at least
            one voxel wide).
    """
    for name, value in (("nx", nx), ("ny", ny), ("page_size", page_size)):
        if value < 1:
            raise TerrainError(f"{name}: {value!r} is not >= 1")
    levels = 1
    while max(-(-nx // (1 << (levels - 1))), -(-ny // (1 << (levels - 1)))) > page_size:
        levels += 1
    return levels


def page_layout(nx: int, ny: int, page_size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pages_x, pages_y, table_offset) of the levels of an nx x ny voxel database (int64 each).

    Level L has ceil(level_size / page_size) pages per side; the levels' tables follow each other
    in page_table, finest first.
    """
    levels = level_count(nx, ny, page_size)
    size_x = np.array([-(-nx // (1 << lv)) for lv in range(levels)], np.int64)
    size_y = np.array([-(-ny // (1 << lv)) for lv in range(levels)], np.int64)
    pages_x = -(-size_x // page_size)
    pages_y = -(-size_y // page_size)
    table_offset = np.concatenate([[0], np.cumsum(pages_x * pages_y)[:-1]]).astype(np.int64)
    return pages_x, pages_y, table_offset


@dataclass(frozen=True)
class PatternBands:
    """A database's vertical patterns as arrays for kernels (the line-of-sight queries and the
    test references walk them; the renderer draws the bands from its own tables).

    Attributes:
        top_m: (K, B) float64 top of each band above the voxel's highest corner, metres; a
            pattern with fewer than B bands repeats its last top.
        rgb: (K, B, 3) float64 linear colour of each band.
        count: (K,) int64 bands of each pattern.
        z_top: the highest point of the terrain with its patterns, from the height data rather
            than the header's z_max (a wrong header cannot cut a hill off); -inf when empty.
    """

    top_m: np.ndarray
    rgb: np.ndarray
    count: np.ndarray
    z_top: float


def pattern_bands(terrain: TerrainDatabase) -> PatternBands:
    """The PatternBands of a database (one row, zero bands' worth, when it has no pattern).

    Raises:
        ValueError: a pattern whose tops and colours do not describe one band or more.
    """
    from services.rig.colour import srgb_to_linear

    k = max(len(terrain.patterns), 1)
    bands = max([1] + [len(p.top_m) for p in terrain.patterns])
    top = np.zeros((k, bands))
    rgb = np.zeros((k, bands, 3))
    count = np.ones(k, np.int64)
    for n, pattern in enumerate(terrain.patterns):
        tops = np.asarray(pattern.top_m, np.float64)
        b = tops.shape[0]
        if b < 1 or np.asarray(pattern.rgb).shape != (b, 3):
            raise ValueError(f"pattern {pattern.name!r}: top_m {tops.shape} and rgb "
                             f"{np.asarray(pattern.rgb).shape} do not describe B >= 1 bands")
        top[n, :b], top[n, b:] = tops, tops[-1]
        rgb[n, :b] = srgb_to_linear(np.asarray(pattern.rgb, np.uint8) / 255.0)  # float64
        count[n] = b
    z = np.asarray(terrain.z)
    tallest = max([0.0] + [float(np.float32(p.top_m[-1])) for p in terrain.patterns])
    return PatternBands(top, rgb, count, float(z.max()) + tallest if z.size else -np.inf)

