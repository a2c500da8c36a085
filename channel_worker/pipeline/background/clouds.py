"""Clouds of JP H07-76990: a coarse cloud database scanned like the ground, blended by range.

JP H07-76990: "Clouds are inserted by scanning another database ... by the same mechanism.
This separate database describes cloud patterns in three dimensions, similar to the way ground
is described. The cloud pattern is intentionally made very rough to produce a blurry cloud with
translucent edges ... the linear resolution of clouds is one-eighth the resolution of the
earth. ... an interpolation stage smooths the cloud scene between coarse pixels ... Pixel range
comparisons are used to determine what is visible."

Here the cloud database is a coarse 2-D grid of nodes holding a cloud slab (base and top
heights, metres) and its extinction, bilinear between them; the background stage scans it
along azimuth columns over the view's azimuth and elevation range at one eighth of the
channel's pixel resolution (CLOUD_FACTOR), integrating each coarse row's ray through the slabs
front to back (_cloud_kernels.scan_clouds_kernel), and _cloud_over_kernels interpolates that
coarse image bilinearly and lays it over whatever lies beyond the cloud's entry range
(terrain, sky, earth plane, polygons).

One ray a texel cannot place a cloud's sharp outline between two rays: against the sky it
came out in 8-pixel stair steps. So where the outline crosses the image it is sampled again,
a ray a pixel, after Whitted's adaptive supersampling (*An improved illumination model for
shaded display*): the quads whose corner texels' opacities differ (edge_quads), and the quads
beside them that the finer rays show the outline reaches (seam_quads). The overlay takes the
opacity there from the finer rays and the colour still from the coarse texels, so inside a
cloud the image stays the patent's blurry one.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.geometry.view import screen_mapping
from channel_worker.pipeline.scene.database import Database

from ._cloud_kernels import (
    edge_quads_kernel,
    refine_clouds_kernel,
    scan_clouds_kernel,
    seam_quads_kernel,
)
from ._groups import CLOUD_CHANNELS, CloudColumns, CloudImage, CloudQuads, CloudSlabs

#: Channel pixels per cloud texel along each axis (JP H07-76990: one eighth of the ground's
#: linear resolution).
CLOUD_FACTOR = 8

#: Fine samples per texel along each axis in a quad a cloud's edge crosses (edge_quads): one
#: a pixel where the texels are densest (CLOUD_FACTOR). Every second pixel (4) left 2-pixel
#: steps, 0.8 pixel off the straight edge of test_cloud_edges' bank (0.35 at 8, the aliasing
#: of a centre sample), at a third of the rays.
REFINE = CLOUD_FACTOR

#: Opacity difference across a quad's corners above which the quad is sampled finer
#: (edge_quads), or along its side above which the quad beside it is too (seam_quads). The
#: colour is not compared: inside a cloud the coarse image's is kept, blurry as JP H07-76990
#: wants it (refined on colour too, the slabs' facets showed through the cloud). Measured on
#: the bundled scene's layer (1024 x 768, the two views of docs/terrain.md section 6): 0.1
#: refines 7.5 % of the quads; 0.05 up to 28 % more and no pixel 10/255 different; 0.2 up to
#: half as many, leaving parts of the edges coarse (pixels up to 16/255 off).
REFINE_CONTRAST = 0.1

#: Brightness of a cloud's base relative to its top: light through a cloud dims downwards.
BASE_SHADE = 0.62


class CloudGrid:
    """The azimuth columns and elevation rows of a view's cloud image (radians).

    Column j is centred on azimuth phi_lo + (j + 1/2) dphi (clockwise from north); row i
    spans elevations theta0 + i dtheta .. theta0 + (i + 1) dtheta. full: the view holds the
    nadir or the zenith, so every azimuth is seen and columns wrap around.
    """

    def __init__(self, phi_lo: float, span: float, full: bool, theta0: float, theta1: float,
                 pixel_angle: float, cos_max: float) -> None:
        self.phi_lo, self.span, self.full = phi_lo, span, full
        self.theta0, self.theta1 = theta0, theta1
        # Rows CLOUD_FACTOR times as coarse as the finest output pixel; columns too, where
        # azimuth is densest on the screen (nearest the horizon: a pixel of angle a spans
        # a / cos(elevation) of azimuth). Guards: pixel_angle > 0 (finite frustum), cos_max > 0
        # (clamped below).
        d = pixel_angle * CLOUD_FACTOR
        self.nrows = max(1, math.ceil((theta1 - theta0) / d))
        self.ncols = max(1, math.ceil(span / (d / cos_max)))
        self.dtheta = (theta1 - theta0) / self.nrows
        self.dphi = span / self.ncols


def cloud_grid(view: View) -> CloudGrid:
    """The azimuth and elevation range a view covers, at the cloud image's resolution.

    Azimuth and elevation have no extremum inside the frustum except at the poles, so the
    frustum's border (sampled densely) and whether it holds the nadir or zenith give both
    ranges; the border's winding about the vertical tells if a pole is inside.
    """
    n = 257
    t = np.linspace(0.0, 1.0, n)
    tl, tr, tb, tt = view.tan_left, view.tan_right, view.tan_bottom, view.tan_top
    xs = np.concatenate([tl + (tr - tl) * t, np.full(n, tr), tr - (tr - tl) * t, np.full(n, tl)])
    ys = np.concatenate([np.full(n, tb), tb + (tt - tb) * t, np.full(n, tt), tt - (tt - tb) * t])
    dirs = np.stack([xs, ys, np.ones_like(xs)], axis=1) @ view.world_to_eye  # world directions
    horiz = np.hypot(dirs[:, 0], dirs[:, 1])
    theta = np.arctan2(dirs[:, 2], horiz)
    phi = np.arctan2(dirs[:, 0], dirs[:, 1])
    loop = np.unwrap(np.append(phi, phi[0]))
    winding = loop[-1] - loop[0]
    sx_scale, _, sy_scale, _ = screen_mapping(view)
    pixel_angle = min(1.0 / abs(sx_scale), 1.0 / abs(sy_scale))  # guard: scales are nonzero
    margin = 2.0 * pixel_angle * CLOUD_FACTOR
    nadir = _pole_inside(view, -1.0, margin)
    zenith = _pole_inside(view, 1.0, margin)
    full = nadir or zenith or abs(winding) > math.pi
    theta0 = -0.5 * math.pi if nadir else max(float(theta.min()) - margin, -0.5 * math.pi)
    theta1 = 0.5 * math.pi if zenith else min(float(theta.max()) + margin, 0.5 * math.pi)
    if full:
        phi_lo, span = float(phi[0]) - math.pi, 2.0 * math.pi
    else:
        lo, hi = float(loop.min()), float(loop.max())
        col_margin = margin / max(math.cos(max(abs(theta0), abs(theta1))), 1e-3)
        phi_lo, span = lo - col_margin, min(hi - lo + 2.0 * col_margin, 2.0 * math.pi)
    if theta0 <= 0.0 <= theta1:
        cos_max = 1.0
    else:
        cos_max = max(math.cos(min(abs(theta0), abs(theta1))), 1e-3)
    return CloudGrid(phi_lo, span, full, theta0, theta1, pixel_angle, cos_max)


def _pole_inside(view: View, sign: float, margin: float) -> bool:
    """Whether the straight-down (sign -1) or straight-up (+1) direction is in the frustum,
    widened by margin radians."""
    e = view.world_to_eye @ np.array([0.0, 0.0, sign])
    if e[2] <= 0.0:
        return False
    pad = math.tan(min(margin, 1.0)) * 2.0
    tx, ty = e[0] / e[2], e[1] / e[2]  # guard: e[2] > 0
    return (view.tan_left - pad <= tx <= view.tan_right + pad
            and view.tan_bottom - pad <= ty <= view.tan_top + pad)


def scan_clouds(database: Database, view: View, air: np.ndarray) -> CloudImage:
    """The coarse cloud image of database.clouds over the view (cloud_grid), sampled finer in
    the quads a cloud's edge crosses (edge_quads) and in those next to them that the finer
    samples show the edge reaches (seam_quads).

    Args:
        database: the scene; database.clouds is not None.
        view: the channel's view for this frame.
        air: the frame's air array (air.air_params).

    Raises:
        ValueError: the scene has no clouds.
    """
    clouds = database.clouds
    if clouds is None:
        raise ValueError("scan_clouds: the scene has no clouds")
    grid = cloud_grid(view)
    centres = _elevations(grid, np.arange(grid.nrows, dtype=np.float64))
    eye = np.array([view.eye[0] - clouds.origin[0], view.eye[1] - clouds.origin[1], view.eye[2]])
    out = np.empty((grid.ncols, grid.nrows, CLOUD_CHANNELS), np.float32)
    slabs = CloudSlabs(clouds.base_m, clouds.top_m, clouds.density, clouds.cell_m, clouds.colour,
                       BASE_SHADE, float(clouds.base_m.min()), float(clouds.top_m.max()))
    columns = CloudColumns(grid.phi_lo, grid.dphi, grid.ncols, np.tan(centres),
                           1.0 / np.cos(centres), np.sin(centres))  # guard: _elevations
    scan_clouds_kernel(slabs, columns, eye, float(view.far), air, out)
    quad, fine = _refine(slabs, grid, out, eye, float(view.far), air)
    return CloudImage(out, grid.full, grid.phi_lo, grid.dphi, grid.theta0, grid.dtheta,
                      grid.ncols * grid.dphi, quad, fine)


def _refine(slabs: CloudSlabs, grid: CloudGrid, texels: np.ndarray, eye: np.ndarray,
            r_far: float, air: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The quads of the coarse image (texels) a cloud's edge crosses, sampled REFINE times
    finer: the edge's quads (edge_quads), then, round after round, the neighbours the edge
    reaches (seam_quads), until it stays inside the refined quads (every round adds quads
    not refined yet, so the rounds end). Returns CloudImage.quad and CloudImage.fine."""
    quad = np.full((grid.ncols, grid.nrows), -1, np.int32)
    # Fine row b of the quads of row r (CloudQuads).
    rows_theta = _elevations(grid, np.arange(grid.nrows)[:, None] + np.arange(REFINE + 1) / REFINE)
    rows_tan, rows_inv_cos, rows_sin = (np.tan(rows_theta), 1.0 / np.cos(rows_theta),
                                        np.sin(rows_theta))  # guard: _elevations
    pieces = []
    count = 0
    alpha = texels[:, :, 3]
    cols, rows = edge_quads(texels, grid.full)
    # Once through even with no quad to refine, so that every kernel here is compiled by the
    # first frame with clouds (ig compile's warm-up), not by the first with a cloud's edge.
    while True:
        quad[cols, rows] = count + np.arange(cols.size, dtype=np.int32)
        right = (cols + 1) % grid.ncols  # a quad has its right column (wrapping if full)
        shaded = ((alpha[cols, rows] == 0.0) & (alpha[right, rows] == 0.0)
                  & (alpha[cols, rows + 1] == 0.0) & (alpha[right, rows + 1] == 0.0))
        quads = CloudQuads(REFINE, grid.phi_lo, grid.dphi, rows_tan, rows_inv_cos, rows_sin,
                           *_groups_by_column(cols), rows, shaded)
        fine = np.empty((cols.size, REFINE + 1, REFINE + 1, CLOUD_CHANNELS), np.float32)
        refine_clouds_kernel(slabs, quads, eye, r_far, air, numba.get_num_threads(), fine)
        pieces.append(fine)
        count += cols.size
        cols, rows = seam_quads(texels, grid.full, quad, cols, rows, fine)
        if not cols.size:
            break
    return quad, np.concatenate(pieces)


def _elevations(grid: CloudGrid, rows: np.ndarray) -> np.ndarray:
    """Elevations (radians) of the rays at cloud image rows `rows` (texel centres at
    integers), kept short of +-90 deg so that 1 / cos stays finite."""
    return np.clip(grid.theta0 + (rows + 0.5) * grid.dtheta, -0.5 * math.pi + 1e-6,
                   0.5 * math.pi - 1e-6)


def edge_quads(texels: np.ndarray, full: bool) -> tuple[np.ndarray, np.ndarray]:
    """The quads of the coarse image (CloudImage) that a cloud's edge crosses: those whose four
    corner texels' opacities differ by more than REFINE_CONTRAST (Whitted's adaptive
    supersampling, *An improved illumination model for shaded display*: corners that differ
    are sampled again finer).

    Args:
        texels: (ncols, nrows, CLOUD_CHANNELS) the coarse image.
        full: its columns wrap round a full circle (CloudImage.full).

    Returns:
        The quads' columns and rows, (quads,) int64 each, columns ascending and rows ascending
        within a column.
    """
    marked = np.empty(texels.shape[:2], np.bool_)
    edge_quads_kernel(texels, full, REFINE_CONTRAST, marked)
    cols, rows = np.nonzero(marked)  # row-major over (column, row)
    return cols.astype(np.int64), rows.astype(np.int64)


def seam_quads(texels: np.ndarray, full: bool, quad: np.ndarray, cols: np.ndarray,
               rows: np.ndarray, fine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The quads not refined yet next to refined quads (cols, rows; their samples fine) whose
    shared side the fine samples show differs in opacity by more than REFINE_CONTRAST from
    what the neighbour reads there (the linear blend of the side's two corner texels): left
    coarse, the neighbour would meet the refined quad in a seam.

    Args:
        texels: (ncols, nrows, CLOUD_CHANNELS) the coarse image.
        full: its columns wrap round a full circle.
        quad: (ncols, nrows) int32 the quads refined so far (CloudImage.quad).
        cols, rows: (quads,) the quads just refined.
        fine: (quads, REFINE + 1, REFINE + 1, CLOUD_CHANNELS) their samples (CloudImage.fine).

    Returns:
        The quads to refine next, ordered as edge_quads orders them.
    """
    marked = np.empty(quad.shape, np.bool_)
    seam_quads_kernel(texels, full, quad, cols, rows, fine, REFINE_CONTRAST, marked)
    cols, rows = np.nonzero(marked)
    return cols.astype(np.int64), rows.astype(np.int64)


def _groups_by_column(cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct columns of quads ordered by column (CloudQuads.col), and where each
    column's quads start, with the count at the end (CloudQuads.start)."""
    first = np.flatnonzero(np.diff(cols, prepend=-1))  # cols ascending
    return cols[first], np.append(first, cols.size).astype(np.int64)
