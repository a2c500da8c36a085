"""Build the bundled airfield scene, channel_worker/data/airfield.json (docs/scene-format.md).

    python -m channel_worker.data.build_airfield            # rewrite airfield.json
    python -m channel_worker.data.build_airfield --check    # exit 1 if it is out of date

The scene is laid out for the bundled flight (host_sim/flight.py) and the default rig, whose
channel seams are at +-30 degrees of azimuth from the nose and whose outer edges are at
+-90 degrees. The airfield is at the world origin:

- runway 36/18, 2000 x 45 m, along x = 0 from its threshold at y = -1000 to y = +1000, surface at
  z = 0.02 m; white markings (side stripes, centreline, threshold "piano keys", aiming point,
  touchdown zone) painted on it: faces of the runway model declared "on" the runway surface
  with layer 1, in its plane, so they show by layer order at any range with no height offset;
- east of it a parallel taxiway, an apron, four hangars and a terminal; the hangars cross the
  right seam during the take-off roll, the terminal as the climb ends;
- west of it the control tower (translucent glass cab), which crosses the left seam during the
  take-off roll, a fire station (rotation) and fuel tanks (climb);
- tree lines either side of the runway and a poplar hedge across its far end;
- further out, a farm (crosses the left channel's outer edge in the descent), cargo sheds north
  of the terminal (the right channel's outer edge in the descent), a factory 1.5 km
  ahead (right seam in the descent), a town 1.5 km to the west-north-west (left seam in the
  turn and the descent), a water tower, a 150 m radio mast, a power line across the extended
  centreline and hills 5-11 km away for a skyline.

Every model is assembled from parts made with the modelling toolkit
(channel_worker/data/modelling.py), which checks every face before anything is written. Bottoms
of solids standing on the earth are left out: the eye never goes below ground and the earth
plane hides them.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from channel_worker.data.modelling import (
    GeometryError,
    Instance,
    Part,
    box,
    dome,
    facing_face,
    ground_rect,
    ground_rects,
    instance_doc,
    loft,
    model_doc,
    ngon,
    prism,
    pyramid,
    render_json,
    round_mm,
    square,
    statistics,
    textured,
    wall_rect,
)

#: Where the bundled scene lives (channel_worker.pipeline.scene.bundled_scene_path()).
OUTPUT = Path(__file__).resolve().with_name("airfield.json")
#: The same airfield on the bundled terrain, with haze: the demo's scene
#: (channel_worker.pipeline.scene.demo_scene_path()).
TERRAIN_OUTPUT = Path(__file__).resolve().with_name("airfield_terrain.json")

# Surfaces painted on the ground: the runway, taxiways and apron lie just above the earth plane
# (docs/scene-format.md: the earth is always drawn behind polygons); markings lie in the plane
# of the pavement they are painted on and are declared "on" it (layer order, no offset).
PAVEMENT_Z = 0.02
# The textured grass field lies just below the pavement, above the earth plane (which is at 0,
# like the bundled terrain's pad), and inside the pad (x -600..400, y -1300..1300).
GRASS_Z = 0.005
GRASS_HALF_X_M = 380.0
GRASS_HALF_Y_M = 1250.0

RUNWAY_LENGTH_M = 2000.0
RUNWAY_WIDTH_M = 45.0
TAXIWAY_X_M = 110.0  # centreline of the parallel taxiway (east of the runway)
TAXIWAY_WIDTH_M = 23.0

# Colours, sRGB.
SKY = "#a4c8ea"
GRASS = "#5f8a3e"
ASPHALT = "#46484b"
CONCRETE = "#7b7d7f"
PAINT_WHITE = "#f2f2ee"
PAINT_YELLOW = "#e3b324"
METAL_WALL = "#b7bcc0"
METAL_ROOF = "#6f7b85"
DOOR = "#59626b"
TOWER_CONCRETE = "#dcd7cd"
TOWER_TRIM = "#6d7378"
GLASS = "#5f95ad"
CONSOLE = "#2e3236"
BRICK = "#9c5a3f"
BRICK_ROOF = "#5e4034"
HOUSE_WALL = "#b88a6c"
FIRE_RED = "#b8322a"
TANK_WHITE = "#e7e8e4"
STEEL = "#8c9196"
MAST_RED = "#c8342c"
GREENS = {"fir": "#2f5a2c", "oak": "#4a7832", "poplar": "#5a8636"}


# ---------------------------------------------------------------------------------------------
# Models (model frame: x right, y forward, z up; the front of a building faces +y).

def runway() -> list[Part]:
    """The paved runway, x -22.5..22.5, y -1000..1000 (face 0), and every marking painted on it."""
    half_w, half_l = RUNWAY_WIDTH_M / 2.0, RUNWAY_LENGTH_M / 2.0
    side = [(-half_w + 0.3, -half_w + 1.2, -half_l, half_l),
            (half_w - 1.2, half_w - 0.3, -half_l, half_l)]
    ends = runway_end_markings()
    # The 18 end is the 36 end turned half a turn about the runway centre.
    rects = side + runway_centreline() + [(x0, x1, y0 - half_l, y1 - half_l) for x0, x1, y0, y1 in ends]
    rects += [(-x1, -x0, half_l - y1, half_l - y0) for x0, x1, y0, y1 in ends]
    return [textured(ground_rect(-half_w, half_w, -half_l, half_l, PAVEMENT_Z, ASPHALT), "runway"),
            ground_rects(rects, PAVEMENT_Z, PAINT_WHITE, on=0)]


def runway_centreline() -> list[tuple[float, float, float, float]]:
    """Centreline dashes, 30 m painted and 20 m gap, 0.9 m wide, clear of the end markings."""
    dash, gap, usable = 30.0, 20.0, 1780.0
    n = int((usable + gap) // (dash + gap))
    y0 = -(n * (dash + gap) - gap) / 2.0
    return [(-0.45, 0.45, y0 + k * (dash + gap), y0 + k * (dash + gap) + dash) for k in range(n)]


def runway_end_markings() -> list[tuple[float, float, float, float]]:
    """Markings of one runway end; the origin is the threshold centre, +y points down the runway.

    Threshold stripes (12 for a 45 m runway), aiming point at 300 m and touchdown-zone bars at
    150, 450, 600 and 750 m, after ICAO Annex 14 proportions.
    """
    rects = []
    for k in range(6):  # threshold "piano keys": 1.8 x 30 m, 6 m in from the threshold
        x = 3.0 + 3.3 * k
        rects += [(x - 0.9, x + 0.9, 6.0, 36.0), (-x - 0.9, -x + 0.9, 6.0, 36.0)]
    rects += [(9.0, 15.0, 300.0, 345.0), (-15.0, -9.0, 300.0, 345.0)]  # aiming point
    for y, bars in ((150.0, 3), (450.0, 2), (600.0, 2), (750.0, 1)):  # touchdown zone
        for b in range(bars):
            x = 9.0 + 3.3 * b
            rects += [(x, x + 1.8, y, y + 22.5), (-x - 1.8, -x, y, y + 22.5)]
    return rects


def taxiways() -> list[Part]:
    """Parallel taxiway east of the runway, three stubs joining it, the apron, yellow lines."""
    hw = TAXIWAY_WIDTH_M / 2.0
    x_tw0, x_tw1 = TAXIWAY_X_M - hw, TAXIWAY_X_M + hw
    stubs = [(RUNWAY_WIDTH_M / 2.0, x_tw0, y - hw, y + hw) for y in (-950.0, 0.0, 950.0)]
    paving = [(x_tw0, x_tw1, -950.0 - hw, 950.0 + hw)] + stubs + [(x_tw1, 200.0, -510.0, -60.0)]
    # Yellow lines, each painted on the one paving face (0: the taxiway, 1-3: the stubs) it lies
    # on; a stub's line is cut where the stub meets the taxiway.
    on_taxiway = [(TAXIWAY_X_M - 0.15, TAXIWAY_X_M + 0.15, -950.0, 950.0)]
    on_taxiway += [(x_tw0, TAXIWAY_X_M - 0.15, y - 0.15, y + 0.15) for y in (-950.0, 0.0, 950.0)]
    parts = [textured(ground_rects(paving, PAVEMENT_Z, CONCRETE), "concrete"),
             ground_rects(on_taxiway, PAVEMENT_Z, PAINT_YELLOW, on=0)]
    for k, y in enumerate((-950.0, 0.0, 950.0)):
        parts.append(ground_rects([(RUNWAY_WIDTH_M / 2.0 + 5.0, x_tw0, y - 0.15, y + 0.15)],
                                  PAVEMENT_Z, PAINT_YELLOW, on=1 + k))
    return parts


def grass() -> list[Part]:
    """The airfield's mown grass: one textured field under the runway, taxiways and buildings
    (GRASS_Z below the pavement), within the bundled terrain's flattened pad. Beyond it the
    earth plane or the terrain carry on in the same green, untextured."""
    return [textured(ground_rect(-GRASS_HALF_X_M, GRASS_HALF_X_M, -GRASS_HALF_Y_M, GRASS_HALF_Y_M,
                                 GRASS_Z, GRASS), "grass")]


def arched_hangar(width: float, depth: float, height: float, segments: int = 10) -> list[Part]:
    """A hangar with a round (barrel) roof, `width` across its front (x), `depth` (y), the
    crown `height` above the floor: a half-ellipse profile lofted front to back, shaded
    smoothly (model "smooth"), its metal cladding textured."""
    hw, hd = width / 2.0, depth / 2.0
    # The cross-section in the x-z plane, in gable_building's order (counter-clockwise seen
    # from the front): over the arch from -x to +x, then back along the floor edge.
    ring = [(-hw * math.cos(math.pi * k / segments), height * math.sin(math.pi * k / segments))
            for k in range(segments + 1)]
    back = [(x, -hd, z) for x, z in ring]
    front = [(x, hd, z) for x, z in ring]
    sides: list[str | None] = [METAL_ROOF] * (len(ring) - 1) + [None]
    return [textured(loft(back, front, sides, cap_a=METAL_WALL, cap_b=METAL_WALL), "metal")]


def gable_building(width: float, depth: float, eaves: float, ridge: float, walls: str, roof: str,
                   *, door: tuple[float, float, str] | None = None) -> list[Part]:
    """A building with a pitched roof: `width` across its front (x), `depth` front to back (y),
    walls `eaves` high and the ridge (along y) at `ridge`, metres. door = (width, height, colour)
    paints a door centred on the front wall."""
    hw, hd = width / 2.0, depth / 2.0
    # Cross-section in the x-z plane, counter-clockwise seen from the front (+y, where +x is on
    # the viewer's left): floor edge first (left out below), then up the -x wall, over the ridge.
    profile = [(hw, 0.0), (-hw, 0.0), (-hw, eaves), (0.0, ridge), (hw, eaves)]
    back = [(x, -hd, z) for x, z in profile]
    front = [(x, hd, z) for x, z in profile]
    body = loft(back, front, [None, walls, roof, roof, walls], cap_a=walls, cap_b=walls)
    parts = [body]
    if door is not None:
        dw, dh, colour = door
        # Painted on the front wall (the body is the model's first part: its face k is k).
        parts.append(wall_rect(-dw / 2.0, dw / 2.0, 0.0, dh, hd, colour,
                               on=facing_face(body, (0.0, 1.0, 0.0))))
    return parts


def flat_roof_building(width: float, depth: float, height: float, walls: str, roof: str, *,
                       band: tuple[float, float, str] | None = None) -> list[Part]:
    """A box building, `width` across its front (x) by `depth` (y) by `height`, metres.
    band = (z0, z1, colour) paints a window band along the front wall."""
    hw, hd = width / 2.0, depth / 2.0
    body = box(-hw, hw, -hd, hd, 0.0, height, walls, top=roof)
    parts = [body]
    if band is not None:
        z0, z1, colour = band
        parts.append(wall_rect(-hw + 2.0, hw - 2.0, z0, z1, hd, colour,
                               on=facing_face(body, (0.0, 1.0, 0.0))))
    return parts


def control_tower() -> list[Part]:
    """A 22 m tower: concrete shaft, octagonal cab of translucent glass with a console inside,
    overhanging roof, antenna; and a low operations building at its foot."""
    cab_r, phase = 5.0, 22.5  # octagon with flat sides facing the axes
    return [
        box(-2.5, 2.5, -2.5, 2.5, 0.0, 17.0, TOWER_CONCRETE),  # top hidden by the cab floor
        prism(ngon(0.0, 0.0, cab_r + 0.4, 8, phase_deg=phase), 17.0, 17.6, TOWER_TRIM,
              top=TOWER_TRIM, bottom=TOWER_TRIM),
        # Glass: sides only. The far panes are back faces and culled, so through the glass one
        # sees the console and whatever is behind the tower.
        prism(ngon(0.0, 0.0, cab_r, 8, phase_deg=phase), 17.6, 20.6, GLASS, opacity=0.4),
        box(-2.0, 2.0, 1.5, 3.2, 17.6, 18.6, CONSOLE, top=CONSOLE),
        prism(ngon(0.0, 0.0, cab_r + 0.8, 8, phase_deg=phase), 20.6, 21.2, TOWER_TRIM,
              top=TOWER_TRIM, bottom=TOWER_TRIM),
        box(-0.15, 0.15, -0.15, 0.15, 21.2, 25.0, STEEL, top=STEEL),
        box(-9.0, 9.0, -12.0, -2.5, 0.0, 4.0, TOWER_CONCRETE, top=TOWER_TRIM),
    ]


def fuel_tank() -> list[Part]:
    """An octagonal fuel tank, 16 m across and 10 m high."""
    return [prism(ngon(0.0, 0.0, 8.0, 8), 0.0, 10.0, TANK_WHITE, top=STEEL)]


def silo() -> list[Part]:
    """A farm silo with a conical roof."""
    body = prism(ngon(0.0, 0.0, 3.5, 8), 0.0, 14.0, "#c9c6bb")
    roof = pyramid(ngon(0.0, 0.0, 3.8, 8, z=14.0), (0.0, 0.0, 17.0), "#7d8a91", bottom="#7d8a91")
    return [body, roof]


def water_tower() -> list[Part]:
    """A 35 m water tower: octagonal shaft carrying an octagonal tank with a pointed roof."""
    return [
        prism(ngon(0.0, 0.0, 2.0, 8), 0.0, 25.0, TOWER_CONCRETE),
        prism(ngon(0.0, 0.0, 7.0, 8), 25.0, 32.0, "#9fb3bf", bottom=STEEL),
        pyramid(ngon(0.0, 0.0, 7.0, 8, z=32.0), (0.0, 0.0, 35.0), STEEL),
    ]


def radio_mast() -> list[Part]:
    """A 150 m mast painted in six red and white bands (obstacle marking), tapering 3 -> 1 m."""
    parts, bands, height = [], 6, 150.0
    for k in range(bands):
        z0, z1 = height * k / bands, height * (k + 1) / bands
        h0, h1 = 1.5 - 1.0 * k / bands, 1.5 - 1.0 * (k + 1) / bands
        colour = MAST_RED if k % 2 == 0 else PAINT_WHITE
        parts.append(loft(square(h0, z0), square(h1, z1), colour,
                          cap_b=colour if k == bands - 1 else None))
    return parts


def pylon() -> list[Part]:
    """A power-line pylon, 35 m: a tapering steel tower with a cross-arm (x) for the wires."""
    return [
        loft(square(4.0, 0.0), square(1.0, 30.0), STEEL),
        pyramid(square(1.0, 30.0), (0.0, 0.0, 35.0), STEEL),
        box(-11.0, 11.0, -0.8, 0.8, 26.0, 27.5, STEEL, top=STEEL, bottom=STEEL),
    ]


def factory() -> list[Part]:
    """A factory hall, 120 x 60 x 20 m, with a 45 m brick chimney behind it."""
    return flat_roof_building(120.0, 60.0, 20.0, "#b9ac96", "#6c7177",
                              band=(9.0, 13.0, "#4b5b69")) + [
        loft([(p[0] + 40.0, p[1] - 40.0, p[2]) for p in square(3.0, 0.0)],
             [(p[0] + 40.0, p[1] - 40.0, p[2]) for p in square(2.0, 45.0)], BRICK, cap_b=CONSOLE),
    ]


def tree(kind: str, sides: int, radius: float, height: float) -> list[Part]:
    """A tree as an n-sided pyramid standing on the ground."""
    return [pyramid(ngon(0.0, 0.0, radius, sides, z=0.0), (0.0, 0.0, height), GREENS[kind])]


def hill(seed: int, radius: float, height: float, colours: Sequence[str]) -> list[Part]:
    """A hill: an irregular 10-sided dome, `radius` and `height` in metres, shaped by `seed`."""
    rng = random.Random(seed)
    n = 10
    shoulder = (0.5 + 0.1 * rng.random()) * radius
    rings = [
        [(r * math.cos(a), r * math.sin(a), 0.0) for a, r in
         ((2.0 * math.pi * i / n, radius * (0.85 + 0.3 * rng.random())) for i in range(n))],
        [(r * math.cos(a), r * math.sin(a), height * (0.55 + 0.1 * rng.random())) for a, r in
         ((2.0 * math.pi * (i + 0.5) / n, shoulder * (0.9 + 0.2 * rng.random()))
          for i in range(n))],
    ]
    apex = (radius * 0.1 * (rng.random() - 0.5), radius * 0.1 * (rng.random() - 0.5), height)
    return [dome(rings, apex, colours)]


def build_models() -> dict[str, list[Part]]:
    """Every model of the scene as its parts, in file order."""
    models: dict[str, list[Part]] = {
        "grass": grass(),
        "runway": runway(),
        "taxiways": taxiways(),
        "hangar": [textured(p, "metal", colours=(METAL_WALL, METAL_ROOF))
                   for p in gable_building(40.0, 50.0, 12.0, 17.0, METAL_WALL, METAL_ROOF,
                                           door=(32.0, 10.0, DOOR))],
        "arched_hangar": arched_hangar(40.0, 50.0, 17.0),
        "shed": gable_building(24.0, 30.0, 7.0, 9.5, "#c8b792", BRICK_ROOF, door=(8.0, 5.0, DOOR)),
        "barn": [textured(p, "brick", colours=(BRICK,))
                 for p in gable_building(16.0, 30.0, 6.0, 11.0, BRICK, "#4e4a46",
                                         door=(5.0, 5.0, "#5b3a2a"))],
        "terminal": flat_roof_building(100.0, 30.0, 12.0, "#d6d0c2", "#8a8f94",
                                       band=(4.0, 9.0, "#3f566c")),
        "fire_station": flat_roof_building(40.0, 24.0, 8.0, "#d9d4c8", "#7b7f84",
                                           band=(0.0, 5.5, FIRE_RED)),
        "control_tower": control_tower(),
        "fuel_tank": fuel_tank(),
        "silo": silo(),
        "water_tower": water_tower(),
        "radio_mast": radio_mast(),
        "pylon": pylon(),
        "factory": factory(),
        "house": [textured(p, "brick", colours=(HOUSE_WALL,))
                  for p in gable_building(10.0, 14.0, 5.0, 8.0, HOUSE_WALL, "#8e3b2c")],
        "block_low": flat_roof_building(40.0, 30.0, 12.0, "#c7b9a3", "#6e6a66"),
        "block_mid": flat_roof_building(30.0, 30.0, 24.0, "#b3aba0", "#5f6266",
                                        band=(20.0, 22.0, "#4b5b69")),
        "block_tall": flat_roof_building(20.0, 20.0, 42.0, "#9aa3ab", "#5a5e62"),
        "fir": tree("fir", 7, 3.0, 14.0),
        "oak": tree("oak", 6, 5.0, 11.0),
        "poplar": tree("poplar", 6, 1.8, 18.0),
    }
    for k, (seed, radius, height) in enumerate(HILLS_SHAPE):
        models[f"hill_{k + 1}"] = hill(seed, radius, height, HILL_COLOURS[k % len(HILL_COLOURS)])
    return models


# Hills: (shape seed, base radius m, height m) and, below, where they stand.
HILLS_SHAPE = ((11, 1800.0, 420.0), (12, 2400.0, 600.0), (13, 1500.0, 330.0), (14, 2600.0, 650.0),
               (15, 2000.0, 480.0), (16, 1700.0, 380.0), (17, 2200.0, 540.0), (18, 1600.0, 320.0),
               (19, 2500.0, 560.0))
# (bearing from the origin, degrees; range, metres)
HILLS_AT = ((-125.0, 8000.0), (-95.0, 9500.0), (-65.0, 7500.0), (-38.0, 10500.0), (-12.0, 8500.0),
            (12.0, 9000.0), (38.0, 7000.0), (62.0, 10000.0), (92.0, 8000.0))
HILL_COLOURS = (("#6f8660", "#7d9169"), ("#728a6d", "#84977b"), ("#6a7f66", "#7a8d74"))


# Textures (docs/scene-format.md "textures", docs/textures.md): the bundled photographs
# (CC0, channel_worker/data/textures/LICENSE.md) and procedural noise for the coarse variation
# that must survive at a distance, where the fine textures have faded.
TEXTURES = {
    "asphalt": {"bundled": "asphalt"},
    "gravel": {"bundled": "gravel"},
    "grass": {"bundled": "grass"},
    "brick": {"bundled": "brick"},
    "patches": {"procedural": "noise", "size": 128, "seed": 3},
    "streaks": {"procedural": "noise", "size": 64, "seed": 8},
    "crowns": {"procedural": "noise", "size": 32, "seed": 11},
}
# Texture codes: the primary texture at its own scale, the secondary and tertiary at a common
# coarser scale (the texture patent's fine and coarse patterns: the fine one fades with range,
# the coarse ones carry on).
TEXTURE_CODES = {
    "runway": {"textures": ["asphalt", "patches", "streaks"], "intensity": 0.9, "scale_m": [8.0, 8.0],
               "detail_scale_m": [120.0, 400.0], "amplitudes": [0.5, 0.4]},
    "concrete": {"textures": ["gravel", "patches"], "intensity": 0.5, "scale_m": [6.0, 6.0],
                 "detail_scale_m": [80.0, 80.0], "detail_offset_m": [17.0, 5.0], "amplitudes": [0.6, 0.0]},
    "grass": {"textures": ["grass", "grass", "patches"], "intensity": 1.0, "scale_m": [10.0, 10.0],
              "detail_scale_m": [60.0, 60.0], "detail_offset_m": [23.0, 9.0],
              "amplitudes": [0.7, 0.5], "modulation": "colour"},
    "brick": {"textures": ["brick"], "intensity": 1.0, "scale_m": [3.0, 3.0], "modulation": "colour"},
    "metal": {"textures": ["streaks"], "intensity": 0.5, "scale_m": [1.5, 12.0]},
    # The land over the bundled terrain (its "detail"): meadow grass with coarse patches; crop
    # rows (noise stretched 25:1) in fields; broken rock. One or two textures each: the cast
    # reads them at every near step (bench_terrain.py section 8).
    "terrain_grass": {"textures": ["grass", "patches"], "intensity": 0.8, "scale_m": [12.0, 12.0],
                      "detail_scale_m": [40.0, 40.0], "detail_offset_m": [31.0, 11.0], "amplitudes": [0.7, 0.0]},
    "field": {"textures": ["streaks"], "intensity": 0.8, "scale_m": [3.0, 75.0]},
    "rock": {"textures": ["gravel", "patches"], "intensity": 0.9, "scale_m": [5.0, 5.0],
             "detail_scale_m": [35.0, 35.0], "amplitudes": [0.8, 0.0]},
    # A forest's canopy from above: crowns and the gaps between them (noise at crown size).
    "canopy": {"textures": ["crowns"], "intensity": 1.2, "scale_m": [56.0, 56.0]},
}
# Models shaded smoothly (Gouraud): the barrel roofs, and the hills' terrain-like slopes.
SMOOTH_MODELS = {"arched_hangar"} | {f"hill_{k + 1}" for k in range(9)}


# ---------------------------------------------------------------------------------------------
# Placement. Positions were chosen with the bundled flight (host_sim/flight.py) so that objects
# cross the seams in every phase; tests/channel_worker/test_bundled_scene.py keeps the two in step.

def build_instances() -> list[Instance]:
    """Every instance of the scene, in file order."""
    out = [
        Instance("grass", (0.0, 0.0, 0.0), "airfield grass"),
        Instance("runway", (0.0, 0.0, 0.0), "runway 36/18"),
        Instance("taxiways", (0.0, 0.0, 0.0), "taxiway A and apron"),
    ]
    # East side; building fronts face west, towards the runway (heading 270).
    west = (270.0, 0.0, 0.0)
    for k, y in enumerate((-480.0, -420.0, -360.0, -300.0)):  # right seam, t = 0..8 s
        # Two barrel-roofed hangars (smooth shading) between gabled ones.
        model = "arched_hangar" if k % 2 == 1 else "hangar"
        out.append(Instance(model, (225.0, y, 0.0), f"hangar {k + 1}", west))
    # The terminal: right seam as the climb ends. Cargo sheds: the right outer edge in the descent.
    out.append(Instance("terminal", (215.0, -120.0, 0.0), "terminal", west))
    for k, y in enumerate((130.0, 170.0, 210.0)):
        out.append(Instance("shed", (215.0, y, 0.0), f"cargo shed {k + 1}", west))
    # West side; fronts face east (heading 90).
    east = (90.0, 0.0, 0.0)
    # Tower: left seam at t ~ 2-3 s; fire station: left seam in the rotation.
    out.append(Instance("control_tower", (-140.0, -600.0, 0.0), "control tower", east))
    out.append(Instance("fire_station", (-150.0, -420.0, 0.0), "fire station", east))
    for k, x in enumerate((-190.0, -168.0, -146.0)):  # left seam in the climb
        out.append(Instance("fuel_tank", (x, -250.0, 0.0), f"fuel tank {k + 1}"))
    out += [  # left outer edge in the descent
        Instance("barn", (-480.0, -330.0, 0.0), "farm barn", (30.0, 0.0, 0.0)),
        Instance("silo", (-455.0, -352.0, 0.0), "farm silo"),
    ]
    out += _trees()
    # Further out.
    # The factory crosses the right seam in the descent.
    out.append(Instance("factory", (-380.0, 1450.0, 0.0), "factory", (180.0, 0.0, 0.0)))
    out.append(Instance("water_tower", (-700.0, 900.0, 0.0), "water tower"))
    out.append(Instance("radio_mast", (1200.0, 2200.0, 0.0), "radio mast"))
    for k, x in enumerate(range(-2400, 2401, 400)):  # a power line across the extended centreline
        out.append(Instance("pylon", (float(x), 1600.0, 0.0), f"pylon {k + 1}"))
    out += _town()
    for k, (bearing, rng) in enumerate(HILLS_AT):
        b = math.radians(bearing)
        position = (round_mm(rng * math.sin(b)), round_mm(rng * math.cos(b)), 0.0)
        out.append(Instance(f"hill_{k + 1}", position, f"hill {k + 1}"))
    return out


def _trees() -> list[Instance]:
    """Tree lines either side of the runway, a poplar hedge across the far end, a small wood.

    Jitter comes from a seeded generator, so the rows look planted by hand but never change.
    """
    rng = random.Random(36)
    out = []

    def plant(kind: str, x: float, y: float, label: str) -> None:
        out.append(Instance(kind, (round_mm(x), round_mm(y), 0.0), label,
                            (round_mm(rng.uniform(0.0, 360.0)), 0.0, 0.0)))

    for k, y in enumerate(range(-1040, 1041, 40)):
        plant("fir" if k % 3 else "oak", -300.0 + rng.uniform(-4.0, 4.0),
              y + rng.uniform(-6.0, 6.0), f"west tree line {k + 1}")
    for k, y in enumerate(range(-1040, 681, 40)):
        plant("oak" if k % 2 else "fir", 330.0 + rng.uniform(-4.0, 4.0),
              y + rng.uniform(-6.0, 6.0), f"east tree line {k + 1}")
    for k, x in enumerate(range(-700, 701, 40)):
        plant("poplar", x + rng.uniform(-3.0, 3.0), 1250.0 + rng.uniform(-2.0, 2.0),
              f"hedge {k + 1}")
    for k in range(14):
        r, a = 150.0 * math.sqrt(rng.random()), rng.uniform(0.0, 2.0 * math.pi)
        plant("oak" if k % 2 else "fir", -700.0 + r * math.cos(a), 420.0 + r * math.sin(a),
              f"wood {k + 1}")
    return out


def _town() -> list[Instance]:
    """A small town 1.5 km west-north-west of the airfield (left seam in the turn and descent)."""
    layout = (("block_tall", -1500.0, 520.0, 0.0), ("block_mid", -1440.0, 440.0, 10.0),
              ("block_mid", -1580.0, 600.0, -5.0), ("block_low", -1420.0, 560.0, 0.0),
              ("block_low", -1560.0, 420.0, 15.0), ("block_low", -1640.0, 500.0, 90.0),
              ("house", -1360.0, 480.0, 100.0), ("house", -1350.0, 520.0, 95.0),
              ("house", -1380.0, 380.0, 80.0), ("house", -1470.0, 640.0, 160.0),
              ("house", -1520.0, 360.0, 20.0), ("block_tall", -1620.0, 380.0, 30.0))
    return [Instance(model, (x, y, 0.0), f"town {model} {k + 1}", (h, 0.0, 0.0))
            for k, (model, x, y, h) in enumerate(layout)]


# ---------------------------------------------------------------------------------------------
# The document.

def build_scene() -> dict[str, Any]:
    """The scene document (docs/scene-format.md) as plain JSON data."""
    models = build_models()
    instances = build_instances()
    unknown = {i.model for i in instances} - set(models)
    if unknown:
        raise GeometryError(f"instances of undefined models: {sorted(unknown)}")
    return {
        "format": "ig-scene/1",
        "name": "bundled airfield",
        "sky": {"colour": SKY},
        "earth": {"colour": GRASS, "height_m": 0.0},
        # Sun in the south-south-west behind the departing aircraft: the faces the flight looks
        # at are lit, and east/west walls differ in shade.
        "lighting": {"sun_heading_deg": 210.0, "sun_elevation_deg": 38.0, "ambient": 0.4},
        "textures": TEXTURES,
        "texture_codes": TEXTURE_CODES,
        "models": {name: model_doc(parts, smooth=name in SMOOTH_MODELS) for name, parts in models.items()},
        "instances": [instance_doc(i) for i in instances],
    }


def build_terrain_scene() -> dict[str, Any]:
    """The airfield on the bundled Jacksboro terrain (its pad flattened to z = 0 under the
    airfield, channel_worker/terrain/bundled.py), in a light summer haze, with morning mist
    lying in the valleys below it."""
    doc = build_scene()
    doc["name"] = "bundled airfield on the Jacksboro terrain"
    # The land's detail: texture codes per land class over the relief colour, and the airfield's
    # grass (colour and code of its grass faces) feathered from the grass faces' edges (the
    # area they cover) over the flattened pad into the land: to 460 m out, past the pad's own
    # blend (pad -450..550 x -1300..1300, blend 400).
    doc["terrain"] = {"database": "bundled:jacksboro", "polygon_margin_m": 1.0,
                      "detail": {"grass": "terrain_grass", "field": "field", "rock": "rock", "forest": "canopy",
                                 "pad": {"code": "grass", "colour": GRASS, "covered": True,
                                         "areas": [[-GRASS_HALF_X_M, -GRASS_HALF_Y_M, GRASS_HALF_X_M,
                                                    GRASS_HALF_Y_M, 460.0]]}}}
    doc["haze"] = {"visibility_m": 30000.0, "scale_height_m": 1500.0, "base_height_m": 0.0,
                   "colour": "#c4ccd6"}
    # Fair-weather cumulus a kilometre above the airfield, over the terrain's area and beyond.
    doc["clouds"] = {"extent_m": [-30000.0, -30000.0, 30000.0, 30000.0], "cell_m": 400.0,
                     "base_m": 1100.0, "thickness_m": 700.0, "cover": 0.3,
                     "extinction_per_m": 0.02, "colour": "#f4f6fa", "seed": 7}
    # Layered fog: mist of 1.2 km visibility in the lowest valleys (120 m below the runway),
    # thinning to clear air 40 m above it.
    doc["fog"] = {"origin_m": [0.0, 0.0, -120.0], "spacing_m": 40.0,
                  "visibility_m": [1200.0, 2500.0, 6000.0, 20000.0, None], "colour": "#d4d8dc"}
    return doc


def main(argv: Sequence[str] | None = None) -> int:
    """Write (or with --check, verify) the bundled scene; returns the process exit status."""
    parser = argparse.ArgumentParser(prog="python -m channel_worker.data.build_airfield",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=OUTPUT, help=f"default: {OUTPUT}")
    parser.add_argument("--terrain-output", type=Path, default=TERRAIN_OUTPUT,
                        help=f"the airfield on the bundled terrain; default: {TERRAIN_OUTPUT}")
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 if the file differs from what would be written")
    args = parser.parse_args(argv)
    doc = build_scene()
    stats = ", ".join(f"{k} {v}" for k, v in statistics(doc).items())
    outputs = ((args.output, render_json(doc)),
               (args.terrain_output, render_json(build_terrain_scene())))
    if args.check:
        for path, text in outputs:
            current = path.read_text(encoding="utf-8") if path.exists() else None
            if current != text:
                print(f"{path} is out of date; run python -m channel_worker.data.build_airfield",
                      file=sys.stderr)
                return 1
            print(f"{path} is up to date ({stats})")
        return 0
    for path, text in outputs:
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path} ({stats})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
