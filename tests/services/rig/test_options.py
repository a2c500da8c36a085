"""RenderOptions: one checked object for every quality knob, the same names everywhere."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from services.rig.options import (
    COVERAGES,
    FILTERS,
    RENDERERS,
    SAMPLE_PATTERNS,
    TEXTURE_FILTERS,
    RenderOptions,
    add_render_arguments,
    from_arguments,
    option_names,
)


def test_defaults_are_the_shipped_quality():
    o = RenderOptions()
    assert (o.samples, o.filter, o.subarea, o.max_translucent, o.terrain_bias) == ("rgss4", "box", 16, 4, 0)
    assert o.haze and o.clouds and o.with_range and o.threads == 0 and o.renderer == "subarea"
    assert o.coverage == "area"
    assert o.texture_filter == "fade"
    assert o.sample_count == 4


@pytest.mark.parametrize("count, name", [(1, "centre"), (2, "d3d2"), (4, "rgss4"), ("8", "d3d8"),
                                         (16, "d3d16"), (np.int64(4), "rgss4")])
def test_a_sample_count_names_its_pattern(count, name):
    assert RenderOptions(samples=count).samples == name


def test_every_pattern_lies_inside_the_pixel_on_the_subpixel_grid():
    for name, sixteenths in SAMPLE_PATTERNS.items():
        offsets = RenderOptions(samples=name).sample_offsets()
        assert offsets.shape == (len(sixteenths), 2)
        assert ((offsets >= 0.0) & (offsets < 1.0)).all(), name
        np.testing.assert_array_equal(offsets * 256, np.round(offsets * 256))
        assert len({tuple(o) for o in offsets}) == len(offsets), name  # no sample twice


@pytest.mark.parametrize("field, value, message", [
    ("samples", 3, "samples: 3 has no pattern; counts are"),
    ("samples", "foo", "samples: unknown pattern 'foo'; known: centre"),
    ("samples", True, "samples: unknown pattern True"),
    ("filter", "lanczos", "filter: unknown filter 'lanczos'; known: box, tent, gaussian"),
    ("renderer", "zbuffer", "renderer: unknown renderer 'zbuffer'"),
    ("coverage", "exact", "coverage: unknown coverage 'exact'; known: area, samples"),
    ("subarea", 0, r"subarea: expected an integer in 1\.\.64, got 0"),
    ("subarea", 16.0, r"subarea: expected an integer in 1\.\.64, got 16\.0"),
    ("max_translucent", 16, r"max_translucent: expected an integer in 1\.\.15, got 16"),
    ("terrain_bias", -5, r"terrain_bias: expected an integer in -4\.\.4, got -5"),
    ("fog_table_subdivision", 65, r"fog_table_subdivision: expected an integer in 1\.\.64, got 65"),
    ("threads", -1, r"threads: expected an integer in 0\.\.1024, got -1"),
    ("threads", True, r"threads: expected an integer in 0\.\.1024, got True"),
    ("haze", "yes", "haze: expected true or false, got 'yes'"),
    ("with_range", 1, "with_range: expected true or false, got 1"),
])
def test_bad_values_are_refused_naming_the_field_and_value(field, value, message):
    with pytest.raises(ValueError, match=message):
        RenderOptions(**{field: value})


def test_the_scanline_renderer_takes_pixel_centres_only():
    RenderOptions(renderer="scanline", samples="centre")
    with pytest.raises(ValueError, match="samples: the scanline renderer samples pixel centres only"):
        RenderOptions(renderer="scanline", samples=4)


def test_from_mapping_refuses_unknown_names_and_says_where():
    with pytest.raises(ValueError, match=r"render\.sample: unknown render option 'sample'; known: samples, filter"):
        RenderOptions.from_mapping({"sample": 4})
    with pytest.raises(ValueError, match=r"rig\.toml: render\.subarea: expected an integer"):
        RenderOptions.from_mapping({"subarea": "16"}, where="rig.toml: render")
    with pytest.raises(ValueError, match="render: expected a table of render options"):
        RenderOptions.from_mapping(["samples"])
    base = RenderOptions(samples=16)
    assert RenderOptions.from_mapping({"filter": "tent"}, base=base) == RenderOptions(samples=16, filter="tent")
    assert RenderOptions.from_mapping(base.to_mapping()) == base


def test_replace_checks_like_the_constructor():
    o = RenderOptions()
    assert o.replace(with_range=False).with_range is False
    with pytest.raises(ValueError, match="unknown render option 'colour'"):
        o.replace(colour=1)
    with pytest.raises(ValueError, match="filter: unknown filter"):
        o.replace(filter="sinc")


def test_registries_are_what_the_pipeline_implements():
    from channel_worker.pipeline.resolve.resolve import FILTERS as implemented
    from channel_worker.pipeline.shade.group import COVERAGES as coverages

    assert set(implemented) == set(FILTERS)
    assert set(coverages) == set(COVERAGES)
    assert set(RENDERERS) == {"subarea", "scanline"}
    assert set(TEXTURE_FILTERS) == {"fade", "mipmap", "both"}  # shade/texturing.py reads each


def _parse(argv, **kw):
    parser = argparse.ArgumentParser()
    add_render_arguments(parser, **kw)
    return parser.parse_args(argv)


def test_command_line_flags_use_the_same_names_and_keep_the_base_when_not_given():
    base = RenderOptions(samples=16, haze=False, terrain_bias=2)
    assert from_arguments(_parse([]), base) == base
    args = _parse(["--samples", "1", "--filter", "tent", "--subarea", "8", "--max-translucent", "2",
                   "--terrain-bias", "-1", "--haze", "--no-clouds", "--fog-table-subdivision", "4",
                   "--threads", "1", "--renderer", "subarea", "--no-range", "--coverage", "samples"],
                  renderer=True, with_range=True)
    o = from_arguments(args, base)
    assert o == RenderOptions(samples="centre", filter="tent", subarea=8, max_translucent=2,
                              terrain_bias=-1, haze=True, clouds=False, fog_table_subdivision=4,
                              with_range=False, threads=1, renderer="subarea", coverage="samples")
    # Every option is reachable from the command line (renderer and range where asked for).
    flags = {a.dest for a in argparse.ArgumentParser()._actions}
    parser = argparse.ArgumentParser()
    add_render_arguments(parser, renderer=True, with_range=True)
    assert set(option_names()) <= {a.dest for a in parser._actions} - flags
    with pytest.raises(ValueError, match=r"terrain_bias: expected an integer in -4..4, got 9"):
        from_arguments(_parse(["--terrain-bias", "9"]))
