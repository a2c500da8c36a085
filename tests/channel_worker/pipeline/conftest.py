"""Small scenes built in code for the pipeline tests."""

from __future__ import annotations

import numpy as np
import pytest

from channel_worker.pipeline.binning.binning import bin_features
from channel_worker.pipeline.binning.edges import setup_edges
from channel_worker.pipeline.contract import (
    Background,
    SampleBuffer,
    ScreenPolygons,
    View,
    no_background,
)
from channel_worker.pipeline.geometry.view import frame_constants
from channel_worker.pipeline.scene.load import parse_scene
from channel_worker.pipeline.visibility.visibility import sample_store
from services.rig.options import RenderOptions


def box_model(w: float, d: float, h: float, colour: str = "#a0a0a0") -> dict:
    """A box with its base centred on the model origin, faces CCW from outside."""
    x, y = w / 2, d / 2
    v = [[-x, -y, 0], [x, -y, 0], [x, y, 0], [-x, y, 0], [-x, -y, h], [x, -y, h], [x, y, h], [-x, y, h]]
    faces = [[3, 2, 1, 0], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    return {"vertices": v, "faces": [{"indices": f, "colour": colour} for f in faces]}


def scene_doc(models: dict, instances: list, *, sky: str = "#0000ff", earth: str = "#00ff00",
              earth_height: float = 0.0) -> dict:
    return {
        "format": "ig-scene/1",
        "sky": {"colour": sky},
        "earth": {"colour": earth, "height_m": earth_height},
        "lighting": {"ambient": 1.0},
        "models": models,
        "instances": instances,
    }


@pytest.fixture
def make_scene():
    """Build a Database from models and instances (flat lighting, pure colours)."""
    def build(models: dict, instances: list, **kw):
        return parse_scene(scene_doc(models, instances, **kw), source="<test>")
    return build


@pytest.fixture
def box_model_factory():
    return box_model


def linear(hex_colour: str) -> np.ndarray:
    srgb = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def screen_polygons(polys: list, planes: list | None = None, opacity: list | None = None,
                    layer: list | None = None) -> ScreenPolygons:
    """ScreenPolygons from fixed-point (1/SUBPIXEL px) vertex lists, wound as project.py winds
    them (negative doubled area); planes default to 1/z = 0.5 everywhere."""
    fixed, start = [], [0]
    for v in polys:
        v = np.asarray(v, np.int64)
        area2 = np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
        assert area2 != 0
        fixed.append(v if area2 < 0 else v[::-1])
        start.append(start[-1] + len(v))
    n = len(polys)
    return ScreenPolygons(
        fixed=np.concatenate(fixed) if n else np.zeros((0, 2), np.int64),
        start=np.array(start, np.int64),
        inv_z=np.array(planes if planes else [(0.0, 0.0, 0.5)] * n, np.float64).reshape(n, 3),
        colour=np.zeros((n, 3), np.float32),
        opacity=np.array(opacity if opacity else [1.0] * n, np.float32),
        feature_id=np.arange(n, dtype=np.int32),
        layer=np.array(layer if layer else [0] * n, np.int16))


class Stored:
    """A stage's sample store, with the counters it reported as .stats."""

    def __init__(self, buffer: SampleBuffer, stats: dict) -> None:
        self.buffer, self.stats = buffer, stats

    def __getattr__(self, name: str):
        return getattr(self.buffer, name)


#: The backdrop of store(): only the horizon matters to the store (colours are resolve's).
_BACKDROP = parse_scene(scene_doc({}, []), source="<store>")


def store(screen: ScreenPolygons, view: View, samples: str | int | np.ndarray, *,
          max_translucent: int = 4, subarea: int = 16, with_range: bool = True,
          background: Background | None = None) -> Stored:
    """The visibility stage's sample store of screen polygons seen in view (edges and bins
    built here), and its counters. samples: a pattern, or (S, 2) sample positions of any kind
    (pixels from the pixel's top-left, on the 1/SUBPIXEL grid)."""
    raw = isinstance(samples, np.ndarray)
    options = RenderOptions(samples="rgss4" if raw else samples, max_translucent=max_translucent,
                            subarea=subarea, with_range=with_range)
    offsets = samples if raw else options.sample_offsets()
    frame = frame_constants(view, _BACKDROP, offsets)
    edges = setup_edges(screen, view.width, view.height)
    bins = bin_features(edges, screen.start, view.width, view.height, subarea)
    counters: dict[str, int] = {}
    buf = sample_store(screen, edges, bins, frame, background or no_background(), options, counters)
    return Stored(buf, counters)
