"""Near trees (scene/forest.py, geometry/trees.py): forest voxels near the eye planted with
polygon trees, the same on every channel and every frame, standing on the surface, and
cross-faded with the voxel blocks so that nothing pops."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from channel_worker.pipeline.background._cast_kernels import _growth
from channel_worker.pipeline.geometry.trees import plant_trees, view_pixel
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene import forest
from channel_worker.pipeline.scene.database import OPACITY_STEPS, TerrainLand
from channel_worker.pipeline.scene.forest import near_tree_ranges, tree_growth, with_near_trees
from channel_worker.pipeline.scene.terrain.build import build_terrain
from channel_worker.pipeline.scene.terrain.features import TREE_PATTERN
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

from ..terrain_fixtures import scene

N = 48
SPACING = 30.0
#: The stand: voxels x 20..23, y 30..33 of a flat field (world x 600..720, y 900..1020).
STAND = (slice(30, 34), slice(20, 24))
#: 320 pixels across 60 degrees: the near-tree range ends at 30 m / (48 px * 3.3 mrad) = 191 m.
CHANNEL = ChannelSpec.symmetric("c", 320, 240, 60.0)


def forest_scene(px: float = 48.0, relief=(0.12, 0.25, 0.06)):
    """A flat field of one relief colour with one stand of trees, with the land's detail (no
    textures) and near trees px pixels wide."""
    mask = np.zeros((N, N), np.uint8)
    mask[STAND] = 1
    colours = np.empty((N + 1, N + 1, 3))
    colours[...] = relief
    terrain = build_terrain(np.zeros((N + 1, N + 1)), colours, spacing_m=SPACING, origin=(0.0, 0.0, 0.0),
                            page_size=16, pattern_mask=mask, patterns=[TREE_PATTERN])
    db = scene(terrain=terrain, sky="#a4c8ea", earth="#5f8a3e")
    land = TerrainLand(grass=-1, field=-1, rock=-1, forest=-1, pad=-1, pad_covered=False,
                       pad_colour=np.zeros(3, np.float32), pads=np.zeros((0, 5)), relief_luminance=0.1,
                       near_tree_px=px)
    return with_near_trees(dataclasses.replace(db, terrain_land=land), px)


@pytest.fixture(scope="module")
def stand():
    return forest_scene()


def planted(db, eye, heading=0.0):
    view = make_view(CHANNEL, Eyepoint(np.asarray(eye, np.float64), heading, -5.0, 0.0))
    out = plant_trees(db, view)
    n = db.instance_model.shape[0]
    return view, out, slice(n, None)


def test_the_cast_and_the_planting_grow_alike():
    d = np.linspace(0.0, 300.0, 601)
    kernel = np.array([_growth.py_func(float(x), 120.0, 200.0) for x in d])
    np.testing.assert_allclose(kernel, tree_growth(d, 120.0, 200.0), atol=1e-12)
    assert kernel[d <= 120.0].max() == 0.0 and kernel[d >= 200.0].min() == 1.0
    assert np.all(np.diff(kernel) >= 0.0)


def test_the_models_face_outwards_and_step_their_opacity(stand):
    near = stand.near_trees
    assert near.models.shape == (2, 3, OPACITY_STEPS)
    for species in range(2):
        for size in range(3):
            for step in range(OPACITY_STEPS):
                model = stand.models[near.models[species, size, step]]
                np.testing.assert_allclose(model.opacity, (step + 1) / OPACITY_STEPS)
                for f in range(model.face_count):
                    pts = model.vertices[model.face_index[model.face_start[f]:model.face_start[f + 1]]]
                    centre = pts.mean(axis=0)
                    normal = model.normal[f]
                    if abs(normal[2]) > 0.999:
                        assert normal[2] < 0.0  # the crown's underside
                    else:
                        assert normal[:2] @ centre[:2] > 0.0  # away from the trunk's axis


def test_no_near_trees_without_a_forest_or_with_zero_pixels():
    plain = forest_scene(px=0.0)
    assert plain.near_trees is None
    view = make_view(CHANNEL, Eyepoint(np.array([660.0, 800.0, 20.0]), 0.0, -5.0, 0.0))
    assert plant_trees(plain, view) is plain


def test_trees_stand_on_forest_voxels_within_the_range_on_the_ground(stand):
    view, out, new = planted(stand, (660.0, 800.0, 20.0))
    start, end = near_tree_ranges(stand.terrain, stand.near_trees, view_pixel(view))
    assert end == pytest.approx(SPACING / (48.0 * view_pixel(view)))
    pos = out.instance_position[new]
    assert pos.shape[0] > 0 and pos.shape[0] % forest.TREES_PER_SIDE ** 2 == 0
    ix, iy = np.floor(pos[:, 0] / SPACING).astype(int), np.floor(pos[:, 1] / SPACING).astype(int)
    assert np.all((ix >= 20) & (ix < 24) & (iy >= 30) & (iy < 34))
    np.testing.assert_allclose(pos[:, 2], -forest.SINK_M)  # flat ground at z = 0
    d = np.sqrt(((ix + 0.5) * SPACING - 660.0) ** 2 + ((iy + 0.5) * SPACING - 800.0) ** 2 + 20.0 ** 2)
    assert d.max() < end
    # Opaque nearer than the cross-fade, fading beyond its start: the step never rises with range.
    models = stand.near_trees.models
    step = np.array([int(np.argwhere(models == m)[0][2]) + 1 for m in out.instance_model[new]])
    assert np.all(step[d < start] == OPACITY_STEPS)
    order = np.argsort(d)
    assert np.all(np.diff(step[order]) <= 0)
    # Feature ids continue the scene's without a gap.
    assert out.instance_face_base[new][0] == stand.feature_count


def test_every_channel_and_every_frame_plants_the_same_trees(stand):
    # The trees depend on the eye and the database alone: a channel looking the other way, or
    # the next frame from the same eye, plants the same ones (no seam between channels).
    _, a, new = planted(stand, (660.0, 800.0, 20.0), heading=0.0)
    _, b, _ = planted(stand, (660.0, 800.0, 20.0), heading=90.0)
    _, c, _ = planted(stand, (660.0, 800.0, 20.0), heading=0.0)
    for x in (b, c):
        np.testing.assert_array_equal(a.instance_model[new], x.instance_model[new])
        np.testing.assert_array_equal(a.instance_position[new], x.instance_position[new])
        np.testing.assert_array_equal(a.instance_rotation[new], x.instance_rotation[new])


def approach(db):
    """Frames flying at the stand's front edge (y = 900) from 320 m to 70 m, 15 m up, 5 m a
    frame: (the distance to the front row's centres (y = 915) at each change, the mean absolute
    change of the linear image from each frame to the next)."""
    ys = np.arange(960.0 - 320.0, 960.0 - 70.0, 5.0)
    frames = [render_frame(db, CHANNEL, Eyepoint(np.array([660.0, y, 15.0]), 0.0, -2.0, 0.0),
                           RenderOptions(samples=4, threads=1)).rgb.astype(np.float64) for y in ys]
    return 915.0 - ys[1:], np.array([np.abs(b - a).mean() for a, b in itertools.pairwise(frames)])


def jump(distance, changes, lo, hi):
    """The largest ratio of one frame's change to the previous frame's, while the front row is
    lo to hi metres away: the stand grows on the screen by a few per cent a frame, a pop
    doubles the change."""
    ratio = changes[1:] / np.maximum(changes[:-1], 1e-12)
    inside = (distance[1:] >= lo) & (distance[1:] <= hi)
    return float(ratio[inside].max())


def test_the_switch_to_trees_does_not_pop(stand, monkeypatch):
    # The range ends at 191 m (the 320-pixel channel). With the cross-fade the change grows
    # smoothly through it (measured: at most 1.5 times the previous frame's); switching the
    # blocks to trees at one range changes the front row at once (2.4 times).
    distance, smooth = approach(stand)
    monkeypatch.setattr(forest, "NEAR_SHARE", 0.995)
    _, hard = approach(stand)
    assert jump(distance, hard, 120.0, 260.0) > 2.0, hard
    assert jump(distance, smooth, 120.0, 260.0) < 1.8, smooth


def test_a_stands_foot_shows_no_rim_of_the_relief_colour():
    # A blue relief under the meadow's green: the land's detail recolours every meadow step,
    # and a step at a stand's foot is part meadow, part stand. It used to take the stand's
    # class for the whole step, which leaves the colour as it is: its meadow share kept the
    # relief's own colour, a rim along the foot (bright teal on the bundled terrain).
    db = dataclasses.replace(forest_scene(px=0.0, relief=(0.05, 0.08, 0.3)), fog=None)
    assert db.near_trees is None  # the blocks themselves, near as they are
    eye = Eyepoint(np.array([660.0, 700.0, 40.0]), 0.0, -8.0, 0.0)
    rgb = render_frame(db, CHANNEL, eye, RenderOptions(samples=4, haze=False)).rgb.astype(np.float64)
    ground = rgb[CHANNEL.height // 2 + 10:]  # below the horizon: meadow and the stand
    blue = ground[..., 2] / np.maximum(ground.sum(axis=-1), 1e-9)
    meadow = rgb[-1, CHANNEL.width // 2]
    # The stand (canopy, trunks) is greener than blue; the meadow is the meadow's class hue.
    assert blue.max() <= meadow[2] / meadow.sum() + 0.02, (blue.max(), meadow)
