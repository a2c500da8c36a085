"""One channel, one frame: the pipeline's stages called in order."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from .backface import eliminate_backfaces
from .binning import DEFAULT_SUBAREA, bin_features
from .clip import clip
from .cull import cull
from .edges import setup_edges
from .geometry import make_view, to_eye
from .project import project
from .resolve import check_filter, resolve
from .samples import sample_pattern
from .scanline import scanline_visibility
from .terrain import DEFAULT_LEVEL_BIAS, render_terrain
from .types import (
    DEFAULT_MAX_TRANSLUCENT,
    ChannelSpec,
    Database,
    Eyepoint,
    Image,
    StageTimes,
    check_max_translucent,
)
from .visibility import (
    resolve_visibility,
    visible_pixels,
)

#: Visibility renderers by name: "subarea" is the sub-area, multi-sample renderer (seed 000);
#: "scanline" the scan-line hidden-surface algorithm of seed 003, one sample per pixel centre,
#: kept as an independent cross-check.
RENDERERS = ("subarea", "scanline")


def render_frame(database: Database, channel: ChannelSpec, eyepoint: Eyepoint, *,
                 samples: int | str = 4, renderer: str = "subarea", filter: str = "box",
                 subarea: int = DEFAULT_SUBAREA, max_translucent: int = DEFAULT_MAX_TRANSLUCENT,
                 with_range: bool = True, times: StageTimes | None = None,
                 trace: dict | None = None, out: np.ndarray | None = None,
                 stats: dict | None = None, terrain_bias: int = DEFAULT_LEVEL_BIAS) -> Image:
    """Render one channel's view of the database from the eyepoint.

    Args:
        database: the loaded scene.
        channel: the channel's offset, frustum and raster size.
        eyepoint: world position (metres, float64) and attitude (degrees).
        samples: sample pattern name or count (samples.py); the scanline renderer takes only
            "centre" (1).
        renderer: name in RENDERERS.
        filter: reconstruction filter name (resolve.FILTERS).
        subarea: sub-area edge length, pixels (binning.py).
        max_translucent: translucent features kept per sample (visibility.py).
        with_range: also compute Image.range_m (else None; a channel that only shows colour
            skips a square root and a division per covered sample).
        times: if given, receives the seconds spent in each stage.
        trace: if given, receives the frame's "screen" polygons and sample "buffer".
        out: (H, W, 3) float32 array the colours are written into (and returned as
            Image.rgb); a caller rendering frame after frame passes the same one.
        stats: if given, receives the visibility counters (SampleBuffer.stats), among them
            "translucent_dropped", and the terrain stage's ("terrain_voxels", ...).
        terrain_bias: terrain resolution level bias (terrain.py; 0: voxels 1 to 2 pixels wide).

    Raises:
        ValueError: a non-finite eyepoint field, an impossible channel, an unknown pattern,
            renderer or filter, a bad sub-area size or store size; the message names the
            field and value.
    """
    offsets = sample_pattern(samples)
    if renderer not in RENDERERS:
        raise ValueError(f"renderer: unknown renderer {renderer!r}; known: {', '.join(RENDERERS)}")
    if renderer == "scanline" and offsets.shape[0] != 1:
        raise ValueError(f"samples: the scanline renderer samples pixel centres only "
                         f"(\"centre\"), got {samples!r}")
    check_filter(filter)
    check_max_translucent(max_translucent)
    clock = _Clock(times)
    background = None  # the terrain stage's output (subarea renderer, scenes that have one)
    with clock("view"):
        view = make_view(channel, eyepoint)
    atmosphere = (database.terrain is not None or database.haze is not None
                  or database.clouds is not None or database.fog is not None)
    if renderer == "scanline" and atmosphere:
        raise ValueError("renderer: the scanline renderer (a cross-check of the polygon "
                         "visibility) draws no terrain, haze, fog or clouds; use \"subarea\"")
    with clock("cull"):
        draws = cull(database, view)
    with clock("transform"):
        polys = to_eye(database, draws, view)
    with clock("backface"):
        polys = eliminate_backfaces(polys)
    with clock("clip"):
        polys = clip(polys, view)
    with clock("project"):
        screen = project(polys, view)
    if renderer == "subarea":
        with clock("edges"):
            edges = setup_edges(screen, view.width, view.height)
        with clock("binning"):
            bins = bin_features(edges, screen.start, view.width, view.height, subarea)
        # The terrain (and the sky and earth through haze and fog, clouds) before the
        # visibility: the polygons are depth-tested against it, so it needs per-sample depth
        # only in the sub-areas that hold polygons. A scene without terrain, haze, fog or
        # clouds skips the stage.
        if atmosphere:
            with clock("terrain"):
                background = render_terrain(database, view, offsets, level_bias=terrain_bias,
                                            depth_tiles=(bins.size, np.diff(bins.start) > 0))
            if stats is not None:
                stats.update(background.stats)
        if filter == "box" and trace is None:
            # Default quality: pixels straight from each sub-area, no sample store in memory.
            with clock("visibility"):
                return visible_pixels(screen, edges, bins, view, database, offsets,
                                      max_translucent, with_range=with_range, out=out,
                                      stats=stats, background=background)
        with clock("visibility"):
            buffer = resolve_visibility(screen, edges, bins, view, offsets, max_translucent,
                                        with_range=with_range, background=background)
    else:
        with clock("scanline"):
            buffer = scanline_visibility(screen, view, database, max_translucent=max_translucent)
            if not with_range:
                buffer = dataclasses.replace(buffer, polygon_range=None)
    with clock("resolve"):
        image = resolve(buffer, screen, view, database, filter, out=out, background=background)
    if stats is not None:
        stats.update(buffer.stats)
    if trace is not None:
        trace["screen"] = screen
        trace["buffer"] = buffer
        trace["background"] = background
    return image


class _Clock:
    def __init__(self, times: StageTimes | None) -> None:
        self.times = times

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            if self.times is not None:
                self.times.seconds[stage] = time.perf_counter() - t0
