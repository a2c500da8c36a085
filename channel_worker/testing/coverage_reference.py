"""Exact area-coverage reference images, for accuracy tests and benchmarks (needs shapely >= 2).

The renderer estimates each pixel's box-filtered colour from S point samples. This module
computes what those samples estimate: the exact mean over the pixel square of the colour seen
at each point, by clipping polygons with shapely, for frames whose visibility order is known
(a front-to-back order of whole polygons, e.g. flat plates at distinct depths).

It reads the SNAPPED screen vertices (ScreenPolygons.fixed / SUBPIXEL), so it sees exactly the
geometry the rasterizer tests samples against: any difference is sampling error, never
projection or snapping. A polygon covers the intersection of its edges' inside half-planes
(the rasterizer's rule); for the convex polygons the pipeline makes that is the polygon itself.

Colour at a screen point: the polygons covering it, in the given order, composited front to
back until the first opaque one (alpha = ScreenPolygons.opacity):
``sum_i alpha_i prod_{j<i} (1 - alpha_j) colour_i + prod_i (1 - alpha_i) behind``, where
behind is the backdrop (sky, or earth below the horizon) when no opaque polygon covers it.

Screen frame: pixels, x right, y down, pixel (x, y) is the square [x, x+1] x [y, y+1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from channel_worker.pipeline.contract import SUBPIXEL, ScreenPolygons, View
from channel_worker.pipeline.geometry.view import earth_dz_screen
from channel_worker.pipeline.scene.database import Database

#: A piece of a pixel smaller than this (pixels^2) counts as absent: shapely's overlay of
#: coordinates below 2^12 is exact to ~1e-12, so anything smaller is rounding, not geometry.
AREA_EPS = 1e-9


@dataclass(frozen=True)
class Backdrop:
    """What is seen where no opaque polygon covers a point.

    Attributes:
        sky_rgb: (3,) linear RGB seen where nothing else is.
        earth_rgb: (3,) linear RGB of the earth plane, or None.
        earth: screen region (pixels) where the earth is seen, or None for no earth.
    """

    sky_rgb: np.ndarray
    earth_rgb: np.ndarray | None = None
    earth: shapely.Geometry | None = None


@dataclass(frozen=True)
class ReferencePixels:
    """The exact box-filtered image and how each pixel is made up.

    Attributes:
        rgb: (H, W, 3) float64 linear RGB, each pixel's exact mean colour.
        pieces: (H, W) int number of regions of constant colour (visible polygon pieces,
            translucent overlaps, sky, earth) meeting the pixel with positive area.
        convex: (H, W) bool every piece's part inside the pixel is convex. A pixel with two
            convex pieces is crossed by exactly one straight edge (two convex sets that
            partition a square are separated by a line).
        contrast: (H, W) float64 largest colour difference (any channel) between the pieces
            meeting the pixel; 0 for a pixel of one piece.
    """

    rgb: np.ndarray
    pieces: np.ndarray
    convex: np.ndarray
    contrast: np.ndarray

    @property
    def single_edge(self) -> np.ndarray:
        """(H, W) bool pixels crossed by exactly one straight boundary between two pieces."""
        return (self.pieces == 2) & self.convex


def sky_backdrop(database: Database) -> Backdrop:
    """The database's sky everywhere (views that cannot see the earth, e.g. looking up)."""
    return Backdrop(sky_rgb=np.asarray(database.sky_colour, np.float64))


def horizon_backdrop(database: Database, view: View) -> Backdrop:
    """Sky above and earth below the horizon line of the view, as the pipeline defines them.

    The earth is seen where the world z of the eye ray through screen point (sx, sy) is
    negative: kx sx + ky sy + k0 < 0 (horizon.earth_dz_screen), a half-plane of the screen.
    """
    kx, ky, k0 = earth_dz_screen(view)
    rect = np.array([[0.0, 0.0], [view.width, 0.0], [view.width, view.height], [0.0, view.height]])
    # Sutherland-Hodgman of the raster rectangle against the half-plane -(kx x + ky y + k0) > 0.
    region = _clip_half_plane(rect, -kx, -ky, -k0)
    earth = shapely.Polygon(region) if len(region) >= 3 else None
    if earth is not None and earth.area <= AREA_EPS:
        earth = None
    return Backdrop(sky_rgb=np.asarray(database.sky_colour, np.float64),
                    earth_rgb=np.asarray(database.earth_colour, np.float64), earth=earth)


def polygon_geometry(screen: ScreenPolygons, index: int) -> shapely.Geometry:
    """Screen region (pixels) polygon `index` covers under the rasterizer's rule.

    That is the intersection of the inside half-planes of its edges: the polygon itself when
    its snapped vertices are convex (always, unless snapping bent a near-degenerate one).
    """
    v = screen.fixed[screen.start[index]:screen.start[index + 1]].astype(np.int64)
    d = np.roll(v, -1, axis=0) - v
    turn = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
    verts = v / SUBPIXEL
    if (turn <= 0).all():  # negative doubled area: every turn is clockwise in y-down
        return shapely.Polygon(verts)
    lo, hi = verts.min(axis=0) - 1.0, verts.max(axis=0) + 1.0
    region = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    for i in range(len(verts)):
        # Inside edge i: (P - V0) x D rotated as edges.py: (Px - X0) dy - (Py - Y0) dx >= 0.
        (x0, y0), (dx, dy) = verts[i], d[i] / SUBPIXEL
        region = _clip_half_plane(region, dy, -dx, y0 * dx - x0 * dy)
        if len(region) < 3:
            return shapely.Polygon()
    return shapely.Polygon(region)


def depth_order(screen: ScreenPolygons, *, check: bool = True) -> np.ndarray:
    """Polygon indices nearest first, by 1/z at each polygon's vertex centroid.

    Right for layers that do not interpenetrate (e.g. plates facing the eye at distinct depths).
    With check, every pair of polygons that overlap on the screen is verified to keep that
    order over their whole overlap (1/z is affine on the screen, so checking the overlap's
    vertices suffices); a tie (coplanar) is decided as the renderer does: the higher layer,
    then the lower index.

    Raises:
        ValueError: two overlapping polygons whose depth order varies over their overlap or
            contradicts the centroid order: the frame has no single visibility order.
    """
    n = screen.polygon_count
    key = np.empty(n)
    for p in range(n):
        c = screen.fixed[screen.start[p]:screen.start[p + 1]].mean(axis=0) / SUBPIXEL
        key[p] = _inv_z(screen, p, c[None])[0]
    order = np.lexsort((np.arange(n), -screen.layer.astype(np.int64), -key))
    if not check:
        return order
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    geoms = [polygon_geometry(screen, p) for p in range(n)]
    tree = shapely.STRtree(geoms)
    for i, j in tree.query(geoms, predicate="intersects").T:
        if i >= j:
            continue
        overlap = shapely.intersection(geoms[i], geoms[j])
        if overlap.area <= AREA_EPS:
            continue
        pts = np.asarray(shapely.get_coordinates(overlap))
        diff = _inv_z(screen, i, pts) - _inv_z(screen, j, pts)
        scale = 1e-12 * max(abs(key[i]), abs(key[j]))
        if (np.abs(diff) <= scale).all():
            continue  # coplanar: the lexsort's tie rule is the renderer's
        if (diff > -scale).all():
            near, far = i, j
        elif (diff < scale).all():
            near, far = j, i
        else:
            near = far = -1
        if near < 0 or rank[near] > rank[far]:
            raise ValueError(f"polygons {i} and {j} overlap with no single depth order (1/z "
                             f"difference {diff.min():.3g}..{diff.max():.3g} over the overlap)")
    return order


def reference_pixels(screen: ScreenPolygons, width: int, height: int, order: np.ndarray,
                     background: np.ndarray | Backdrop) -> ReferencePixels:
    """Exact box-filtered pixels of the frame.

    Args:
        screen: the frame's projected polygons (snapped).
        width, height: raster size, pixels.
        order: indices of the polygons to draw, nearest first (depth_order); polygons not
            listed are not drawn.
        background: a constant (3,) linear RGB, or a Backdrop (sky and earth).
    """
    if not isinstance(background, Backdrop):
        background = Backdrop(sky_rgb=np.asarray(background, np.float64).reshape(3))
    raster = shapely.box(0.0, 0.0, float(width), float(height))
    # Open regions: parts of the raster not yet behind an opaque polygon, each with its
    # transmittance and the colour composited so far (both constant over the region).
    open_regions: list[tuple[shapely.Geometry, float, np.ndarray]] = [(raster, 1.0, np.zeros(3))]
    closed: list[tuple[shapely.Geometry, np.ndarray]] = []
    colour = screen.colour.astype(np.float64)
    opacity = screen.opacity.astype(np.float64)
    for p in np.asarray(order, np.int64):
        poly = polygon_geometry(screen, int(p))
        if poly.is_empty:
            continue
        alpha = float(opacity[p])
        nxt = []
        for region, through, acc in open_regions:
            inter = shapely.intersection(region, poly)
            rest = shapely.difference(region, poly)
            seen = acc + through * alpha * colour[p]
            if inter.area > AREA_EPS:
                if alpha >= 1.0:
                    closed.append((inter, seen))
                else:
                    nxt.append((inter, through * (1.0 - alpha), seen))
            if rest.area > AREA_EPS:
                nxt.append((rest, through, acc))
        open_regions = nxt
    for region, through, acc in open_regions:
        if background.earth is not None:
            earth = shapely.intersection(region, background.earth)
            if earth.area > AREA_EPS:
                closed.append((earth, acc + through * np.asarray(background.earth_rgb, np.float64)))
            region = shapely.difference(region, background.earth)
        if region.area > AREA_EPS:
            closed.append((region, acc + through * background.sky_rgb))
    return _accumulate(closed, width, height)


def reference_image(screen: ScreenPolygons, width: int, height: int, order: np.ndarray,
                    background: np.ndarray | Backdrop) -> np.ndarray:
    """(H, W, 3) float64 exact box-filtered linear RGB (see reference_pixels)."""
    return reference_pixels(screen, width, height, order, background).rgb


def half_plane_discrepancy(offsets: np.ndarray, *, angles: int = 3600) -> float:
    """Largest error of a sample pattern's coverage estimate for one straight edge.

    sup over half-planes H of |#(samples in H) / S - area(H n pixel)|, a sample exactly on the
    line counted either way (the top-left rule may give it to either side). For a fixed edge
    direction the count is constant between samples while the area is monotone, so the sup is
    reached with the line through a sample; directions are a grid of `angles` plus every
    direction through two samples or a sample and a pixel corner (where the count changes),
    which finds the sup to about 1e-4.

    Args:
        offsets: (S, 2) sample positions inside the pixel, pixels from its top-left.
    """
    pts = np.asarray(offsets, np.float64)
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    ends = np.concatenate([pts, corners])
    d = (ends[:, None, :] - pts[None, :, :]).reshape(-1, 2)
    d = d[np.hypot(d[:, 0], d[:, 1]) > 0]
    crit = np.arctan2(d[:, 1], d[:, 0]) + np.pi / 2  # normals of lines through the pairs
    theta = np.concatenate([np.linspace(0.0, 2 * np.pi, angles, endpoint=False), crit])
    n = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    proj = n @ pts.T  # (A, S)
    s = pts.shape[0]
    below = (proj[:, None, :] < proj[:, :, None]).sum(axis=2) / s  # strictly below sample k's line
    at_or_below = (proj[:, None, :] <= proj[:, :, None]).sum(axis=2) / s
    area = _half_plane_area(n[:, 0:1], n[:, 1:2], proj)
    return float(max(np.abs(below - area).max(), np.abs(at_or_below - area).max()))


def _half_plane_area(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Area of {a x + b y <= t} inside the unit square (broadcasting): the CDF of a U + b V."""
    lo = np.minimum(a, 0.0) + np.minimum(b, 0.0)
    y = t - lo
    al, be = np.abs(a), np.abs(b)
    big, small = np.maximum(al, be), np.minimum(al, be)
    def ramp(u: np.ndarray) -> np.ndarray:
        return np.maximum(u, 0.0) ** 2

    with np.errstate(divide="ignore", invalid="ignore"):
        quad = (ramp(y) - ramp(y - small) - ramp(y - big) + ramp(y - small - big)) \
            / (2 * small * big)
        lin = np.clip(y / big, 0.0, 1.0)
    return np.clip(np.where(small > 1e-12, quad, lin), 0.0, 1.0)


def _inv_z(screen: ScreenPolygons, p: int, pts: np.ndarray) -> np.ndarray:
    a, b, c = screen.inv_z[p]
    return a * pts[:, 0] + b * pts[:, 1] + c


def _clip_half_plane(poly: np.ndarray, a: float, b: float, c: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of a convex polygon where a x + b y + c >= 0."""
    out = []
    m = len(poly)
    for i in range(m):
        p, q = poly[i], poly[(i + 1) % m]
        dp, dq = a * p[0] + b * p[1] + c, a * q[0] + b * q[1] + c
        if dp >= 0:
            out.append(p)
        if (dp >= 0) != (dq >= 0):
            out.append(p + (q - p) * (dp / (dp - dq)))
    return np.array(out).reshape(-1, 2)


def _accumulate(closed: list[tuple[shapely.Geometry, np.ndarray]], width: int,
                height: int) -> ReferencePixels:
    """Per-pixel areas of every closed piece, summed into colour, piece count and contrast."""
    ys, xs = np.mgrid[0:height, 0:width]
    boxes = shapely.box(xs.ravel(), ys.ravel(), xs.ravel() + 1.0, ys.ravel() + 1.0)
    tree = shapely.STRtree(boxes)
    npx = width * height
    rgb = np.zeros((npx, 3))
    pieces = np.zeros(npx, np.int64)
    convex = np.ones(npx, bool)
    cmin = np.full((npx, 3), np.inf)
    cmax = np.full((npx, 3), -np.inf)
    for geom, colour in closed:
        idx = tree.query(geom, predicate="intersects")
        shapely.prepare(geom)
        inner = shapely.contains_properly(geom, boxes[idx])
        area = np.ones(idx.shape[0])
        hull_gap = np.zeros(idx.shape[0])
        edge = ~inner
        if edge.any():
            parts = shapely.intersection(boxes[idx[edge]], geom)
            area[edge] = shapely.area(parts)
            hull_gap[edge] = shapely.area(shapely.convex_hull(parts)) - area[edge]
        keep = area > AREA_EPS
        idx, area, hull_gap = idx[keep], area[keep], hull_gap[keep]
        np.add.at(rgb, idx, area[:, None] * colour[None, :])
        np.add.at(pieces, idx, 1)
        convex[idx] &= hull_gap <= AREA_EPS
        cmin[idx] = np.minimum(cmin[idx], colour)
        cmax[idx] = np.maximum(cmax[idx], colour)
    contrast = np.where(pieces[:, None] > 0, cmax - cmin, 0.0).max(axis=1)
    return ReferencePixels(rgb=rgb.reshape(height, width, 3),
                           pieces=pieces.reshape(height, width),
                           convex=convex.reshape(height, width),
                           contrast=contrast.reshape(height, width))
