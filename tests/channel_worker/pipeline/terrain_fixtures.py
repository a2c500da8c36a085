"""Small terrain databases, scenes and comparisons shared by the terrain tests.

Imported by the background, fog and scene tests (``from ..terrain_fixtures import ...``;
pytest runs with --import-mode=importlib).
Everything here is deterministic and small so the tests stay fast; databases are cached per
process (functools.cache), they are frozen dataclasses and never modified.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from channel_worker.pipeline.background.background import render_background
from channel_worker.pipeline.contract import Background, View
from channel_worker.pipeline.geometry.view import frame_constants
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.load import parse_scene
from channel_worker.pipeline.scene.terrain.build import build_terrain
from channel_worker.testing.terrain_reference import reference_terrain, single_level_database
from services.rig.colour import srgb_to_linear
from services.rig.options import RenderOptions

#: Four samples (rotated grid) and one at the pixel centre, pixels from the top-left corner.
RGSS4 = RenderOptions(samples="rgss4").sample_offsets()
CENTRE = np.array([[0.5, 0.5]])

#: Sky and earth share one grey in the accuracy tests, so a sample that misses the terrain has
#: the same colour in the renderer (sky above the horizon, earth plane below) as in the
#: reference (one background colour).
GREY = "#808080"

#: The hills database: HILLS_N x HILLS_N voxels of HILLS_SPACING metres, centred on the origin.
HILLS_N = 128
HILLS_SPACING = 40.0
HILLS_ORIGIN = (-0.5 * HILLS_N * HILLS_SPACING, -0.5 * HILLS_N * HILLS_SPACING, 0.0)


@dataclasses.dataclass(frozen=True)
class Stage:
    """The background stage's output for one view, and the counters it reported (.stats);
    Background's fields read through."""

    background: Background
    stats: dict

    def __getattr__(self, name: str):
        return getattr(self.background, name)


def render_terrain(database: Database, view: View, offsets: np.ndarray, *,
                   level_bias: int = 0) -> Stage:
    """The background stage alone, with per-sample depth everywhere (no sub-area mask)."""
    counters: dict[str, int] = {}
    frame = frame_constants(view, database, offsets)
    bg = render_background(database, view, frame, RenderOptions(terrain_bias=level_bias), None,
                           counters)
    return Stage(bg, counters)


def scene(*, terrain=None, haze: dict | None = None, sky: str = GREY, earth: str = GREY,
          models: dict | None = None, instances: list | None = None,
          margin_m: float | None = None, fog: dict | None = None) -> Database:
    """A scene document parsed, with an in-memory terrain attached (flat lighting)."""
    doc = {"format": "ig-scene/1", "sky": {"colour": sky}, "earth": {"colour": earth},
           "lighting": {"ambient": 1.0}, "models": models or {}, "instances": instances or []}
    if haze is not None:
        doc["haze"] = haze
    if fog is not None:
        doc["fog"] = fog
    db = parse_scene(doc, source="<terrain test>")
    changes = {}
    if terrain is not None:
        changes["terrain"] = terrain
    if margin_m is not None:
        changes["terrain_margin_m"] = margin_m
    return dataclasses.replace(db, **changes) if changes else db


def linear(hex_colour: str) -> np.ndarray:
    """(3,) linear RGB of an sRGB '#rrggbb'."""
    return srgb_to_linear(np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0)


def hills_nodes(n: int = HILLS_N, spacing: float = HILLS_SPACING):
    """(heights (n+1, n+1) float32 metres, colours (n+1, n+1, 3) uint8 sRGB) of rolling hills
    0 .. about 270 m high, coloured by height with a 200 m checkerboard for detail."""
    y, x = np.mgrid[0:n + 1, 0:n + 1] * spacing
    size = n * spacing
    h = (120.0 * np.sin(x / size * 4.0 * np.pi) * np.cos(y / size * 3.0 * np.pi)
         + 150.0 * np.exp(-((x - 0.6 * size) ** 2 + (y - 0.7 * size) ** 2)
                          / (2.0 * (0.1 * size) ** 2)))
    h = (h - h.min()).astype(np.float32)
    t = h / h.max()
    c = np.empty(h.shape + (3,))
    c[..., 0] = 0.3 + 0.5 * t
    c[..., 1] = 0.5 + 0.3 * t
    c[..., 2] = 0.25 + 0.15 * ((x // 200 + y // 200) % 2)
    return h, np.clip(np.round(c * 255.0), 0, 255).astype(np.uint8)


@functools.cache
def hills_db(origin_shift: float = 0.0):
    """The hills as a single-level database (page size 32), origin shifted by (s, s, 0)."""
    h, c = hills_nodes()
    origin = np.array(HILLS_ORIGIN) + np.array([origin_shift, origin_shift, 0.0])
    return single_level_database(h, c, HILLS_SPACING, origin, page_size=32)


def flat_nodes(n: int, height: float = 0.0, srgb=(90, 140, 60)):
    """(heights, colours) of a flat field of n x n voxels."""
    h = np.full((n + 1, n + 1), height, np.float32)
    c = np.zeros((n + 1, n + 1, 3), np.uint8)
    c[...] = srgb
    return h, c


def multi_level(heights: np.ndarray, colours_srgb: np.ndarray, spacing: float, origin, *,
                page_size: int = 32, prune_tolerance=None):
    """A multi-level database from level-0 nodes (colours sRGB uint8) by the offline build."""
    lin = srgb_to_linear(colours_srgb.astype(np.float64) / 255.0)
    return build_terrain(np.asarray(heights, np.float64), lin, spacing_m=spacing,
                         origin=np.asarray(origin, np.float64), page_size=page_size,
                         prune_tolerance=prune_tolerance)


@dataclasses.dataclass
class Comparison:
    """How a terrain render agrees with the exact reference (see compare)."""

    colour_mean: float      # mean over pixels of the mean absolute channel error (linear)
    colour_p99: float       # its 99th percentile
    coverage_disagree: float  # share of samples where (inv_z > 0) != reference hit
    range_median: float     # pixel-centre range: median relative error away from silhouettes
    range_p95: float        # its 95th percentile
    range_hits: int         # pixels the range errors are taken over
    coverage_ours: float    # share of samples our inv_z marks as terrain
    coverage_ref: float     # share of samples the reference hits
    column_gap: float       # largest difference of the two coverages within one image column
    finite: bool            # our colours and 1/z are finite and no range is NaN

    def __str__(self) -> str:
        return (f"colour mean {self.colour_mean:.4f} p99 {self.colour_p99:.4f}; coverage "
                f"disagree {self.coverage_disagree:.4f} (ours {self.coverage_ours:.3f} ref "
                f"{self.coverage_ref:.3f}); range rel median {self.range_median:.4f} p95 "
                f"{self.range_p95:.4f} over {self.range_hits} px")


def compare(database: Database, view, *, level_bias: int = 0) -> Comparison:
    """Render the terrain of a view at 4 samples and at the pixel centre and measure it against
    the reference (database.sky_colour is the reference's background: keep sky = earth)."""
    bg = render_terrain(database, view, RGSS4, level_bias=level_bias)
    ref = reference_terrain(database.terrain, view, RGSS4)
    want = ref.pixel_rgb(database.sky_colour.astype(np.float64))
    err = np.abs(bg.rgb.astype(np.float64) - want).mean(axis=2)
    ours = bg.inv_z > 0.0
    centre = render_terrain(database, view, CENTRE, level_bias=level_bias)
    ref_c = reference_terrain(database.terrain, view, CENTRE)
    r_ref = ref_c.range_m[..., 0]
    # Ranges are compared away from silhouettes: where the reference's pixel centre and those
    # of the 8 neighbouring pixels all see terrain (a silhouette pixel's range is the nearer
    # surface's in one renderer and may be the farther one's in the other).
    hit = np.pad(ref_c.hit[..., 0], 1, constant_values=False)
    h, w = r_ref.shape
    interior = np.all([hit[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)], axis=0)
    seen = interior & np.isfinite(centre.range_m)
    rel = np.abs(centre.range_m[seen].astype(np.float64) - r_ref[seen]) / r_ref[seen]
    return Comparison(
        colour_mean=float(err.mean()), colour_p99=float(np.percentile(err, 99)),
        coverage_disagree=float((ours != ref.hit).mean()),
        range_median=float(np.median(rel)) if rel.size else 0.0,
        range_p95=float(np.percentile(rel, 95)) if rel.size else 0.0,
        range_hits=int(seen.sum()),
        coverage_ours=float(ours.mean()), coverage_ref=float(ref.hit.mean()),
        column_gap=float(np.abs(ours.mean(axis=(0, 2)) - ref.hit.mean(axis=(0, 2))).max()),
        finite=bool(np.isfinite(bg.rgb).all() and np.isfinite(bg.inv_z).all()
                    and not np.isnan(bg.range_m).any()))


def surface_z(terrain, x: float, y: float) -> float:
    """World z of a single-level database's bilinear surface at world (x, y)."""
    from channel_worker.pipeline.background.terrain import surface_height

    z = surface_height(terrain, x - terrain.origin[0], y - terrain.origin[1])
    assert z is not None, (x, y)
    return z + float(terrain.origin[2])


def uphill_heading(terrain, x: float, y: float, step: float = 5.0) -> float:
    """Heading (degrees clockwise from north) of steepest ascent at world (x, y)."""
    gx = surface_z(terrain, x + step, y) - surface_z(terrain, x - step, y)
    gy = surface_z(terrain, x, y + step) - surface_z(terrain, x, y - step)
    return math.degrees(math.atan2(gx, gy))


#: sRGB red of each level of level_coloured_db (green and blue 0): linear red rises with the level.
LEVEL_RED = (40, 90, 130, 165, 195, 220, 240, 255)


def level_coloured_db(n: int, spacing: float, *, page_size: int = 64, height: float = 0.0,
                      origin=(0.0, 0.0, 0.0), missing=None):
    """A flat database whose level L is coloured sRGB (LEVEL_RED[L], 0, 0): the picture shows
    which level the renderer drew where.

    Every page of a level is the same stored page (the page table may point many entries at
    one page), so databases tens of kilometres wide cost a few pages. missing(level, px, py)
    -> True leaves that page out (table entry -1; never for the coarsest level).
    """
    from channel_worker.pipeline.scene.terrain.database import TerrainDatabase, page_layout

    pages_x, pages_y, table_offset = page_layout(n, n, page_size)
    levels = len(pages_x)
    assert levels <= len(LEVEL_RED)
    p = page_size
    z = np.full((levels, p, p, 4), height, np.float32)
    rgb = np.zeros((levels, p, p, 4, 3), np.uint8)
    for lv in range(levels):
        rgb[lv, ..., 0] = LEVEL_RED[lv]
    table = np.empty(int((pages_x * pages_y).sum()), np.int32)
    for lv in range(levels):
        for py in range(int(pages_y[lv])):
            for px in range(int(pages_x[lv])):
                gone = missing is not None and lv < levels - 1 and missing(lv, px, py)
                table[table_offset[lv] + py * pages_x[lv] + px] = -1 if gone else lv
    return TerrainDatabase(
        spacing_m=float(spacing), origin=np.asarray(origin, np.float64), nx=n, ny=n,
        page_size=p, levels=levels, pages_x=pages_x, pages_y=pages_y, table_offset=table_offset,
        page_table=table, z=z, rgb=rgb, pattern=np.zeros((levels, p, p), np.uint8),
        z_min=float(height), z_max=float(height), source="<level_coloured_db>")


def level_of(red_linear: np.ndarray) -> np.ndarray:
    """Fractional level from a level_coloured_db pixel's linear red (piecewise linear between
    the levels' colours: a pixel straddling levels L and L + 1 gives L + its share of L + 1)."""
    from channel_worker.pipeline.background.terrain import _SRGB_LUT

    reds = _SRGB_LUT[np.array(LEVEL_RED)].astype(np.float64)
    return np.interp(red_linear, reds, np.arange(len(LEVEL_RED), dtype=np.float64))


def without_pages(terrain, level: int, pages):
    """The database with pages (px, py) of one level left out of the page table (-1)."""
    table = np.array(terrain.page_table, copy=True)
    for px, py in pages:
        table[terrain.table_offset[level] + py * terrain.pages_x[level] + px] = -1
    return dataclasses.replace(terrain, page_table=table)


def coarse_levels(terrain, first: int):
    """The database made of levels first .. levels - 1 only: level `first` becomes level 0
    (voxels 2**first times as wide), sharing the page arrays."""
    start = int(terrain.table_offset[first])
    nx, ny = terrain.level_size(first)
    return dataclasses.replace(
        terrain, spacing_m=terrain.spacing_m * (1 << first), nx=nx, ny=ny,
        levels=terrain.levels - first, pages_x=terrain.pages_x[first:].copy(),
        pages_y=terrain.pages_y[first:].copy(),
        table_offset=terrain.table_offset[first:] - start,
        page_table=np.array(terrain.page_table[start:], copy=True))


def hit_points(view, range_m: np.ndarray) -> np.ndarray:
    """(H, W, 3) world points the pixel centres' rays reach at range_m (nan where infinite)."""
    from channel_worker.pipeline.geometry.view import screen_mapping

    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    tx = (np.arange(view.width) + 0.5 - sx_off) / sx_scale
    ty = (np.arange(view.height) + 0.5 - sy_off) / sy_scale
    eye_dir = np.stack(np.broadcast_arrays(tx[None, :], ty[:, None], np.ones((1, 1))), -1)
    world = eye_dir @ view.world_to_eye
    world /= np.linalg.norm(world, axis=-1, keepdims=True)
    r = np.where(np.isfinite(range_m), range_m, np.nan).astype(np.float64)
    return view.eye + world * r[..., None]
