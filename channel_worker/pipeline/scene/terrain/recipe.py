"""A terrain recipe: source, colour, placement and shaping options -> a TerrainDatabase.

`ig terrain build` and the bundled terrain (bundled.py) both describe a build as a recipe dict,
stored in the database's info so a database says how it was made:

=============  ==================================================================  ============
key            meaning                                                             default
=============  ==================================================================  ============
source         elevation URL (sources.py)                                          required
colour         colour URL (sources.py)                                             relief:gist_earth
spacing_m      level-0 voxel width, metres                                         source's cell
origin         [lat deg, lon deg, h m]: geodetic position of world (0, 0, 0)       grid centre, h 0
flatten        [[x0, y0, x1, y1, z, blend_m], ...] world metres (features.py)      []
trees          {"density": 0..1, "seed": int, "max_slope_deg": deg} or null        null
page_size      voxels per page side                                                128
prune          [dz_m, drgb] tolerance to leave out reproducible pages, or null     null
=============  ==================================================================  ============
"""

from __future__ import annotations

from typing import Any

from .build import build_terrain
from .database import DEFAULT_PAGE_SIZE, TerrainDatabase, TerrainError
from .features import BUILDING_PATTERN, TREE_PATTERN, check_pad, flatten, tree_mask
from .placement import place
from .sources import DEFAULT_COLOUR, colour_nodes, open_elevation

#: Pattern indices of every recipe build: 1 tree, 2 building.
PATTERNS = (TREE_PATTERN, BUILDING_PATTERN)
_KEYS = {"source", "colour", "spacing_m", "origin", "flatten", "trees", "page_size", "prune"}
_TREE_KEYS = {"density", "seed", "max_slope_deg"}


def build_from_recipe(recipe: dict[str, Any]) -> TerrainDatabase:
    """Build a terrain database from a recipe (module docstring).

    World frame: x east, y north, z up, metres; world (0, 0, 0) is the geodetic origin and
    origin[2] of the database is 0 (heights are world z, within a few km of 0).

    Raises:
        TerrainError: an unknown key or a bad value, naming it.
    """
    unknown = recipe.keys() - _KEYS
    if unknown:
        raise TerrainError(f"recipe: unknown key(s) {', '.join(sorted(unknown))}")
    if "source" not in recipe:
        raise TerrainError("recipe: source is missing")
    pads = [check_pad(p, "flatten") for p in recipe.get("flatten") or ()]
    trees = recipe.get("trees")
    if trees is not None and (not isinstance(trees, dict) or trees.keys() - _TREE_KEYS or "density" not in trees):
        raise TerrainError(f"trees: {trees!r} is not {{density, seed, max_slope_deg}}")

    grid = open_elevation(recipe["source"])
    origin = recipe.get("origin")
    placed = place(grid, spacing_m=recipe.get("spacing_m"), origin=tuple(origin) if origin is not None else None)
    x, y = placed.node_xy()
    heights = flatten(placed.heights, x, y, pads)
    colours = colour_nodes(recipe.get("colour") or DEFAULT_COLOUR, heights, spacing_m=placed.spacing_m)
    mask = None
    if trees is not None:
        mask = tree_mask(heights, x, y, spacing_m=placed.spacing_m, density=float(trees["density"]),
                         seed=int(trees.get("seed", 0)), max_slope_deg=float(trees.get("max_slope_deg", 35.0)),
                         pads=pads, pattern=1)
    info = {
        "source": grid.info.get("source", recipe["source"]),
        "licence": grid.info.get("licence", ""),
        "attribution": grid.info.get("attribution", ""),
        "placement": {k: v for k, v in placed.info.items() if k not in ("source", "licence", "attribution")},
        "recipe": {**recipe, "spacing_m": placed.spacing_m,
                   "origin": list(placed.geodetic_origin) if placed.geodetic_origin else None},
    }
    return build_terrain(heights, colours, spacing_m=placed.spacing_m, origin=(placed.x0, placed.y0, 0.0),
                         page_size=int(recipe.get("page_size") or DEFAULT_PAGE_SIZE),
                         prune_tolerance=tuple(recipe["prune"]) if recipe.get("prune") else None,
                         pattern_mask=mask, patterns=PATTERNS, info=info)
