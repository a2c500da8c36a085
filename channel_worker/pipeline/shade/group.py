"""What every shading kernel of one frame reads, as one group (ShadeFrame): the frame's
constants, its background, the Shading of its polygons and, for the box filter, the
analytic edge coverage. The visibility stage's fused box filter and the resolve stage's
kernels take it instead of its four parts one by one."""

from __future__ import annotations

from typing import NamedTuple

from channel_worker.pipeline.contract import Background, Edges, FrameConstants, ScreenPolygons
from services.rig.options import RenderOptions

from ._coverage_kernels import Coverage, coverage_group
from .shading import Shading, shading

#: The coverage rules registered in services.rig.options.COVERAGES: whether a pixel one edge
#: crosses takes the exact area inside it (_coverage_kernels) or its samples' count.
COVERAGES: dict[str, bool] = {"area": True, "samples": False}


class ShadeFrame(NamedTuple):
    """One frame's shading inputs.

    Attributes:
        frame: the frame's constants (raster, sample positions, horizon, screen mapping).
        background: the background stage's output (or no_background()).
        sh: the polygons' Shading (shading.shading).
        cov: the analytic edge coverage (_coverage_kernels.Coverage; off unless the box
            filter takes single-edge pixels' exact area).
    """

    frame: FrameConstants
    background: Background
    sh: Shading
    cov: Coverage


def area_coverage(options: RenderOptions, samples: int) -> bool:
    """Whether single-edge pixels take their exact area: coverage "area" with the box filter
    (the wider filters weigh samples of neighbouring pixels, which an area does not say) and
    at least two samples (one sample never sees two features)."""
    return COVERAGES[options.coverage] and options.filter == "box" and samples >= 2


def shade_frame(screen: ScreenPolygons, frame: FrameConstants, background: Background,
                options: RenderOptions, edges: Edges | None) -> ShadeFrame:
    """The frame's ShadeFrame; the analytic coverage is on where area_coverage says so and
    the edges are given."""
    on = area_coverage(options, frame.offsets.shape[0])
    return ShadeFrame(frame, background, shading(screen, frame, background),
                      coverage_group(on, screen, edges))
