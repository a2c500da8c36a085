"""Textured and Gouraud-shaded faces as rendered (shade/texturing.py): continuous across shared
edges, the same at any screen rotation, anti-aliased against a 64-sample reference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.load import parse_scene
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions


def scene(models: dict, instances: list, *, codes: dict | None = None, sun_elevation: float = 35.0) -> Database:
    return parse_scene({
        "format": "ig-scene/1", "sky": {"colour": "#8090a0"}, "earth": {"colour": "#405030"},
        "lighting": {"sun_heading_deg": 120.0, "sun_elevation_deg": sun_elevation, "ambient": 0.3},
        "textures": {"brick": {"bundled": "brick"}, "chk": {"procedural": "checker", "size": 64},
                     "noise": {"procedural": "noise", "size": 64, "seed": 2}},
        "texture_codes": codes if codes is not None else {
            "wall": {"textures": ["brick", "noise"], "scale_m": [3.0, 3.0], "detail_scale_m": [30.0, 30.0],
                     "amplitudes": [0.5, 0.0], "modulation": "colour"},
            "chk": {"textures": ["chk"], "scale_m": [4.0, 4.0], "intensity": 0.9}},
        "models": models, "instances": instances}, source="<test>")


def ground_faces(half: float, split: bool, code: str = "wall") -> dict:
    h = half
    if not split:
        return {"vertices": [[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]],
                "faces": [{"indices": [0, 1, 2, 3], "colour": "#a08070", "texture": code}]}
    v = [[-h, -h, 0], [0.3, -h, 0], [h, -h, 0], [h, h, 0], [0.3, h, 0], [-h, h, 0]]
    return {"vertices": v, "faces": [{"indices": [0, 1, 4, 5], "colour": "#a08070", "texture": code},
                                     {"indices": [1, 2, 3, 4], "colour": "#a08070", "texture": code}]}


def render(db: Database, eye: Eyepoint, size: tuple[int, int] = (160, 120), **options) -> np.ndarray:
    channel = ChannelSpec.symmetric("c", size[0], size[1], 60.0)
    opts = RenderOptions(with_range=False, **options)
    return render_frame(db, channel, eye, opts).rgb.astype(np.float64)


@pytest.mark.parametrize("coverage", ["samples", "area"])
def test_texture_runs_on_across_a_shared_edge(coverage):
    """Two coplanar faces sharing an edge, with one texture code, look like one face. The
    texture coordinates agree exactly; a pixel inside one face is shaded once at its centre
    and a pixel the shared edge crosses per sample (or, with coverage "area", as its two
    sides' samples weighed by area), all at a pixel's footprint, so the two pictures differ
    only by the filtered texture's variation inside a pixel along the edge."""
    eye = Eyepoint.of(0.0, -40.0, 6.0, 0.0, -12.0, 0.0)
    one = render(scene({"g": ground_faces(60.0, False)}, [{"model": "g", "position": [0, 0, 0]}]), eye,
                 coverage=coverage)
    two = render(scene({"g": ground_faces(60.0, True)}, [{"model": "g", "position": [0, 0, 0]}]), eye,
                 coverage=coverage)
    diff = np.abs(one - two)
    assert one[60:].std() > 0.01  # the texture is there to be compared
    # Measured: at most 0.0017 (samples), 0.024 (area: far pixels spanning many checks).
    assert diff.max() < (0.005 if coverage == "samples" else 0.05)
    assert diff.mean() < 2e-5
    assert (diff.max(axis=2) > 1e-4).sum() <= 60  # only along the shared edge


def smooth_roof() -> dict:
    v = [[-10, -10, 0], [10, -10, 0], [10, 0, 6], [-10, 0, 6], [10, 10, 0], [-10, 10, 0]]
    return {"vertices": v, "smooth": {"crease_deg": 80.0},
            "faces": [{"indices": [0, 1, 2, 3], "colour": "#c0c0c0"},
                      {"indices": [3, 2, 4, 5], "colour": "#c0c0c0"}]}


@pytest.mark.parametrize("samples", ["centre", "rgss4"])
def test_gouraud_shading_turns_with_the_screen(samples):
    """ARL Systems Note 77: interpolating a quadrilateral's shading along scan lines changes
    as the screen turns. Ours, linear over triangles in the face, turns with the screen: the
    picture at roll 90 is the picture at roll 0 turned a quarter."""
    db = scene({"r": smooth_roof()}, [{"model": "r", "position": [0, 0, 0]}], sun_elevation=10.0)
    up = render(db, Eyepoint.of(0.0, 0.0, 40.0, 0.0, -90.0, 0.0), (128, 128), samples=samples)
    turned = render(db, Eyepoint.of(0.0, 0.0, 40.0, 0.0, -90.0, 90.0), (128, 128), samples=samples)
    assert up.std() > 0.02
    diff = np.abs(np.rot90(up, k=1) - turned)
    rotated = np.abs(np.rot90(up, k=-1) - turned)
    best = min(diff.mean(), rotated.mean())
    assert best < 2e-4
    assert min(np.quantile(diff, 0.99), np.quantile(rotated, 0.99)) < 1e-3


def test_fused_pixels_equal_the_sample_store_resolved():
    """The default fused path and the sample store resolved with the box filter shade
    textured and Gouraud faces alike."""
    db = scene({"g": ground_faces(60.0, False), "r": smooth_roof()},
               [{"model": "g", "position": [0, 0, 0]}, {"model": "r", "position": [0, 15, 0]}])
    channel = ChannelSpec.symmetric("c", 160, 120, 60.0)
    eye = Eyepoint.of(3.0, -30.0, 8.0, 0.0, -10.0, 7.0)
    opts = RenderOptions(with_range=False)
    fused = render_frame(db, channel, eye, opts).rgb
    stored = render_frame(db, channel, eye, opts, trace={}).rgb
    assert np.abs(fused - stored).max() < 1e-5


GRAZING = Eyepoint.of(0.0, -200.0, 3.0, 0.0, -4.0, 0.0)


def reference(db: Database) -> np.ndarray:
    """64 samples a pixel: one at each pixel centre of a raster eight times as fine, box
    filtered 8 x 8. A textured face is shaded once per pixel at that pixel's footprint (1/8
    of ours), so the fade keeps the texture wherever a pixel could resolve it."""
    fine = render(db, GRAZING, (1280, 960), samples="centre", texture_filter="fade")
    return fine.reshape(120, 8, 160, 8, 3).mean(axis=(1, 3))


@pytest.fixture(scope="module")
def grazing():
    db = scene({"g": ground_faces(2000.0, False, "chk")}, [{"model": "g", "position": [0, 0, 0]}])
    return db, reference(db)


def ground_rmse(image: np.ndarray, ref: np.ndarray) -> float:
    rows = slice(51, 120)  # below the horizon (row 50.3: pitch -4 on a 60 x 47 degree view)
    return float(np.sqrt(np.mean((image[rows] - ref[rows]) ** 2)))


#: RMSE bounds against the 64-sample reference on the grazing checkerboard, rows below the
#: horizon (measured 2026-11-27: fade 0.045, mipmap and both 0.011, the same at 1, 4 and 16
#: samples: inside one face a textured pixel is shaded once, at its footprint, whatever the
#: samples; bounds about 25 % above; bench/bench_texture.py reports the figures). The fade's
#: error is contrast it takes away near the eye, where the reference still resolves the
#: checks: the patent's fade is the cheapest filter, not the most faithful.
BOUNDS = {("fade", "centre"): 0.056, ("fade", "rgss4"): 0.056, ("fade", "d3d16"): 0.056,
          ("mipmap", "centre"): 0.015, ("mipmap", "rgss4"): 0.015, ("mipmap", "d3d16"): 0.015,
          ("both", "centre"): 0.015, ("both", "rgss4"): 0.015, ("both", "d3d16"): 0.015}


@pytest.mark.parametrize(("texture_filter", "samples"), sorted(BOUNDS))
def test_grazing_texture_is_anti_aliased(grazing, texture_filter, samples):
    """A textured plane seen at a grazing angle stays within a stated RMSE of the 64-sample
    reference at 1, 4 and 16 samples, for each filter."""
    db, ref = grazing
    err = ground_rmse(render(db, GRAZING, samples=samples, texture_filter=texture_filter), ref)
    assert err <= BOUNDS[(texture_filter, samples)]


def test_without_fading_the_distant_plane_aliases(grazing):
    """Where the checks are smaller than a pixel (the rows near the horizon), point sampling
    without the fade aliases (RMSE 0.07 against the reference, measured); fading leaves
    (nearly) nothing to alias."""
    db, ref = grazing
    raw = dataclasses.replace(db, textures=db.textures._replace(finest=np.zeros_like(db.textures.finest)))
    far = slice(51, 90)
    aliased = render(raw, GRAZING, samples="centre", texture_filter="fade")[far]
    faded = render(db, GRAZING, samples="centre", texture_filter="fade")[far]
    rmse_aliased = float(np.sqrt(np.mean((aliased - ref[far]) ** 2)))
    rmse_faded = float(np.sqrt(np.mean((faded - ref[far]) ** 2)))
    assert rmse_aliased > 0.04
    assert rmse_faded < 0.4 * rmse_aliased
