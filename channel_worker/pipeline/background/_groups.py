"""What the background stage's kernels take: the stage's own grouped values.

The contract (contract.py) holds what crosses a stage boundary (FrameConstants, the air array,
Background); the groups here never leave the background stage. Each is a NamedTuple of arrays
and numbers, which numba passes whole into a kernel, so every kernel's signature says at a
glance what it consumes:

    scan_kernel(pages: VoxelPages, grid: ColumnGrid, limits: ScanLimits, air, out_pre, out_visits,
                threads)
    scan_clouds_kernel(slabs: CloudSlabs, columns: CloudColumns, eye, r_far, air, out)
    warp_kernel(frame, pre: Preimage, air, sky_haze: SkyHaze, clouds: CloudImage,
                depth: SampleDepth, block, out: BackgroundArrays, threads)
    sky_earth_kernel(frame, air, out_rgb, out_range)

Angles are radians: azimuth clockwise from north, elevation up from the horizontal. Ground
ranges and heights are metres.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Pre-image texel channels: premultiplied linear RGB after haze and fog, coverage, and the
#: inverse range (1/metres) of the surface seen at the texel's centre elevation (0 where none
#: is). Written by the column scan, read by the warp.
PRE_R, PRE_G, PRE_B, PRE_A, PRE_IR = 0, 1, 2, 3, 4
PRE_CHANNELS = 5

#: Cloud texel channels: premultiplied linear RGB after haze and fog, opacity, and the range
#: (metres) at which the texel's ray enters cloud (+inf where it meets none).
CLOUD_CHANNELS = 5


class VoxelPages(NamedTuple):
    """The terrain database as the column scan reads it (scene/terrain/database.py).

    Attributes:
        z: (P, page, page, 4) float32 voxel corner heights, metres above the database origin.
        rgb: (P, page, page, 4, 3) uint8 sRGB voxel corner colours.
        pattern: (P, page, page) uint8 vertical pattern per voxel (0: plain ground, k:
            pattern k - 1).
        page_table: (T,) int32 page of each level's (px, py), or -1 where the level lacks it.
        table_offset: (levels,) int64 where each level's entries start in page_table.
        pages_x, pages_y: (levels,) int64 pages across and up each level.
        log2_page: log2 of the page size in voxels.
        level_nx, level_ny: (levels,) int64 voxels across and up each level.
        spacing: level-0 voxel width, metres (level L voxels are spacing 2**L wide).
        extent_x, extent_y: the database's ground extent, metres east and north.
        z_max: highest corner height of any level, metres above the database origin.
        pat_top: (K, B) float32 each pattern's band tops, metres above the voxel's highest
            corner.
        pat_rgb: (K, B, 3) float32 each band's linear colour.
        pat_bands: (K,) int64 bands per pattern.
        lut: (256,) float32 sRGB byte -> linear.
    """

    z: np.ndarray
    rgb: np.ndarray
    pattern: np.ndarray
    page_table: np.ndarray
    table_offset: np.ndarray
    pages_x: np.ndarray
    pages_y: np.ndarray
    log2_page: int
    level_nx: np.ndarray
    level_ny: np.ndarray
    spacing: float
    extent_x: float
    extent_y: float
    z_max: float
    pat_top: np.ndarray
    pat_rgb: np.ndarray
    pat_bands: np.ndarray
    lut: np.ndarray


class ColumnGrid(NamedTuple):
    """The pre-image grid as the column scan walks it (terrain.PreimageGrid). Every visible
    surface segment's call takes it, so it holds only what those calls read (which rows each
    column scans is in ScanLimits).

    Attributes:
        phi_lo: azimuth of column 0's left edge; column j is centred on phi_lo + (j + 1/2)
            dphi.
        dphi: column width (azimuth).
        ncols: columns.
        theta0: elevation of row 0's lower edge; row i spans theta0 + i dtheta .. + dtheta.
        dtheta: row height (elevation).
        nrows: rows.
        row_cs: (nrows, 2) float64 cosine and sine of each row's centre elevation.
        top_cs: (nrows, 2) float64 cosine and sine of each row's top edge.
    """

    phi_lo: float
    dphi: float
    ncols: int
    theta0: float
    dtheta: float
    nrows: int
    row_cs: np.ndarray
    top_cs: np.ndarray


class ScanLimits(NamedTuple):
    """Where the column scans start and how far they go.

    Attributes:
        first_row: (MAX_SKIP + 1,) int64 the lowest row a column whose index has k trailing
            zero bits scans (towards the nadir only every 2**k-th column is needed).
        eye: (3,) float64 eye position relative to the database origin, metres (kept above the
            surface, terrain.MIN_CLEARANCE_M).
        r_switch: (levels,) float64 ground range where level L + 1 takes over from level L,
            metres (inf for the coarsest).
        r_far: ground range beyond which nothing is scanned (the far plane, or opaque haze or
            fog), metres.
    """

    first_row: np.ndarray
    eye: np.ndarray
    r_switch: np.ndarray
    r_far: float


class Preimage(NamedTuple):
    """The zero-roll pre-image as the warp reads it.

    Attributes:
        texels: (ncols, nrows, PRE_CHANNELS) float32 (the PRE_* channels); a (1, 1,
            PRE_CHANNELS) zero stand-in covering the whole grid when there is no terrain.
        full: every azimuth is seen (the view holds the nadir or the zenith): columns wrap.
        phi_lo: azimuth of column 0's left edge.
        dphi: column width (azimuth).
        theta0: elevation of row 0's lower edge.
        dtheta: row height (elevation).
        span: azimuth the columns cover (ncols dphi).
    """

    texels: np.ndarray
    full: bool
    phi_lo: float
    dphi: float
    theta0: float
    dtheta: float
    span: float


class SkyHaze(NamedTuple):
    """The haze of the sky (range infinite), which depends on elevation alone.

    Attributes:
        table: (n,) float64 haze share at elevations theta0 + (i + 1/2) dtheta (one zero
            without haze).
        theta0: elevation of entry 0's lower edge.
        dtheta: elevation step between entries.
    """

    table: np.ndarray
    theta0: float
    dtheta: float


class CloudImage(NamedTuple):
    """The coarse cloud pre-image (clouds.scan_clouds) as the warp lays it over the background.

    Attributes:
        on: the scene has clouds.
        texels: (ncols, nrows, CLOUD_CHANNELS) float32; a (1, 1, CLOUD_CHANNELS) zero stand-in
            without clouds.
        col_ratio, row_ratio: pre-image texels per cloud texel along the columns and the rows.
    """

    on: bool
    texels: np.ndarray
    col_ratio: float
    row_ratio: float


class SampleDepth(NamedTuple):
    """Where the warp writes per-sample terrain depth (Background.inv_z), and how.

    Attributes:
        margin_m: the scene's polygon margin: the terrain is pushed back by this much height,
            metres, so a polygon lying on it wins.
        tile: sub-area edge length, pixels.
        need: (tiles,) bool per sub-area (row-major) whether depth is wanted there (it holds
            polygons to test against the terrain); elsewhere inv_z is left 0.
    """

    margin_m: float
    tile: int
    need: np.ndarray


class BackgroundArrays(NamedTuple):
    """The arrays the warp fills (Background's rgb, inv_z, range_m and cloud).

    Attributes:
        rgb: (H, W, 3) float32.
        inv_z: (H, W, S) float32.
        range_m: (H, W) float32.
        cloud: (H, W, CLOUD_CHANNELS) float32, or contract.no_cloud() without clouds.
    """

    rgb: np.ndarray
    inv_z: np.ndarray
    range_m: np.ndarray
    cloud: np.ndarray


class CloudSlabs(NamedTuple):
    """The cloud database as the cloud scan reads it (scene/atmosphere.Clouds).

    Attributes:
        base, top: (ny + 1, nx + 1) node grids of the slab's base and top, world metres.
        density: (ny + 1, nx + 1) node grid of extinction, 1/metres.
        cell: node spacing, metres.
        colour: (3,) linear RGB of a cloud's lit top.
        base_shade: brightness of the base relative to the top.
    """

    base: np.ndarray
    top: np.ndarray
    density: np.ndarray
    cell: float
    colour: np.ndarray
    base_shade: float


class CloudColumns(NamedTuple):
    """The coarse cloud grid as the cloud scan walks it.

    Attributes:
        phi_lo: azimuth of column 0's left edge; column j is centred on phi_lo + (j + 1/2)
            dphi.
        dphi: column width (azimuth).
        ncols: columns.
        row_tan, row_inv_cos, row_sin: (nrows,) float64 tangent, 1 / cosine and sine of each
            row's centre elevation (kept short of +-90 degrees).
    """

    phi_lo: float
    dphi: float
    ncols: int
    row_tan: np.ndarray
    row_inv_cos: np.ndarray
    row_sin: np.ndarray
