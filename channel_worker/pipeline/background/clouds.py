"""Clouds of JP H07-76990: a coarse cloud database scanned like the ground, blended by range.

JP H07-76990: "Clouds are inserted by scanning another database ... by the same mechanism.
This separate database describes cloud patterns in three dimensions, similar to the way ground
is described. The cloud pattern is intentionally made very rough to produce a blurry cloud with
translucent edges ... the linear resolution of clouds is one-eighth the resolution of the
earth. ... an interpolation stage smooths the cloud scene between coarse pixels ... Pixel range
comparisons are used to determine what is visible."

Here the cloud database is a coarse 2-D grid of cells, each holding a cloud slab (base and top
heights, metres) of uniform extinction; the background stage scans it along azimuth columns
over the view's azimuth and elevation range at one eighth of the channel's pixel resolution
(CLOUD_FACTOR), integrating each coarse row's ray through the slabs front to back
(_cloud_kernels.scan_clouds_kernel), and _cloud_over_kernels interpolates that coarse image
bilinearly and lays it over whatever lies beyond the cloud's entry range (terrain, sky, earth
plane, polygons).
"""

from __future__ import annotations

import math

import numpy as np

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.geometry.view import screen_mapping
from channel_worker.pipeline.scene.database import Database

from ._cloud_kernels import scan_clouds_kernel
from ._groups import CLOUD_CHANNELS, CloudColumns, CloudImage, CloudSlabs

#: Channel pixels per cloud texel along each axis (JP H07-76990: one eighth of the ground's
#: linear resolution).
CLOUD_FACTOR = 8

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
    """The coarse cloud image of database.clouds over the view (cloud_grid).

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
    # Texel centres stop short of +-90 deg, so 1 / cos stays finite.
    centres = np.clip(grid.theta0 + (np.arange(grid.nrows) + 0.5) * grid.dtheta,
                      -0.5 * math.pi + 1e-6, 0.5 * math.pi - 1e-6)
    eye = np.array([view.eye[0] - clouds.origin[0], view.eye[1] - clouds.origin[1], view.eye[2]])
    out = np.empty((grid.ncols, grid.nrows, CLOUD_CHANNELS), np.float32)
    slabs = CloudSlabs(clouds.base_m, clouds.top_m, clouds.density, clouds.cell_m, clouds.colour,
                       BASE_SHADE)
    columns = CloudColumns(grid.phi_lo, grid.dphi, grid.ncols, np.tan(centres),
                           1.0 / np.cos(centres), np.sin(centres))
    scan_clouds_kernel(slabs, columns, eye, float(view.far), air, out)
    return CloudImage(out, grid.full, grid.phi_lo, grid.dphi, grid.theta0, grid.dtheta,
                      grid.ncols * grid.dphi)
