"""The scene's atmosphere as an external host (CIGI) sets it: the Environment of a Frame
(services/rig/environment.py) turned into the Database's haze, fog, clouds and sun.

    visibility_m               -> haze (Koschmieder visibility -> the haze's half-haze distance)
    layers, not cloud          -> fog: strata along world z (US 5,535,374's sample planes)
    layers, cloud              -> clouds: one procedural layer (atmosphere.cloud_layer)
    sun                        -> database.sun

What the environment leaves unset keeps the scene's own: no visibility keeps the scene's haze,
no fog layer the scene's fog, no cloud layer the scene's clouds, no sun the scene's sun. Once
the host sends a layer of a kind, that kind is the host's alone: fog layers that hold no
extinction (coverage 0, thickness 0) give clear air, not the scene's fog.

Workers apply the environment every frame, and it rarely changes: EnvironmentCache returns the
same Database object for an unchanged environment, so nothing is rebuilt per frame.
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict

import numpy as np

from services.rig.colour import srgb_to_linear
from services.rig.environment import Environment, WeatherLayer, check_environment

from .atmosphere import KOSCHMIEDER, MAX_FOG_PLANES, Clouds, Fog, Haze, cloud_layer
from .database import Database

# Defaults for what the scene does not state (docs/scene-format.md gives the scene's own).

#: Haze scale height when the scene has no haze, metres (load.DEFAULT_HAZE_SCALE_HEIGHT_M: haze
#: sits mostly in the lowest kilometre or two); its base height is then the earth plane's.
DEFAULT_HAZE_SCALE_HEIGHT_M = 1200.0
#: Haze colour when the scene has no haze: the bundled demo scene's blue-grey, sRGB.
DEFAULT_HAZE_SRGB = (0xC4 / 255, 0xCC / 255, 0xD6 / 255)
#: Fog colour when the scene has no fog: a neutral light grey, sRGB.
DEFAULT_FOG_SRGB = (0xC8 / 255, 0xC8 / 255, 0xC8 / 255)
#: Cloud-top colour when the scene has no clouds: the bundled demo scene's, sRGB.
DEFAULT_CLOUD_SRGB = (0xF4 / 255, 0xF6 / 255, 0xFA / 255)

#: Sample planes per thickness of the thinnest fog layer: linear interpolation between box-
#: averaged planes ramps each boundary over one spacing, so a layer keeps at least half its
#: thickness at full extinction (and its whole optical depth, always).
FOG_PLANES_PER_LAYER = 4
#: Least fog plane spacing, metres: a thinner layer is smeared over this, its depth kept.
MIN_FOG_SPACING_M = 1.0
#: Clear planes beyond the lowest base and the highest top (sigma keeps its end value beyond
#: the last plane, so the ends must be clear air).
FOG_MARGIN_PLANES = 2

#: Half size of the cloud layer's square around the origin when the scene has no terrain, metres.
CLOUD_HALF_EXTENT_M = 20_000.0
#: Cloud node spacing when the scene has no clouds of its own, metres (the bundled scene's).
DEFAULT_CLOUD_CELL_M = 400.0
#: Most cloud cells (the cloud database is coarse; load.py refuses scenes above 4 million): a
#: larger extent gets a coarser cell.
MAX_CLOUD_CELLS = 1_000_000
#: Cloud noise seed of layer id k: CLOUD_SEED_BASE + k, the same clouds on every channel, frame
#: and machine.
CLOUD_SEED_BASE = 0x1C16


#: An environment with every kind a host may set (haze, a fog stratum, a cloud layer, the sun),
#: rendered once before the first frame of a rig that follows a CIGI host (the workers' warm-up,
#: `ig compile`): a scene without an atmosphere of its own would otherwise compile the haze,
#: fog and cloud kernels in the middle of the run, at the host's first weather (half a minute
#: on a cold cache, a second or more from it: frames the swap barrier would time out).
WARM_UP_ENVIRONMENT = Environment(
    visibility_m=20_000.0,
    layers=(WeatherLayer(layer_id=0, base_m=-50.0, thickness_m=100.0, visibility_m=2_000.0, coverage=1.0,
                         cloud=False),
            WeatherLayer(layer_id=1, base_m=1_500.0, thickness_m=400.0, visibility_m=100.0, coverage=0.5,
                         cloud=True)),
    sun=(0.0, 0.6, 0.8))


def with_environment(database: Database, env: Environment) -> Database:
    """The database with the host's environment in place of the scene's atmosphere and sun.

    Pure (nothing is cached here; EnvironmentCache caches).

    Args:
        database: the loaded scene.
        env: the host's environment (world metres, x east, y north, z up).

    Returns:
        A new Database sharing the scene's geometry, or database itself when env sets nothing.

    Raises:
        ValueError: a field cannot be rendered; the message names it ("environment.layers[2]
            .visibility_m: ...").
    """
    check_environment(env)
    if env == Environment():
        return database
    indexed = list(enumerate(env.layers))
    fog_layers = [(i, la) for i, la in indexed if not la.cloud]
    cloud_layers = [(i, la) for i, la in indexed if la.cloud]
    sun = database.sun
    if env.sun is not None:
        sun = np.asarray(env.sun, np.float64)
        sun = sun / np.linalg.norm(sun)  # check_environment: the norm is 1 +- 1e-6
    return dataclasses.replace(
        database, sun=sun,
        haze=database.haze if env.visibility_m is None else _haze(database, env.visibility_m),
        fog=_fog(database, fog_layers) if fog_layers else database.fog,
        clouds=_clouds(database, cloud_layers) if cloud_layers else database.clouds)


def _haze(database: Database, visibility_m: float) -> Haze:
    """The haze of a meteorological visibility: Koschmieder's beta = KOSCHMIEDER / V, and the
    scene's Haze.visibility_m is the half-haze distance ln 2 / beta of a level path at its base
    height. The visibility holds at the haze's base height (the scene's, else the earth plane),
    not at the eye: the result is shared by every frame, wherever the eye is."""
    beta = KOSCHMIEDER / visibility_m  # check_environment: visibility_m > 0
    # The haze stage divides ln 2 by the half distance: beta must be finite, not just V > 0.
    if not math.isfinite(beta):
        raise ValueError(f"environment.visibility_m: {visibility_m} gives extinction {beta} per metre")
    half_m = math.log(2.0) / beta
    scene = database.haze
    if scene is not None:
        return dataclasses.replace(scene, visibility_m=half_m)
    return Haze(visibility_m=half_m, scale_height_m=DEFAULT_HAZE_SCALE_HEIGHT_M,
                base_height_m=float(database.earth_height),
                colour=srgb_to_linear(np.array(DEFAULT_HAZE_SRGB)).astype(np.float32))


def _extinction(index: int, layer: WeatherLayer) -> float:
    """Extinction inside a layer, 1/metres (Koschmieder: KOSCHMIEDER / visibility)."""
    sigma = KOSCHMIEDER / layer.visibility_m  # check_environment: visibility_m > 0
    if not math.isfinite(sigma):
        raise ValueError(f"environment.layers[{index}].visibility_m: {layer.visibility_m} gives "
                         f"extinction {sigma} per metre")
    return sigma


def _top(index: int, layer: WeatherLayer) -> float:
    top = layer.base_m + layer.thickness_m
    if not math.isfinite(top):
        raise ValueError(f"environment.layers[{index}].thickness_m: {layer.thickness_m} puts "
                         f"the top of a layer based at {layer.base_m} m at {top} m")
    return top


def _fog(database: Database, layers: list[tuple[int, WeatherLayer]]) -> Fog | None:
    """The fog strata of the non-cloud layers: along world z, extinction KOSCHMIEDER /
    visibility_m times coverage inside [base_m, base_m + thickness_m], 0 outside, overlapping
    layers adding up. None (clear air) when no layer holds any extinction.

    Each sample plane holds the average of that step function over its own spacing (a box
    filter): interpolated linearly between planes, as the fog stage does, every layer keeps its
    optical depth exactly and its boundaries ramp over one spacing.
    """
    strata = [(_extinction(i, la) * la.coverage, la.base_m, _top(i, la)) for i, la in layers]
    strata = [(s, lo, hi) for s, lo, hi in strata if s > 0.0 and hi > lo]
    if not strata:
        return None
    lowest = min(lo for _, lo, _ in strata)
    highest = max(hi for _, _, hi in strata)
    spacing = max(min(hi - lo for _, lo, hi in strata) / FOG_PLANES_PER_LAYER, MIN_FOG_SPACING_M)
    # Bounded plane count: layers far apart widen the spacing (depths are still kept).
    spacing = max(spacing, (highest - lowest) / (MAX_FOG_PLANES - 1 - 2 * FOG_MARGIN_PLANES))
    if not (math.isfinite(spacing) and spacing > 0.0):
        raise ValueError(f"environment.layers: fog layers spanning {lowest} to {highest} m give "
                         f"a sample spacing of {spacing} m")
    origin_z = lowest - FOG_MARGIN_PLANES * spacing
    count = min(MAX_FOG_PLANES, math.ceil((highest - origin_z) / spacing) + FOG_MARGIN_PLANES + 1)
    z = origin_z + np.arange(count) * spacing
    sigma = np.zeros(count)
    for s, lo, hi in strata:
        overlap = np.minimum(hi, z + 0.5 * spacing) - np.maximum(lo, z - 0.5 * spacing)
        sigma += s * np.clip(overlap, 0.0, spacing) / spacing  # spacing > 0: checked above
    colour = (database.fog.colour if database.fog is not None
              else srgb_to_linear(np.array(DEFAULT_FOG_SRGB)).astype(np.float32))
    return Fog(axis=np.array([0.0, 0.0, 1.0]), origin=np.array([0.0, 0.0, origin_z]),
               spacing_m=spacing, extinction=sigma, colour=colour)


def _clouds(database: Database, layers: list[tuple[int, WeatherLayer]]) -> Clouds | None:
    """The lowest cloud layer that shows (coverage and thickness > 0) as a procedural layer;
    None (clear sky) when none shows.

    The renderer's cloud database holds one slab per cell (Clouds: one base and top per node),
    so only one layer is drawn; the lowest is the one a low-flying aircraft sees, and hides
    the others from below. Its extent is the terrain's (else CLOUD_HALF_EXTENT_M around the
    origin); its seed is CLOUD_SEED_BASE + layer_id, so every channel and frame sees the same
    clouds.
    """
    shown = [(i, la) for i, la in layers if la.coverage > 0.0 and la.thickness_m > 0.0]
    if not shown:
        return None
    index, layer = min(shown, key=lambda item: item[1].base_m)
    _top(index, layer)
    terrain = database.terrain
    if terrain is not None:
        east, north = terrain.extent_m
        x0, y0 = float(terrain.origin[0]), float(terrain.origin[1])
        extent = (x0, y0, x0 + east, y0 + north)
    else:
        h = CLOUD_HALF_EXTENT_M
        extent = (-h, -h, h, h)
    area = (extent[2] - extent[0]) * (extent[3] - extent[1])
    scene = database.clouds
    cell = max(scene.cell_m if scene is not None else DEFAULT_CLOUD_CELL_M,
               math.sqrt(area / MAX_CLOUD_CELLS))
    colour = (scene.colour if scene is not None
              else srgb_to_linear(np.array(DEFAULT_CLOUD_SRGB)).astype(np.float32))
    return cloud_layer(extent_m=extent, cell_m=cell, base_m=layer.base_m,
                       thickness_m=layer.thickness_m, cover=layer.coverage,
                       extinction_per_m=_extinction(index, layer), colour=colour,
                       seed=CLOUD_SEED_BASE + layer.layer_id)


class EnvironmentCache:
    """with_environment for one worker, remembering the last few results: an unchanged
    environment gives the same Database object, so nothing is rebuilt per frame, and a host
    switching between a few environments (a weather toggle) rebuilds none of them.

    Keyed on the Environment (a frozen, hashable dataclass) for one database at a time, held by
    reference (not id(): a freed database's id may be reused); another database starts afresh.
    Not thread-safe: one worker's render loop calls it.

    Args:
        size: environments remembered (>= 1).
    """

    def __init__(self, size: int = 4) -> None:
        if size < 1:
            raise ValueError(f"size: {size} is not >= 1")
        self.size = size
        self._database: Database | None = None
        self._results: OrderedDict[Environment, Database] = OrderedDict()

    def get(self, database: Database, env: Environment) -> Database:
        """with_environment(database, env), built once per environment.

        Raises:
            ValueError: as with_environment (a bad environment is not remembered).
        """
        if database is not self._database:
            self._database, self._results = database, OrderedDict()
        result = self._results.get(env)
        if result is None:
            result = with_environment(database, env)
            self._results[env] = result
            if len(self._results) > self.size:
                self._results.popitem(last=False)
        else:
            self._results.move_to_end(env)
        return result
