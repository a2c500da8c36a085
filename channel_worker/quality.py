"""Quality options shared by `ig render`, `ig worker` and `ig demo`: what each costs is in
`make bench` (bench/results/visibility.json), speed against error per setting."""

from __future__ import annotations

import argparse
from typing import Any

from .pipeline.binning import DEFAULT_SUBAREA
from .pipeline.render import RENDERERS
from .pipeline.resolve import FILTERS
from .pipeline.samples import pattern_names
from .pipeline.terrain import DEFAULT_LEVEL_BIAS
from .pipeline.types import DEFAULT_MAX_TRANSLUCENT


def add_quality_arguments(parser: argparse.ArgumentParser, *, renderer: bool = False) -> None:
    """--samples, --filter, --subarea, --max-translucent, --terrain-bias (and --renderer if
    asked)."""
    parser.add_argument("--samples", default="4",
                        help=f"samples per pixel: a count (1, 2, 4, 8, 16) or a pattern "
                             f"({', '.join(pattern_names())}); default 4")
    parser.add_argument("--filter", default="box", choices=sorted(FILTERS),
                        help="pixel reconstruction filter (default box: the pixel's own samples)")
    parser.add_argument("--subarea", type=int, default=DEFAULT_SUBAREA,
                        help=f"sub-area size in pixels for coverage binning (default {DEFAULT_SUBAREA})")
    parser.add_argument("--max-translucent", type=int, default=DEFAULT_MAX_TRANSLUCENT,
                        help=f"translucent features kept per sample (default {DEFAULT_MAX_TRANSLUCENT})")
    parser.add_argument("--terrain-bias", type=int, default=DEFAULT_LEVEL_BIAS,
                        help="terrain resolution level bias, -4..4: voxels are kept 2^bias to "
                             "2^(bias+1) pixels wide (default 0; -1 finer and slower, +1 coarser)")
    if renderer:
        parser.add_argument("--renderer", default="subarea", choices=RENDERERS,
                            help="visibility renderer (scanline: seed 003 cross-check, --samples centre)")


def quality_options(args: argparse.Namespace) -> dict[str, Any]:
    """render_frame keyword arguments from the parsed options (validated by render_frame)."""
    options: dict[str, Any] = {"samples": args.samples, "filter": args.filter,
                               "subarea": args.subarea, "max_translucent": args.max_translucent,
                               "terrain_bias": args.terrain_bias}
    if hasattr(args, "renderer"):
        options["renderer"] = args.renderer
    return options


def check_options(options: dict[str, Any]) -> None:
    """ValueError naming the first bad option, before anything is started."""
    from .pipeline.binning import check_subarea
    from .pipeline.resolve import check_filter
    from .pipeline.samples import sample_pattern
    from .pipeline.terrain import check_level_bias
    from .pipeline.types import check_max_translucent

    sample_pattern(options.get("samples", 4))
    check_filter(options.get("filter", "box"))
    check_subarea(options.get("subarea", DEFAULT_SUBAREA))
    check_max_translucent(options.get("max_translucent", DEFAULT_MAX_TRANSLUCENT))
    check_level_bias(options.get("terrain_bias", DEFAULT_LEVEL_BIAS))
    if options.get("renderer", "subarea") not in RENDERERS:
        raise ValueError(f"renderer: unknown renderer {options['renderer']!r}; known: {', '.join(RENDERERS)}")
