"""The land's detail over the terrain (docs/terrain.md "Detail") on the demo scene: the airfield
set into the land without a seam, fields and rock where the land says, texture that fades with
range, and a scene without terrain.detail drawn as before."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

#: The airfield's grass faces' west edge (channel_worker/data/build_airfield.py: the grass field
#: spans x -380..380, y -1250..1250), inside the terrain's flattened pad (x -450..550).
GRASS_WEST_X = -380.0
#: Straight down from 120 m: 45 degrees across 240 pixels is 0.41 m a pixel on the ground.
DOWN = ChannelSpec.symmetric("down", 240, 160, 45.0)
OPTIONS = RenderOptions(samples=4)


@pytest.fixture(scope="module")
def demo():
    return load_scene(demo_scene_path())


def look_down(x: float, y: float, height: float = 120.0) -> Eyepoint:
    return Eyepoint(np.array([x, y, height]), 0.0, -90.0, 0.0)


def column_of(x: float, eye_x: float, height: float, width: int, fov_deg: float) -> float:
    """Image column (pixels from the left, continuous) of ground x seen straight down."""
    half = np.tan(np.radians(fov_deg / 2.0)) * height
    return (x - (eye_x - half)) / (2.0 * half) * width


def test_no_seam_where_the_airfield_grass_meets_the_land(demo):
    # Straight down over the grass faces' west edge: the land on the left, the airfield's grass
    # faces on the right. The step in the columns' mean linear colour across the edge must be
    # no larger than the steps between neighbouring columns elsewhere (the texture's own
    # variation): no visible seam.
    eye_x = GRASS_WEST_X + 10.0  # the edge a quarter of the way across
    img = render_frame(demo, DOWN, look_down(eye_x, 0.0), OPTIONS).rgb.astype(np.float64)
    profile = img.mean(axis=0)  # (columns, 3) mean linear colour of each column
    edge = column_of(GRASS_WEST_X, eye_x, 120.0, DOWN.width, 45.0)
    c = int(round(edge))
    across = np.abs(profile[c + 2] - profile[c - 3]).sum()  # 5 columns apart, straddling the edge
    steps = np.abs(profile[5:] - profile[:-5]).sum(axis=1)  # the same spacing everywhere
    away = np.concatenate([steps[:c - 8], steps[c + 3:]])
    assert across <= np.percentile(away, 90), (across, np.percentile(away, 90))
    # And the two sides are the same grass: their means within 4 % of each other.
    left = profile[:c - 3].mean(axis=0)
    right = profile[c + 3:].mean(axis=0)
    assert np.all(np.abs(left - right) <= 0.04 * right), (left, right)


def test_without_the_detail_the_seam_is_there(demo):
    # The same view without terrain.detail: the relief colour meets the airfield's grass in a
    # step far above the texture's own variation (what the test above would catch).
    plain = dataclasses.replace(demo, terrain_land=None)
    eye_x = GRASS_WEST_X + 10.0
    img = render_frame(plain, DOWN, look_down(eye_x, 0.0), OPTIONS).rgb.astype(np.float64)
    profile = img.mean(axis=0)
    c = int(round(column_of(GRASS_WEST_X, eye_x, 120.0, DOWN.width, 45.0)))
    across = np.abs(profile[c + 2] - profile[c - 3]).sum()
    steps = np.abs(profile[5:] - profile[:-5]).sum(axis=1)
    away = np.concatenate([steps[:c - 8], steps[c + 3:]])
    assert across > 3.0 * np.percentile(away, 90)


def test_the_land_near_the_eye_is_textured_and_the_texture_fades_with_range(demo):
    # 300 m over the land west of the airfield, looking 20 degrees down: texture near the eye
    # (pixel-to-pixel variation well above the plain relief's), next to none far away.
    ch = ChannelSpec.symmetric("c", 200, 150, 40.0)
    eye = Eyepoint(np.array([-2600.0, -600.0, 300.0]), 270.0, -20.0, 0.0)
    detailed = render_frame(demo, ch, eye, OPTIONS).rgb.astype(np.float64)
    plain = render_frame(dataclasses.replace(demo, terrain_land=None), ch, eye, OPTIONS).rgb.astype(np.float64)

    def roughness(img, rows):
        band = img[rows]
        return float(np.abs(np.diff(band, axis=1)).mean())

    near = slice(130, 150)  # the bottom rows: the nearest ground
    assert roughness(detailed, near) > 2.0 * roughness(plain, near)


def test_the_scene_names_the_detail_and_the_pads_come_from_the_terrain(demo):
    from channel_worker.pipeline.background.terrain import terrain_detail
    from channel_worker.pipeline.geometry.view import frame_constants, make_view

    land = demo.terrain_land
    assert land is not None and min(land.grass, land.field, land.rock, land.forest, land.pad) >= 0
    # The bundled scene's pad area is its grass faces' (which cover it), feathered 460 m out.
    assert land.pads.tolist() == [[-380.0, -1250.0, 380.0, 1250.0, 460.0]] and land.pad_covered
    frame = frame_constants(make_view(DOWN, look_down(0.0, 0.0)), demo, OPTIONS.sample_offsets())
    assert terrain_detail(demo, frame).on
    # A scene without terrain.detail: off, and the cast skips it.
    assert not terrain_detail(dataclasses.replace(demo, terrain_land=None), frame).on


def test_without_areas_the_pads_are_the_terrains_flattened_ones(tmp_path):
    import json

    doc = json.loads(demo_scene_path().read_text(encoding="utf-8"))
    del doc["terrain"]["detail"]["pad"]["areas"]
    doc["terrain"]["offset_m"] = [10.0, -20.0, 0.0]
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    land = load_scene(path).terrain_land
    # The bundled terrain's recipe flattens x -450..550, y -1300..1300 with a 400 m blend; the
    # terrain's offset moves them with it.
    assert land.pads.tolist() == [[-440.0, -1320.0, 560.0, 1280.0, 400.0]]


@pytest.mark.parametrize("detail, field", [
    ({"grass": "no_such_code"}, "terrain.detail.grass"),
    ({"rock": 3}, "terrain.detail.rock"),
    ({"pad": {"code": "grass"}}, "terrain.detail.pad"),
    ({"pad": {"colour": "green"}}, "terrain.detail.pad.colour"),
    ({"meadow": "grass"}, "terrain.detail"),
    ({"pad": {"colour": "#00ff00", "covered": "yes"}}, "terrain.detail.pad.covered"),
    ({"pad": {"colour": "#00ff00", "areas": []}}, "terrain.detail.pad.areas"),
    ({"pad": {"colour": "#00ff00", "areas": [[0, 0, -1, 1, 5]]}}, "terrain.detail.pad.areas[0]"),
    ({"pad": {"colour": "#00ff00", "areas": [[0, 0, 1, 1, "wide"]]}}, "terrain.detail.pad.areas[0][4]"),
])
def test_a_bad_detail_is_refused_naming_the_field(tmp_path, detail, field):
    import json

    from channel_worker.pipeline.scene.load import SceneError

    doc = json.loads(demo_scene_path().read_text(encoding="utf-8"))
    doc["terrain"]["detail"] = detail
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(SceneError, match=re.escape(field)):
        load_scene(path)


def test_a_forests_canopy_is_textured_not_a_flat_block(demo):
    # Straight down from 150 m over a stand south-west of the airfield: its tree voxels' tops
    # (the canopy) carry the forest's code: crowns and gaps, where the plain pattern is one
    # flat colour. The blocks themselves: this near, the scene would draw polygon trees.
    ch = ChannelSpec.symmetric("c", 96, 96, 30.0)
    eye = look_down(-900.0, -3270.0, 150.0)
    blocks = dataclasses.replace(demo, near_trees=None)
    detailed = render_frame(blocks, ch, eye, OPTIONS).rgb.astype(np.float64)
    plain = render_frame(dataclasses.replace(blocks, terrain_land=None), ch, eye, OPTIONS).rgb.astype(np.float64)
    assert np.ptp(plain[30:66, 30:66].mean(axis=2)) < 0.01  # the plain canopy: one colour
    assert detailed[30:66, 30:66].mean(axis=2).std() > 5.0 * plain[30:66, 30:66].mean(axis=2).std() + 0.002
