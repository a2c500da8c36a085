"""The bundled demo terrain: matplotlib's Jacksboro DEM around the bundled airfield.

Built from BUNDLED_RECIPE on first use into a cache directory ($IG_CACHE_DIR, else
~/.cache/ig-rig) under a name keyed by a hash of the recipe, the package version and the
builder's source, so a changed recipe or builder rebuilds; the build goes to a temporary
directory beside it and is renamed into place, so a reader never sees a half-written database
and two processes building at once both end with the same complete one.

The airfield (channel_worker/data/airfield.json: runway 36 along world x = 0 from y = -1000 to
+1000, taxiway and buildings up to x = +400) sits on a pad flattened to world z = 0 over
x -450..550, y -1300..1300 with a 400 m blend. Its geodetic origin was chosen once, offline:
every position on a 100 m lattice within 3 km of the flattest valley floor found on a coarse
pass over the whole DEM was tried as world (0, 0), keeping the one whose placed 1 x 2.6 km pad
has the smallest height range (48.5 m, standard deviation 10 m) among those where nothing in
the climb-out corridor (x -1500..600, y -1300..2500) rises more than 40 m above the pad (the
bundled flight climbs to 67 m). Its height, 349.2 m, is the mean DEM height over the pad, so
that the pad maps to world z = 0 with as much cut as fill.
"""

from __future__ import annotations

import hashlib
import json
import os
from importlib import metadata
from pathlib import Path

from .database import FORMAT
from .store import build_cached, load_terrain

#: Lat, lon (degrees, WGS-84) and height (metres, the DEM's datum) of world (0, 0, 0).
AIRFIELD_ORIGIN = (36.6089, -84.1708, 349.2)

BUNDLED_RECIPE = {
    "source": "mpl:jacksboro",
    "colour": "relief:gist_earth",
    "spacing_m": 30.0,
    "origin": list(AIRFIELD_ORIGIN),
    "flatten": [[-450.0, -1300.0, 550.0, 1300.0, 0.0, 400.0]],
    "trees": {"density": 0.25, "seed": 2, "max_slope_deg": 35.0},
    "page_size": 128,
    "prune": None,
}

#: The modules whose source is part of the cache key (a change in how a database is built
#: rebuilds the cached one).
_BUILDER_MODULES = ("build.py", "recipe.py", "placement.py", "features.py", "sources.py", "grid.py",
                    "_mpl_dem.py", "_relief.py", "store.py", "database.py")


def cache_dir() -> Path:
    """$IG_CACHE_DIR if set, else ~/.cache/ig-rig."""
    env = os.environ.get("IG_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "ig-rig"


def recipe_key(recipe: dict) -> str:
    """16 hex digits of the hash of a recipe, the package version and the builder's source."""
    digest = hashlib.sha256()
    digest.update(json.dumps(recipe, sort_keys=True).encode())
    digest.update(FORMAT.encode())
    try:
        digest.update(metadata.version("ig-rig").encode())
    except metadata.PackageNotFoundError:  # running from a source tree that is not installed
        digest.update(b"uninstalled")
    here = Path(__file__).parent
    for name in _BUILDER_MODULES:
        digest.update((here / name).read_bytes())
    return digest.hexdigest()[:16]


def bundled_terrain_path() -> Path:
    """The bundled terrain's directory, built on first use (a few seconds).

    Returns:
        ``<cache>/jacksboro-<key>.igt``, a complete database (load it with store.load_terrain).
    """
    from .recipe import build_from_recipe

    return build_cached(cache_dir() / f"jacksboro-{recipe_key(BUNDLED_RECIPE)}.igt",
                        lambda: build_from_recipe(BUNDLED_RECIPE))


def load_bundled_terrain(*, mmap: bool = True):
    """The bundled terrain, loaded (built first if needed)."""
    return load_terrain(bundled_terrain_path(), mmap=mmap)
