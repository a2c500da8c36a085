"""What the background stage's kernels take: the stage's own grouped values.

The contract (contract.py) holds what crosses a stage boundary (FrameConstants, the air array,
Background); the groups here never leave the background stage. Each is a NamedTuple of arrays
and numbers, which numba passes whole into a kernel, so every kernel's signature says at a
glance what it consumes:

    cast_kernel(pages: VoxelPages, detail: TerrainDetail, fan: LineFan, limits: ScanLimits,
                air, frame, sky: SkyTable, out: BackgroundArrays, aux: CastPixels, visits,
                threads)
    sample_depth_kernel(frame, aux: CastPixels, depth: SampleDepth, out_inv_z, threads)
    scan_clouds_kernel(slabs: CloudSlabs, columns: CloudColumns, eye, r_far, air, out)
    refine_clouds_kernel(slabs: CloudSlabs, quads: CloudQuads, eye, r_far, air, threads, out)
    cloud_over_kernel(frame, clouds: CloudImage, block, range_m, rgb, out_cloud, threads)
    sky_earth_kernel(frame, air, sky: SkyTable, out_rgb, out_range)

Angles are radians: azimuth clockwise from north, elevation up from the horizontal. Ground
ranges and heights are metres.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Cloud texel channels: premultiplied linear RGB after haze and fog, opacity, and the range
#: (metres) at which the texel's ray enters cloud (+inf where it meets none).
CLOUD_CHANNELS = 5

class VoxelPages(NamedTuple):
    """The terrain database as the cast reads it (scene/terrain/database.py).

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
        pat_canopy: (K,) bool whether a pattern's top is a forest's canopy (a "tree" pattern:
            the land's detail textures it).
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
    pat_canopy: np.ndarray
    lut: np.ndarray


class LineFan(NamedTuple):
    """The lines of the terrain cast (cast.line_fan): screen lines through the vertical
    vanishing point V (the image of the nadir or the zenith), each the image of one vertical
    half-plane through the eye.

    The screen is split into four wedges around V by the diagonals through it; a wedge's lines
    are aimed at the pixel centres of the screen edge it faces, one a pixel, and stepped one
    pixel row (UP, DOWN) or column (LEFT, RIGHT) at a time from that edge towards V. In a
    wedge's own coordinates (p along the aimed edge, q towards it, both in pixels: UP p = x,
    q = -y; DOWN p = x, q = y; LEFT p = y, q = -x; RIGHT p = y, q = x) line i passes through
    (aim[i], qa) and V, and at q its p is aim[i] + (q - qa) slope[i].

    Attributes:
        wedge: (L,) int64 the wedge of each line (_cast_kernels.UP, DOWN, LEFT, RIGHT).
        aim: (L,) float64 p of the aimed point.
        slope: (L,) float64 dp / dq along the line.
        prev, next: (L,) bool the line before (after) it in the arrays is its wedge's
            neighbour on the low (high) p side: of the lines whose points fall in one pixel,
            the one nearest its centre takes it.
        sin_phi, cos_phi: (L,) float64 sine and cosine of the line's azimuth.
        qa: (4,) float64 q of each wedge's aimed edge (pixel centres).
        nmajor, nminor: (4,) int64 pixels along q and along p of each wedge.
        vp, vq: (4,) float64 V in each wedge's coordinates, homogeneous with weight vw.
        vw: V's homogeneous weight (>= 0; 0: V at infinity, the lines parallel).
        nadir: V is the nadir's image (elevation grows away from V), else the zenith's.
    """

    wedge: np.ndarray
    aim: np.ndarray
    slope: np.ndarray
    prev: np.ndarray
    next: np.ndarray
    sin_phi: np.ndarray
    cos_phi: np.ndarray
    qa: np.ndarray
    nmajor: np.ndarray
    nminor: np.ndarray
    vp: np.ndarray
    vq: np.ndarray
    vw: float
    nadir: bool


class ScanLimits(NamedTuple):
    """Where the line scans start and how far they go.

    Attributes:
        eye: (3,) float64 eye position relative to the database origin, metres (kept above the
            surface, terrain.MIN_CLEARANCE_M).
        r_switch: (levels,) float64 ground range where level L + 1 takes over from level L,
            metres (inf for the coarsest).
        r_far: ground range beyond which nothing is scanned (the far plane, or opaque haze or
            fog), metres.
        tree_start, tree_end: slant ranges (metres) over which a forest voxel's block rises
            from the ground to its full height, cross-fading with the near polygon trees
            (scene/forest.py); tree_end 0: blocks at every range (no near trees).
    """

    eye: np.ndarray
    r_switch: np.ndarray
    r_far: float
    tree_start: float
    tree_end: float


#: The land classes of TerrainDetail.table.
GRASS, FIELD, ROCK, PAD, FOREST = 0, 1, 2, 3, 4
LAND_CLASSES = 5
#: Where the values sit in TerrainDetail.table (one array: the cast passes it down its calls
#: whole, and fewer arrays are fewer arguments).
T_ORIGIN = 0  # 3: world x, y, z of the database origin (texture coordinates are world metres)
T_ROCK_SLOPE = 3  # slope (tangent) above which the ground is rock
T_FIELD_SLOPE = 4  # slope (tangent) within which a field cell's corners lie from its centre
T_FIELD_SHARE = 5  # share (0..1) of the field cells that hold a field
T_FIELD_W = 6  # field cell width (east), metres, > 0
T_FIELD_H = 7  # field cell height (north), metres, > 0
T_HEDGE_M = 8  # half-width of the hedge along a field's edge, metres
T_LUM_REF = 9  # the relief colours' mean luminance (linear), > 0
T_HEDGE = 10  # 3: a hedge's colour factor on its field
T_PAD_COVERED = 13  # 1: the scene's faces cover the pads (no texture read inside them)
T_CLASSES = 14  # LAND_CLASSES rows of T_CLASS_N, below
#: A class's row: look row (-1: none), linear colour r, g, b, the share (mix) of the relief's
#: hue it takes keeping the relief's brightness (PAD: its lit colour, taken whole), then for each
#: of its code's textures (MAX_CODE_TEXTURES) the footprints (metres) from which it has faded
#: out: the pixel's larger side, and its side across the line (inf: never; terrain.fade_outs).
T_CLASS_FADE = 5
T_CLASS_N = T_CLASS_FADE + 2 * 3
T_FIELDS_N = T_CLASSES + LAND_CLASSES * T_CLASS_N  # how many kinds of field
T_PADS_N = T_FIELDS_N + 1  # how many pads
T_PADS_AT = T_PADS_N + 1  # where the pads start: 5 each (x0, y0, x1, y1, blend_m), world metres
T_FIELDS = T_PADS_AT + 1  # 3 per kind of field: its linear colour; the pads follow


class TerrainDetail(NamedTuple):
    """The land's detail over the terrain's relief colour (terrain.terrain_detail; docs/terrain.md
    "Detail"): land classes, each with a colour and a texture code of the scene, fields and
    hedges, and the airfield pads' grass.

    Attributes:
        on: whether the cast draws any detail (False: it pays nothing for it).
        texels, level, levels, finest: the scene's texture store (FrameConstants' tex_*), as
            texture_sampling.TextureArrays names them (not one nested group: numba's parallel
            loops take no group within a group).
        looks: (L, LOOK_SLOTS) float64 the scene's look table.
        texture_filter: the frame's texture filter (FrameConstants.texture_filter).
        table: float64 every other value, at the T_* positions.
    """

    on: bool
    texels: np.ndarray
    level: np.ndarray
    levels: np.ndarray
    finest: np.ndarray
    looks: np.ndarray
    texture_filter: int
    table: np.ndarray


class CastPixels(NamedTuple):
    """What the cast leaves per pixel for the per-sample depth (_depth_kernels).

    Attributes:
        pixels: (H, W, 2) float32 per pixel the share the terrain covers, and 1/z (eye
            depth, metres) of the terrain there (0 where the terrain never reached; at a
            partly covered pixel, and the first uncovered one above a line's last surface,
            that surface continued): one array, so a pixel's two values share a cache line.
    """

    pixels: np.ndarray


class SkyTable(NamedTuple):
    """The sky and the earth plane through the air, by elevation (_sky_kernels).

    Attributes:
        tabulated: the air depends on elevation alone (no fog, or fog strata along the
            vertical), so the tables hold it; else the colours are computed per pixel.
        sky, earth: (SKY_TABLE_SIZE, 3) float64 linear colour at elevation sines -1 .. 1
            (one-row stand-ins when not tabulated).
    """

    tabulated: bool
    sky: np.ndarray
    earth: np.ndarray


class CloudImage(NamedTuple):
    """The coarse cloud image (clouds.scan_clouds) as cloud_over_kernel lays it over the
    background, with the finer samples of the quads a cloud's edge crosses.

    A quad (c, r) is the square between the centres of texels (c, r), (c + 1, r), (c, r + 1)
    and (c + 1, r + 1) (column c + 1 is column 0 past the last when full): the points whose
    floor is (c, r) in cloud image coordinates (texel centres at integers).

    Attributes:
        texels: (ncols, nrows, CLOUD_CHANNELS) float32.
        full: every azimuth is seen (the view holds the nadir or the zenith): columns wrap.
        phi_lo: azimuth of column 0's left edge; column j is centred on phi_lo + (j + 1/2)
            dphi.
        dphi: column width (azimuth).
        theta0: elevation of row 0's lower edge.
        dtheta: row height (elevation).
        span: azimuth the columns cover (ncols dphi).
        quad: (ncols, nrows) int32 the index in fine of quad (c, r), or -1 where the quad is
            read from its four corner texels alone.
        fine: (quads, f + 1, f + 1, CLOUD_CHANNELS) float32 each refined quad's samples on
            an f x f grid (f = clouds.REFINE): fine[t, a, b] lies a / f texel right of and
            b / f texel above the quad's corner (c, r), so fine[t, 0, 0] is that texel's ray
            again. Their colour is 0 where the quad's corner texels have cloud (the overlay
            takes its colour from those; CloudQuads.shaded).
    """

    texels: np.ndarray
    full: bool
    phi_lo: float
    dphi: float
    theta0: float
    dtheta: float
    span: float
    quad: np.ndarray
    fine: np.ndarray


class SampleDepth(NamedTuple):
    """Where per-sample terrain depth (Background.inv_z) is wanted, and how.

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
    """The arrays the stage fills (Background's rgb, inv_z, range_m and cloud).

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
        z_min, z_max: the lowest base and the highest top of any node, world metres.
    """

    base: np.ndarray
    top: np.ndarray
    density: np.ndarray
    cell: float
    colour: np.ndarray
    base_shade: float
    z_min: float
    z_max: float


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


class CloudQuads(NamedTuple):
    """The quads of the coarse cloud image to sample finer (clouds.edge_quads), as the
    refining scan walks them: grouped by column, one radial scan per fine column of a group.

    Fine sample (a, b) of quad (c, r) looks at azimuth phi_lo + (c + a / factor + 1/2) dphi
    and elevation theta0 + (r + b / factor + 1/2) dtheta (CloudImage's grid; kept short of
    +-90 degrees).

    Attributes:
        factor: fine samples per texel along each axis (clouds.REFINE).
        phi_lo, dphi: the coarse image's columns (CloudImage).
        row_tan, row_inv_cos, row_sin: (nrows, factor + 1) float64 tangent, 1 / cosine and
            sine of fine row b's elevation in the quads of row r, at [r, b].
        col: (G,) int64 the column of each group of quads.
        start: (G + 1,) int64 group g holds quads start[g] .. start[g + 1] - 1.
        row: (quads,) int64 each quad's row, ascending within a group.
        shaded: (quads,) bool whether the quad's fine samples need their colour: its corner
            texels have no cloud (elsewhere the overlay takes the colour from them, and the
            fine samples' colour is left 0).
    """

    factor: int
    phi_lo: float
    dphi: float
    row_tan: np.ndarray
    row_inv_cos: np.ndarray
    row_sin: np.ndarray
    col: np.ndarray
    start: np.ndarray
    row: np.ndarray
    shaded: np.ndarray
