"""Cloud edges (clouds.py, _cloud_kernels.py, _cloud_over_kernels.py): the coarse cloud image
(JP H07-76990: an eighth of the pixel resolution) is sampled finer in the quads a cloud's edge
crosses, so an edge against the sky is as smooth as the pixels, while inside the cloud the
image stays the coarse one. Measured on the edge profile of a cloud bank whose top rises
straight across the view: the row where its opacity crosses a half, column by column."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from channel_worker.pipeline.background import clouds as clouds_module
from channel_worker.pipeline.background._groups import CLOUD_CHANNELS
from channel_worker.pipeline.background.air import air_params
from channel_worker.pipeline.background.clouds import REFINE, scan_clouds, seam_quads
from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.atmosphere import Clouds
from channel_worker.pipeline.scene.database import Database
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

from ..terrain_fixtures import scene

W, H = 256, 192
CHANNEL = ChannelSpec.symmetric("c", W, H, 60.0)
#: Level, looking north from 800 m: below the bank's top, so its top edge lies against the sky.
EYE = Eyepoint.of(0.0, 0.0, 800.0, 0.0, 0.0, 0.0)
#: The bank's near face, metres north of the eye, and its node spacing (the bundled scene's).
FACE_Y, CELL = 2000.0, 400.0
#: The bank's top: TOP_M above x = 0, rising TOP_SLOPE metres per metre east.
TOP_M, TOP_SLOPE = 1000.0, 0.15


def bank() -> Database:
    """A white cloud bank from FACE_Y northwards (its grid starts there, so the face is sharp),
    its base on the ground, opaque a few tens of metres in; black sky and earth behind it."""
    x = np.arange(-3200.0, 3200.0 + CELL, CELL)
    y = np.arange(FACE_Y, 6000.0 + CELL, CELL)
    xx = np.broadcast_to(x, (y.size, x.size))
    top = (TOP_M + TOP_SLOPE * xx).astype(np.float32)
    layer = Clouds(origin=np.array([x[0], FACE_Y]), cell_m=CELL, base_m=np.zeros_like(top),
                   top_m=top, density=np.full_like(top, 0.05), colour=np.ones(3, np.float32))
    return dataclasses.replace(scene(sky="#000000", earth="#000000"), clouds=layer)


def render(db: Database) -> np.ndarray:
    """(H, W, 3) linear RGB of the bank, one sample at each pixel's centre."""
    return render_frame(db, CHANNEL, EYE, RenderOptions(samples="centre")).rgb


def edge_rows(rgb: np.ndarray) -> np.ndarray:
    """Per column, the row (pixels from the top, linear between pixel centres) where the green
    first reaches 0.5 going down: where the white cloud's opacity over black crosses a half."""
    green = rgb[:, :, 1]
    rows = np.empty(green.shape[1])
    for x in range(green.shape[1]):
        i = int(np.argmax(green[:, x] >= 0.5))
        assert i > 0, x  # sky above the edge, cloud below
        lo, hi = green[i - 1, x], green[i, x]
        rows[x] = i - 1 + (0.5 - lo) / (hi - lo)  # guard: hi >= 0.5 > lo
    return rows


def steps(rows: np.ndarray) -> float:
    """The largest distance (pixels) of the edge from a smooth (quadratic) fit: the face's top
    is a straight line in the world, so on the screen too, and what is left is the steps."""
    x = np.arange(rows.size)
    return float(np.abs(rows - np.polyval(np.polyfit(x, rows, 2), x)).max())


def test_a_cloud_top_rising_across_the_sky_has_no_steps(monkeypatch):
    rows = edge_rows(render(bank()))
    assert rows.max() - rows.min() > 32  # the edge crosses four coarse rows and more
    # Measured: 0.35 px (rms 0.17), the half-pixel aliasing of one sample at each pixel's
    # centre on a sharp edge. The coarse image alone gave 3.4 px (rms 1.8: 8-pixel steps),
    # the fine samples with the slab taken at the middle of each cell crossing 1.2 px (a step
    # where the rays cross from one 400 m cell into the next).
    assert steps(rows) < 0.75
    # The measure sees the coarse image's 8-pixel steps: with no quad refined they are back.
    monkeypatch.setattr(clouds_module, "REFINE_CONTRAST", math.inf)
    assert steps(edge_rows(render(bank()))) > 2.5


def test_inside_the_cloud_the_image_is_the_coarse_one(monkeypatch):
    fine = render(bank())
    monkeypatch.setattr(clouds_module, "REFINE_CONTRAST", math.inf)
    coarse = render(bank())
    # The bank's edges: its top against the sky, its foot against the earth in front of it.
    top = edge_rows(fine)
    foot = (H - 1) - edge_rows(fine[::-1])
    assert (foot - top).min() > 64
    changed_y, changed_x = np.nonzero(np.abs(fine - coarse).max(axis=2) > 1e-3)
    assert changed_y.size > 0
    # Only within a coarse texel or two (8 pixels each) of an edge: JP H07-76990's blurry
    # interior is kept.
    near = np.minimum(np.abs(changed_y - top[changed_x]), np.abs(changed_y - foot[changed_x]))
    assert near.max() < 2 * 8


def test_the_fine_samples_stay_on_the_edge_and_meet_the_coarse_texels():
    db = bank()
    view = make_view(CHANNEL, EYE)
    image = scan_clouds(db, view, air_params(db, view, 8))
    ncols = image.quad.shape[0]
    refined = np.argwhere(image.quad >= 0)
    assert 0 < len(refined) <= 4 * ncols  # two edges (top, foot), each in one or two quads a column
    # A refined quad's corner samples are its corner texels' rays, whatever other rays a walk
    # carries: the same opacity and entry range, so the fine and coarse images agree there.
    for c, r in refined:
        t = image.quad[c, r]
        for a, b in ((0, 0), (REFINE, 0), (0, REFINE), (REFINE, REFINE)):
            texel = image.texels[(c + a // REFINE) % ncols, r + b // REFINE]
            np.testing.assert_array_equal(image.fine[t, a, b, 3:], texel[3:])


#: A quad side's fine samples between its corners (the corners are the coarse texels' rays).
INNER = slice(1, REFINE)


def _image(ncols: int = 6, nrows: int = 5) -> np.ndarray:
    texels = np.zeros((ncols, nrows, CLOUD_CHANNELS), np.float32)
    texels[:, :, 4] = np.inf
    return texels


@pytest.mark.parametrize(("side", "neighbour"), [((0, INNER), (1, 2)), ((REFINE, INNER), (3, 2)),
                                                 ((INNER, 0), (2, 1)), ((INNER, REFINE), (2, 3))])
def test_a_quad_the_edge_reaches_is_refined_next(side, neighbour):
    # Quad (2, 2) is refined; its fine samples find cloud along one side that the coarse
    # texels (clear) do not show: the quad across that side is next.
    texels = _image()
    quad = np.full(texels.shape[:2], -1, np.int32)
    quad[2, 2] = 0
    cols, rows = np.array([2]), np.array([2])
    fine = np.zeros((1, REFINE + 1, REFINE + 1, CLOUD_CHANNELS), np.float32)
    fine[0][side + (3,)] = 0.5
    found = seam_quads(texels, False, quad, cols, rows, fine)
    assert [tuple(map(int, q)) for q in zip(*found, strict=True)] == [neighbour]
    # Within REFINE_CONTRAST of the coarse blend, or already refined: nothing more.
    fine[0][side + (3,)] = 0.5 * clouds_module.REFINE_CONTRAST
    assert seam_quads(texels, False, quad, cols, rows, fine)[0].size == 0
    fine[0][side + (3,)] = 0.5
    quad[neighbour] = 1
    assert seam_quads(texels, False, quad, cols, rows, fine)[0].size == 0


def test_the_seam_search_wraps_round_a_full_circle_and_stops_at_a_clamped_border():
    texels = _image()
    quad = np.full(texels.shape[:2], -1, np.int32)
    quad[0, 2] = 0
    fine = np.zeros((1, REFINE + 1, REFINE + 1, CLOUD_CHANNELS), np.float32)
    fine[0, 0, INNER, 3] = 0.5  # the left side
    cols, rows = np.array([0]), np.array([2])
    # Wrapping, the quad left of column 0 is the last column's (it closes the circle).
    found = seam_quads(texels, True, quad, cols, rows, fine)
    assert [tuple(map(int, q)) for q in zip(*found, strict=True)] == [(5, 2)]
    # Clamped, there is none.
    assert seam_quads(texels, False, quad, cols, rows, fine)[0].size == 0
