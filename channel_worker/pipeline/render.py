"""One channel, one frame: the pipeline's stages called in order."""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Iterator

from .backface import eliminate_backfaces
from .clip import clip
from .cull import cull
from .geometry import make_view, to_eye
from .horizon import synthesize_horizon
from .project import project
from .raster import rasterize
from .resolve import resolve
from .samples import sample_pattern
from .types import ChannelSpec, Database, Eyepoint, Image, StageTimes


def render_frame(database: Database, channel: ChannelSpec, eyepoint: Eyepoint, *,
                 samples: int | str = 4, times: StageTimes | None = None) -> Image:
    """Render one channel's view of the database from the eyepoint.

    Args:
        database: the loaded scene.
        channel: the channel's offset, frustum and raster size.
        eyepoint: world position (metres, float64) and attitude (degrees).
        samples: sample pattern name or count (see samples.py).
        times: if given, receives the seconds spent in each stage.

    Raises:
        ValueError: a non-finite eyepoint field, an impossible channel, an unknown pattern;
            the message names the field and value.
    """
    clock = _Clock(times)
    offsets = sample_pattern(samples)
    with clock("view"):
        view = make_view(channel, eyepoint)
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
    with clock("horizon"):
        buffer = synthesize_horizon(database, view, offsets)
    with clock("raster"):
        buffer = rasterize(screen, buffer)
    with clock("resolve"):
        image = resolve(buffer, view, database)
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
