"""Scenes built in code for the query tests: terrain from node grids (single_level_database),
polygons from scene documents."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from channel_worker.pipeline.scene.load import parse_scene
from channel_worker.pipeline.scene.terrain.database import Pattern
from channel_worker.testing.terrain_reference import single_level_database

SPACING = 10.0
TREE = Pattern(name="tree", top_m=np.array([3.0, 14.0], np.float32),
               rgb=np.array([[100, 70, 40], [20, 90, 30]], np.uint8))


def quad(x0: float, y0: float, x1: float, y1: float, z: float, colour: str = "#808080",
         opacity: float = 1.0) -> dict:
    """A horizontal rectangle facing up."""
    v = [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]
    return {"vertices": v, "faces": [{"indices": [0, 1, 2, 3], "colour": colour, "opacity": opacity}]}


def wall(x: float, y0: float, y1: float, z0: float, z1: float, colour: str = "#ff0000",
         opacity: float = 1.0) -> dict:
    """A vertical rectangle in the plane x = const, facing -x."""
    v = [[x, y0, z0], [x, y0, z1], [x, y1, z1], [x, y1, z0]]
    return {"vertices": v, "faces": [{"indices": [0, 1, 2, 3], "colour": colour, "opacity": opacity}]}


def scene(models: dict | None = None, heights=None, *, origin=(0.0, 0.0, 0.0), offset=(0.0, 0.0, 0.0),
          pattern_mask=None, margin: float = 1.0):
    """A Database: the models each placed once at offset, over terrain whose nodes are heights
    ((ny + 1, nx + 1), row 0 south; None: no terrain) at origin + offset."""
    models = models or {}
    doc = {"format": "ig-scene/1", "sky": {"colour": "#0000ff"}, "earth": {"colour": "#00ff00", "height_m": 0.0},
           "lighting": {"ambient": 1.0}, "models": models,
           "instances": [{"model": name, "position": list(offset)} for name in models]}
    db = parse_scene(doc, source="<query test>")
    if heights is None:
        return db
    h = np.asarray(heights, np.float64)
    colours = np.zeros(h.shape + (3,), np.uint8)
    colours[..., 1] = 128
    terrain = single_level_database(h, colours, SPACING, np.add(origin, offset), page_size=4,
                                    pattern_mask=pattern_mask, patterns=(TREE,))
    return dataclasses.replace(db, terrain=terrain, terrain_margin_m=margin)


def nodes(f, nx: int = 12, ny: int = 9) -> np.ndarray:
    """Node heights f(x, y) on the test grid (metres from the terrain origin)."""
    y, x = np.mgrid[0:ny + 1, 0:nx + 1] * SPACING
    return f(x, y)


@pytest.fixture(scope="session")
def bundled():
    """The bundled scene (terrain and airfield), loaded once."""
    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    return load_scene(demo_scene_path())
