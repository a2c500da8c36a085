"""warp_alone: the background stage without the terrain's column scan, for the compile
processes (channel_worker/compile_jobs.py) that build the warp's kernels apart from the scan's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from channel_worker.pipeline.background.background import render_background, scan_alone, warp_alone
from channel_worker.pipeline.geometry.view import frame_constants, make_view
from channel_worker.pipeline.scene.load import bundled_scene_path, demo_scene_path, load_scene
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

CHANNEL = ChannelSpec("small", 48, 36, -30.0, 30.0, -22.5, 22.5)
EYE = Eyepoint.of(0.0, -800.0, 60.0, 0.0, -3.0, 0.0)


def _frame(scene):
    options = RenderOptions(with_range=False)
    view = make_view(CHANNEL, EYE)
    return view, frame_constants(view, scene, options.sample_offsets()), options


def test_it_draws_what_the_stage_draws_of_the_scene_without_its_terrain():
    demo = load_scene(demo_scene_path())
    assert demo.terrain is not None and demo.clouds is not None
    view, frame, options = _frame(demo)
    alone = warp_alone(demo, view, frame, options)
    bare = render_background(dataclasses.replace(demo, terrain=None), view, frame, options, None, {})
    for field in ("rgb", "inv_z", "range_m", "cloud"):
        np.testing.assert_array_equal(getattr(alone, field), getattr(bare, field), err_msg=field)
    assert not alone.inv_z.any()  # no terrain: nothing hides a polygon


def test_a_scene_without_terrain_or_clouds_has_no_warp_to_compile():
    flat = load_scene(bundled_scene_path())
    view, frame, options = _frame(flat)
    with pytest.raises(ValueError, match="neither terrain nor clouds"):
        warp_alone(flat, view, frame, options)


def test_the_scan_alone_is_the_pre_image_the_stage_warps():
    demo = load_scene(demo_scene_path())
    view, _, options = _frame(demo)
    pre = scan_alone(demo, view, options)
    assert pre.texels.shape[0] > 1 and (pre.texels[..., 3] > 0).any()  # terrain was scanned
    flat = load_scene(bundled_scene_path())
    with pytest.raises(ValueError, match="no terrain"):
        scan_alone(flat, *_frame(flat)[::2])
