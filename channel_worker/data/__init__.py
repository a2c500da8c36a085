"""Data shipped with the channel worker: the bundled airfield scene and its generator.

The bundled scenes can be named instead of given by path (`ig render --scene airfield`,
`ig demo --scene airfield`): SCENES is the one table of their names, which the commands'
help and docs/scene-format.md read.
"""

from __future__ import annotations

from pathlib import Path

_HERE = Path(__file__).resolve().parent

#: Bundled scene name -> (file in this folder, what it shows). The first is the default of
#: `ig render` and `ig demo`: the world the demo flies.
SCENES: dict[str, tuple[str, str]] = {
    "airfield-terrain": ("airfield_terrain.json", "the demo's world: the airfield on the bundled terrain, with "
                                                   "haze, fog and clouds"),
    "airfield": ("airfield.json", "the airfield alone on a flat earth (renders in a fraction of the time)"),
}
DEFAULT_SCENE = "airfield-terrain"


def scene_names_help() -> str:
    """The bundled scenes for a command's help: "NAME (what it shows); ..."."""
    return "; ".join(f"{name} ({what})" for name, (_, what) in SCENES.items())


def resolve_scene(text: str | None, *, setting: str = "--scene") -> Path:
    """The scene file of a --scene value: a bundled scene's name (SCENES), else a path to a
    file (whose content the loader checks); None is DEFAULT_SCENE. A file whose path is a
    bundled name is reached as ./NAME.

    Raises:
        ValueError: neither a bundled name nor an existing file, naming setting and the value.
    """
    path = Path(_bundled(DEFAULT_SCENE if text is None else text))
    if not path.exists():
        raise ValueError(f"{setting}: {text!r} is neither a bundled scene ({', '.join(SCENES)}) nor a file")
    return path


def bundled_or_path(text: str | None) -> str | None:
    """A --scene value with a bundled scene's name (SCENES) turned into its file; a path, or
    None (the command's default), as given. For the commands whose default is not
    DEFAULT_SCENE (`ig worker`, `ig compile`: the rig file's [scene], else the flat airfield)."""
    return None if text is None else _bundled(text)


def _bundled(text: str) -> str:
    """A bundled scene's file for its name, else text as given."""
    return str(_HERE / SCENES[text][0]) if text in SCENES else text
