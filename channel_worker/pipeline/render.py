"""One channel, one frame: the pipeline's stages called in order (docs/architecture.md)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numba
import numpy as np

from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions
from services.rig.report import FrameReport

from .background.background import render_background
from .binning.binning import bin_features
from .binning.edges import setup_edges
from .contract import Image, no_background
from .geometry.backface import eliminate_backfaces
from .geometry.clip import clip
from .geometry.cull import cull
from .geometry.project import project
from .geometry.transform import to_eye
from .geometry.trees import plant_trees
from .geometry.view import frame_constants, make_view
from .jit import thread_pool_size
from .resolve.resolve import resolve
from .scene.database import Database
from .visibility.scanline import scanline_visibility
from .visibility.visibility import sample_store, visible_pixels

_DEFAULT = RenderOptions()


def render_frame(database: Database, channel: ChannelSpec, eyepoint: Eyepoint,
                 options: RenderOptions = _DEFAULT, *, report: FrameReport | None = None,
                 trace: dict | None = None, out: np.ndarray | None = None) -> Image:
    """Render one channel's view of the database from the eyepoint.

    Args:
        database: the loaded scene.
        channel: the channel's offset, frustum and raster size.
        eyepoint: world position (metres, float64) and attitude (degrees).
        options: every quality knob (services.rig.options.RenderOptions).
        report: if given, receives the seconds spent in each stage and the stages' counters
            ("translucent_dropped", "terrain_voxels", ...; docs/pipeline.md).
        trace: if given, receives the frame's "screen" polygons, sample "buffer" (None on the
            default box path, which keeps no sample store) and "background".
        out: (H, W, 3) float32 array the colours are written into (and returned as
            Image.rgb); a caller rendering frame after frame passes the same one.

    Raises:
        ValueError: a non-finite eyepoint field, an impossible channel, more threads than
            numba was started with, or a scene the scanline renderer cannot draw; the message
            names the field and value.
    """
    clock = _Clock(report)
    scene = _drawn(database, options)
    with _threads(options.threads):
        with clock("view"):
            view = make_view(channel, eyepoint)
            frame = frame_constants(view, scene, options.sample_offsets(), options.texture_filter)
        atmosphere = (scene.terrain is not None or scene.haze is not None
                      or scene.clouds is not None or scene.fog is not None)
        if options.renderer == "scanline" and atmosphere:
            raise ValueError("renderer: the scanline renderer (a cross-check of the polygon "
                             "visibility) draws no terrain, haze, fog or clouds; use \"subarea\"")
        if scene.near_trees is not None:
            with clock("trees"):
                scene = plant_trees(scene, view)
        with clock("cull"):
            draws = cull(scene, view)
        with clock("transform"):
            polys = to_eye(scene, draws, view)
        with clock("backface"):
            polys = eliminate_backfaces(polys)
        with clock("clip"):
            polys = clip(polys, view)
        with clock("project"):
            screen = project(polys, view)
        counters = report.counters if report is not None else {}
        background, buffer, edges = no_background(), None, None
        if options.renderer == "scanline":
            with clock("visibility"):
                buffer = scanline_visibility(screen, frame, options, counters)
        else:
            with clock("edges"):
                edges = setup_edges(screen, view.width, view.height)
            with clock("binning"):
                bins = bin_features(edges, screen.start, view.width, view.height, options.subarea)
            # The background (terrain, the sky and earth through haze and fog, clouds) before
            # the visibility: polygons are depth-tested against it, so it needs per-sample depth
            # only in the sub-areas that hold polygons. A scene without any skips the stage.
            if atmosphere:
                with clock("background"):
                    background = render_background(scene, view, frame, options, bins, counters,
                                                   parts=report.part_seconds if report else None)
            if options.filter == "box" and trace is None:
                # Default quality: pixels straight from each sub-area, no sample store in memory.
                with clock("visibility"):
                    image = visible_pixels(screen, edges, bins, frame, background, options,
                                           counters, out=out)
                return image
            with clock("visibility"):
                buffer = sample_store(screen, edges, bins, frame, background, options, counters)
        with clock("resolve"):
            image = resolve(buffer, screen, frame, background, options, edges=edges, out=out)
    if trace is not None:
        trace["screen"] = screen
        trace["buffer"] = buffer
        trace["background"] = background
    return image


def _drawn(database: Database, options: RenderOptions) -> Database:
    """The database as the options draw it: without its haze or clouds when they are off."""
    haze = database.haze if options.haze else None
    clouds = database.clouds if options.clouds else None
    if haze is database.haze and clouds is database.clouds:
        return database
    return dataclasses.replace(database, haze=haze, clouds=clouds)


@contextmanager
def _threads(threads: int) -> Iterator[None]:
    """numba's parallel kernels on `threads` threads for the frame (0: every thread it has)."""
    if threads == 0:
        yield
        return
    if threads > thread_pool_size():
        raise ValueError(f"threads: {threads} is more than the {thread_pool_size()} numba was started "
                         f"with (NUMBA_NUM_THREADS)")
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


class _Clock:
    """Times each stage into the report (nothing without one)."""

    def __init__(self, report: FrameReport | None) -> None:
        self.report = report

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        if self.report is None:
            yield
            return
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.report.stage_seconds[stage] = time.perf_counter() - t0
