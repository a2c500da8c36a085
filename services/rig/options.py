"""Render options: every quality knob of a channel in one typed, checked object.

`RenderOptions` is built with the same names from every place a knob can be set, and refuses
an unknown name or a bad value with a message that names it:

- the command line of `ig render` and `ig worker` (add_render_arguments / from_arguments:
  ``--samples rgss4 --terrain-bias 1 --no-haze``, dashes for underscores);
- the rig file's ``[render]`` table (docs/rig-format.md; from_mapping), which every worker of
  the rig reads, so all channels render alike unless a worker's command line says otherwise;
- the ``ig.v1.RenderOptions`` message (wire.py), which a worker reports in its status.

What each setting costs and buys is measured by `make bench` (bench/README.md): speed against
error per sample pattern, sub-area size, terrain level bias and fog table spacing.

The names of sample patterns, filters and renderers are registered here, once; the pipeline
implements each registered name (tests/channel_worker/pipeline/test_render.py checks that it
implements exactly these).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Sample patterns by name: positions in 1/16 pixel from the pixel centre. These are the
#: Direct3D standard multisample patterns (well studied for edge anti-aliasing); every position
#: lies on the rasterizer's 1/256-pixel grid. A pattern may also be asked for by its count.
SAMPLE_PATTERNS: dict[str, tuple[tuple[int, int], ...]] = {
    # One sample at the pixel centre: the classic point-sampled image.
    "centre": ((0, 0),),
    "d3d2": ((4, 4), (-4, -4)),
    # Rotated grid: four distinct x and four distinct y positions, so near-horizontal and
    # near-vertical edges get four coverage levels each.
    "rgss4": ((-2, -6), (6, -2), (-6, 2), (2, 6)),
    "d3d8": ((1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)),
    "d3d16": ((1, 1), (-1, -3), (-3, 2), (4, -1), (-5, -2), (2, 5), (5, 3), (3, -5),
              (-2, 6), (0, -7), (-4, -6), (-6, 4), (-8, 0), (7, -4), (6, 7), (-7, -8)),
}
_PATTERN_BY_COUNT = {len(v): k for k, v in SAMPLE_PATTERNS.items()}

#: Pixel reconstruction filters by name (implemented by the resolve stage).
FILTERS: dict[str, str] = {
    "box": "the pixel's own samples, equal weights (the sub-area pixel output; fastest)",
    "tent": "bilinear, radius 1 pixel: also reads the 8 neighbouring pixels' samples",
    "gaussian": "sigma 0.5 pixel, cut at 1.5: also reads the 8 neighbouring pixels' samples",
}

#: How a texture is filtered to a pixel's footprint (implemented by the resolve stage's
#: texturing; docs/textures.md).
TEXTURE_FILTERS: dict[str, str] = {
    "fade": "each texture's amplitude fades as its finest frequency nears the pixel's sampling "
            "rate (the texture patent's anti-aliasing); one bilinear read per texture",
    "mipmap": "trilinear read from a pre-filtered pyramid at the pixel's footprint "
              "(Williams, Pyramidal parametrics); two bilinear reads per texture",
    "both": "level 0 for as long as the fade keeps it, cross-faded into the pyramid beyond: "
            "sharper than mipmap for textures without fine detail, never aliasing",
}

#: How the box filter weighs a pixel's features (implemented by the resolve stage,
#: shade/_coverage_kernels.py). Where one straight edge crosses a pixel the exact area it
#: covers is known in closed form; the samples still decide what is seen.
COVERAGES: dict[str, str] = {
    "area": "the exact area where one edge crosses a pixel between two features, the samples' "
            "count elsewhere (box filter; on random quads it halves every pattern's error)",
    "samples": "the samples' count everywhere (each pixel the mean of its point samples)",
}

#: Visibility renderers by name.
RENDERERS: dict[str, str] = {
    "subarea": "the sub-area, multi-sample renderer of EP 0611020 (the product)",
    "scanline": "the scan-line renderer of ARL Systems Note 77, one sample per pixel centre; a "
                "cross-check of the polygon visibility that draws no terrain or atmosphere",
}


@dataclass(frozen=True)
class RenderOptions:
    """Every quality knob of one channel.

    Attributes:
        samples: sample pattern name (SAMPLE_PATTERNS); a count (1, 2, 4, 8, 16, as int or
            text) is taken as the pattern of that count and stored as its name.
        filter: pixel reconstruction filter (FILTERS).
        subarea: sub-area edge length for coverage binning, pixels (1..64: a row of one
            sample of a sub-area is one 64-bit coverage mask).
        max_translucent: translucent features kept per sample, nearest first (1..15).
        terrain_bias: terrain resolution level bias (-4..4): voxels are kept 2**bias to
            2**(bias + 1) pixels wide; -1 is finer and slower, +1 coarser and faster.
        haze: draw the scene's haze (False: as if the scene had none).
        clouds: draw the scene's clouds.
        fog_table_subdivision: resample planes of the layered fog's per-frame table per sample
            plane spacing (1..64), where the scene does not set table_spacing_m; finer costs
            table build time (microseconds), not time per sample.
        with_range: also produce each pixel's range in metres (Image.range_m; EXR Z).
        threads: worker threads for the parallel kernels; 0 takes every core numba was
            started with.
        renderer: visibility renderer (RENDERERS).
        texture_filter: how textures are filtered to the pixel's footprint (TEXTURE_FILTERS).
        coverage: how the box filter weighs a pixel's features (COVERAGES); the tent and
            gaussian filters always weigh samples.
    """

    samples: str = "rgss4"
    filter: str = "box"
    subarea: int = 16
    max_translucent: int = 4
    terrain_bias: int = 0
    haze: bool = True
    clouds: bool = True
    fog_table_subdivision: int = 8
    with_range: bool = True
    threads: int = 0
    renderer: str = "subarea"
    texture_filter: str = "fade"
    coverage: str = "area"

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", _pattern_name(self.samples))
        _choice("filter", self.filter, FILTERS)
        _choice("renderer", self.renderer, RENDERERS)
        _choice("texture_filter", self.texture_filter, TEXTURE_FILTERS)
        _choice("coverage", self.coverage, COVERAGES)
        for name, lo, hi in (("subarea", 1, 64), ("max_translucent", 1, 15), ("terrain_bias", -4, 4),
                             ("fog_table_subdivision", 1, 64), ("threads", 0, 1024)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or not lo <= value <= hi:
                raise ValueError(f"{name}: expected an integer in {lo}..{hi}, got {value!r}")
            object.__setattr__(self, name, int(value))
        for name in ("haze", "clouds", "with_range"):
            value = getattr(self, name)
            if not isinstance(value, bool | np.bool_):
                raise ValueError(f"{name}: expected true or false, got {value!r}")
            object.__setattr__(self, name, bool(value))
        if self.renderer == "scanline" and self.samples != "centre":
            raise ValueError(f"samples: the scanline renderer samples pixel centres only "
                             f"(\"centre\"), got {self.samples!r}")

    @property
    def sample_count(self) -> int:
        """Samples per pixel."""
        return len(SAMPLE_PATTERNS[self.samples])

    def sample_offsets(self) -> np.ndarray:
        """(S, 2) float64 sample positions, pixels from the pixel's top-left corner."""
        return 0.5 + np.array(SAMPLE_PATTERNS[self.samples], dtype=np.float64) / 16.0

    def replace(self, **changes: Any) -> RenderOptions:
        """A copy with some options changed (checked like the constructor's)."""
        unknown = sorted(set(changes) - set(option_names()))
        if unknown:
            raise ValueError(_unknown("render option", unknown[0]))
        return dataclasses.replace(self, **changes)

    def to_mapping(self) -> dict[str, Any]:
        """The options as a plain mapping (the rig file's and the bench JSON's form)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_mapping(cls, doc: Mapping[str, Any], *, where: str = "render",
                     base: RenderOptions | None = None) -> RenderOptions:
        """Options from a mapping of option names (a rig file's ``[render]`` table), over base.

        Raises:
            ValueError: not a mapping, an unknown name, or a bad value; the message names
                ``where.name`` and the value.
        """
        if not isinstance(doc, Mapping):
            raise ValueError(f"{where}: expected a table of render options, got {doc!r}")
        base = base or cls()
        for key in doc:
            if key not in option_names():
                raise ValueError(f"{where}.{key}: {_unknown('render option', key)}")
        try:
            return base.replace(**dict(doc))
        except ValueError as exc:
            raise ValueError(f"{where}.{exc}") from None


def option_names() -> tuple[str, ...]:
    """Every option's name, in declaration order."""
    return tuple(f.name for f in dataclasses.fields(RenderOptions))


def add_render_arguments(parser: argparse.ArgumentParser, *, renderer: bool = False,
                         with_range: bool = False) -> None:
    """The options as command-line flags (--samples, --filter, --subarea, --max-translucent,
    --terrain-bias, --haze/--no-haze, --clouds/--no-clouds, --fog-table-subdivision,
    --texture-filter, --threads, --coverage; --renderer and --range/--no-range where the command
    has a use for them).

    Every flag defaults to None, "not given": from_arguments then keeps the value of the base
    options (a rig file's, or the defaults).
    """
    d = RenderOptions()
    group = parser.add_argument_group("render options (docs/rig-format.md [render]; bench/README.md)")
    group.add_argument("--samples", default=None,
                       help=f"samples per pixel: a count ({', '.join(str(n) for n in sorted(_PATTERN_BY_COUNT))}) "
                            f"or a pattern ({', '.join(SAMPLE_PATTERNS)}); default {d.samples}")
    group.add_argument("--filter", default=None, choices=list(FILTERS),
                       help=f"pixel reconstruction filter; default {d.filter}")
    group.add_argument("--subarea", type=int, default=None,
                       help=f"sub-area size for coverage binning, pixels; default {d.subarea}")
    group.add_argument("--max-translucent", type=int, default=None,
                       help=f"translucent features kept per sample; default {d.max_translucent}")
    group.add_argument("--terrain-bias", type=int, default=None,
                       help="terrain level bias, -4..4: voxels are kept 2^bias to 2^(bias+1) pixels wide "
                            f"(-1 finer and slower, +1 coarser and faster); default {d.terrain_bias}")
    group.add_argument("--haze", action=argparse.BooleanOptionalAction, default=None,
                       help="draw the scene's haze (default: yes)")
    group.add_argument("--clouds", action=argparse.BooleanOptionalAction, default=None,
                       help="draw the scene's clouds (default: yes)")
    group.add_argument("--fog-table-subdivision", type=int, default=None,
                       help="layered fog table entries per sample-plane spacing, 1..64; "
                            f"default {d.fog_table_subdivision}")
    group.add_argument("--texture-filter", default=None, choices=list(TEXTURE_FILTERS),
                       help=f"texture filtering to the pixel footprint; default {d.texture_filter}")
    group.add_argument("--threads", type=int, default=None,
                       help="threads for the parallel kernels (0: every core); default 0")
    group.add_argument("--coverage", default=None, choices=list(COVERAGES),
                       help="box filter: exact area of a pixel's single edge (area) or the "
                            f"samples' count (samples); default {d.coverage}")
    if renderer:
        group.add_argument("--renderer", default=None, choices=list(RENDERERS),
                           help="visibility renderer (scanline: the cross-check, --samples centre); "
                                "default subarea")
    if with_range:
        group.add_argument("--range", dest="with_range", action=argparse.BooleanOptionalAction,
                           default=None, help="also compute each pixel's range (EXR Z; default: yes)")


def from_arguments(args: argparse.Namespace, base: RenderOptions | None = None) -> RenderOptions:
    """The options given on the command line (add_render_arguments) over base.

    Raises:
        ValueError: a bad value, named with its option.
    """
    given = {name: getattr(args, name) for name in option_names()
             if getattr(args, name, None) is not None}
    return (base or RenderOptions()).replace(**given)


def _pattern_name(spec: Any) -> str:
    if isinstance(spec, str) and spec.isdigit():
        spec = int(spec)
    if isinstance(spec, int | np.integer) and not isinstance(spec, bool):
        if int(spec) not in _PATTERN_BY_COUNT:
            raise ValueError(f"samples: {spec} has no pattern; counts are {sorted(_PATTERN_BY_COUNT)}")
        return _PATTERN_BY_COUNT[int(spec)]
    if not isinstance(spec, str) or spec not in SAMPLE_PATTERNS:
        raise ValueError(f"samples: unknown pattern {spec!r}; known: {', '.join(SAMPLE_PATTERNS)}")
    return spec


def _choice(name: str, value: Any, known: Mapping[str, str]) -> None:
    if not isinstance(value, str) or value not in known:
        raise ValueError(f"{name}: unknown {name} {value!r}; known: {', '.join(known)}")


def _unknown(kind: str, name: str) -> str:
    return f"unknown {kind} {name!r}; known: {', '.join(option_names())}"
