"""A bench scene modelled on a real approach: about 10,000 polygons seen from a 3-degree glide path.

    python bench/scenes/approach.py              # print the scene's counts
    python bench/scenes/approach.py --out a.json # also write the scene file (docs/scene-format.md)

`approach_scene()` returns the scene document (parse_scene-able, the same every run: all jitter
comes from seeded generators and every vertex is rounded to millimetres); `approach_eyepoint()`
and `approach_channel()` the standard view of it. The world origin is the centre of the runway
threshold; the runway runs north (+y).

- runway 36/18, 45 x 3000 m (x -22.5..22.5, y 0..3000), pavement 2 cm above the earth plane,
  one model: the asphalt is face 0; rubber deposits in both touchdown zones lie "on" it at
  layer 1; every white marking (threshold bar and stripes, designation numerals, touchdown-zone
  bars, aiming point, centreline dashes, side stripes) lies on it at layer 2, painted over the
  rubber where they overlap. No marking is lifted off the pavement;
- a parallel taxiway 200 m east with five stubs and an apron, yellow centrelines on each
  paving face; threshold lights and a PAPI;
- a 900 m approach lighting system under the glide path: a barrette of five lights on a stand
  every 30 m and five crossbars (light units are 35 cm boxes: sub-pixel polygons from the eye);
- hangars, a terminal, a control tower with a translucent glass cab, cargo sheds, fuel tanks;
- a town of gabled houses and blocks either side of the approach path, 300 m to 1.4 km short
  of the threshold;
- several hundred trees as translucent billboards (opacity 0.6-0.85): two or three crossing
  vertical quads per tree, each quad a front and a back face, in tree lines along the runway,
  woods, gardens and hedgerows;
- terrain patches: fields of varying colour on a 250 m grid from 1.5 km short of the threshold
  to 8.5 km beyond it, 4 km either side (the airfield's grass is the earth plane), with hedge
  gaps where the earth plane shows through, and east-west roads in some of the gaps;
- hills 9-14 km ahead for a skyline.

The eyepoint (approach_eyepoint) is 1.5 km short of the threshold on the extended centreline,
on a 3-degree glide path to a point 300 m past the threshold (94.3 m above the runway), heading
north, pitched 3 degrees down so the aiming point is at the centre of the picture. The channel
(approach_channel) is 1280 x 1024 with a 60-degree horizontal field of view and square pixels.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

# Runnable from a plain checkout too.
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from channel_worker.data.build_airfield import (
    control_tower,
    flat_roof_building,
    fuel_tank,
    gable_building,
    hill,
)
from channel_worker.data.modelling import Face, Part, box, make_part, model_doc
from services.rig.frame import ChannelSpec, Eyepoint

RUNWAY_LENGTH_M = 3000.0
RUNWAY_WIDTH_M = 45.0
PAVEMENT_Z = 0.02
TAXIWAY_X_M = 200.0
TAXIWAY_WIDTH_M = 23.0
GLIDE_PATH_DEG = 3.0
#: Where the glide path meets the runway, metres past the threshold.
GLIDE_PATH_ORIGIN_M = 300.0
#: Distance of the standard eyepoint short of the threshold, metres.
EYE_DISTANCE_M = 1500.0

# Colours, sRGB.
SKY = "#a9c9e8"
GRASS = "#5f8a3e"
ASPHALT = "#48494c"
RUBBER = "#2c2d2f"
CONCRETE = "#7d7f80"
PAINT_WHITE = "#f0f0ec"
PAINT_YELLOW = "#e0b020"
LIGHT_WHITE = "#fff6d8"
LIGHT_GREEN = "#58d070"
LIGHT_RED = "#e04030"
STAND = "#3a3d40"
FIELD_COLOURS = ("#6b8f3e", "#7fa04a", "#8a9a4f", "#a59a5c", "#b8a96a", "#7a6a48", "#5d7f3a",
                 "#94a85a", "#c2b280", "#6e7f45")
HOUSE_WALLS = ("#e1d6bf", "#d8cbb0", "#cfc4b4", "#e8e0cc", "#b9a68a")
HOUSE_ROOFS = ("#8e3b2c", "#7a3527", "#5c5450", "#9a4a33")
TREE_GREENS = ("#2f5a2c", "#3d6b30", "#4a7832", "#557f3a", "#36602e")
HILL_COLOURS = (("#6f8660", "#7d9169"), ("#728a6d", "#84977b"), ("#6a7f66", "#7a8d74"))

UP = (0.0, 0.0, 1.0)


def approach_eyepoint() -> Eyepoint:
    """The standard eyepoint: 1.5 km short of the threshold on the 3-degree glide path.

    Heading north down the runway, pitched down by the glide-path angle so the picture is
    centred on the glide path's aiming point; wings level. Position in world metres.
    """
    height = (EYE_DISTANCE_M + GLIDE_PATH_ORIGIN_M) * math.tan(math.radians(GLIDE_PATH_DEG))
    return Eyepoint.of(0.0, -EYE_DISTANCE_M, round(height, 3), 0.0, -GLIDE_PATH_DEG, 0.0)


def approach_channel(width: int = 1280, height: int = 1024) -> ChannelSpec:
    """One forward channel: 60 degrees horizontal field of view, square pixels (47.9 degrees
    vertical at 1280 x 1024)."""
    return ChannelSpec.symmetric("approach", width, height, 60.0)


# ---------------------------------------------------------------------------------------------
# Parts painted on a surface.

def painted(rects: Iterable[tuple[float, float, float, float]], colour: str, *, z: float,
            on: int | None, layer: int = 1) -> Part:
    """Ground rectangles (x0, x1, y0, y1) facing up at height z, one face each.

    on: the model face they lie on (scene "on") with `layer`, or None for base surfaces.
    """
    vertices: list[tuple[float, float, float]] = []
    faces = []
    for x0, x1, y0, y1 in rects:
        b = len(vertices)
        vertices += [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
        faces.append(Face((b, b + 1, b + 2, b + 3), colour, on=on, layer=layer))
    return make_part(vertices, faces, facing=UP)


def seven_segment(digit: int, x0: float, y0: float, width: float, height: float,
                  stroke: float) -> list[tuple[float, float, float, float]]:
    """A runway designation digit as non-overlapping rectangles, read looking +y (top = +y)."""
    segments = {0: "abcdef", 1: "bc", 2: "abdeg", 3: "abcdg", 4: "bcfg", 5: "acdfg",
                6: "acdefg", 7: "abc", 8: "abcdefg", 9: "abcdfg"}[digit]
    x1, y1, ym = x0 + width, y0 + height, y0 + height / 2.0
    s, h = stroke, stroke / 2.0
    # Horizontal strokes span the full width; vertical strokes fill between them.
    shapes = {
        "a": (x0, x1, y1 - s, y1), "g": (x0, x1, ym - h, ym + h), "d": (x0, x1, y0, y0 + s),
        "f": (x0, x0 + s, ym + h, y1 - s), "b": (x1 - s, x1, ym + h, y1 - s),
        "e": (x0, x0 + s, y0 + s, ym - h), "c": (x1 - s, x1, y0 + s, ym - h),
    }
    return [shapes[k] for k in segments]


# ---------------------------------------------------------------------------------------------
# Models (x right, y forward, z up).

def runway_end(designation: str) -> tuple[list, list]:
    """(rubber, white) rectangles of one runway end; origin at the threshold centre, +y down the
    runway. After ICAO Annex 14 for a 45 m wide runway of 3000 m."""
    white = [(-20.4, 20.4, 1.5, 3.3)]  # threshold bar
    for k in range(6):  # twelve threshold stripes, 1.8 x 30 m
        x = 3.0 + 3.3 * k
        white += [(x - 0.9, x + 0.9, 6.0, 36.0), (-x - 0.9, -x + 0.9, 6.0, 36.0)]
    digit_w, gap = 4.0, 1.5
    x = -(len(designation) * digit_w + (len(designation) - 1) * gap) / 2.0
    for ch in designation:  # designation numerals, 9 m tall, 12 m past the stripes
        white += seven_segment(int(ch), x, 48.0, digit_w, 9.0, 0.9)
        x += digit_w + gap
    white += [(9.0, 15.0, 400.0, 460.0), (-15.0, -9.0, 400.0, 460.0)]  # aiming point
    for y, bars in ((150.0, 3), (300.0, 3), (600.0, 2), (750.0, 2), (900.0, 1)):  # touchdown zone
        for b in range(bars):
            x = 9.0 + 3.3 * b
            white += [(x, x + 1.8, y, y + 22.5), (-x - 1.8, -x, y, y + 22.5)]
    rubber = []  # tyre marks, staggered patches through the touchdown zone
    for k, (y0, y1, half) in enumerate(((120.0, 260.0, 7.0), (260.0, 420.0, 11.0),
                                        (420.0, 610.0, 12.5), (610.0, 780.0, 10.0),
                                        (780.0, 950.0, 6.5))):
        shift = 1.0 if k % 2 else -1.0
        rubber.append((-half + shift, half + shift, y0, y1))
    return rubber, white


def runway() -> list[Part]:
    """Runway 36/18: asphalt (face 0), rubber on it at layer 1, white markings at layer 2."""
    hw, length = RUNWAY_WIDTH_M / 2.0, RUNWAY_LENGTH_M
    rubber36, white36 = runway_end("36")
    rubber18, white18 = runway_end("18")

    def far_end(rects: list) -> list:  # the 18 end: half a turn about the runway centre
        return [(-x1, -x0, length - y1, length - y0) for x0, x1, y0, y1 in rects]

    dash, gap, first, last = 30.0, 20.0, 80.0, length - 80.0
    dashes = int((last - first + gap) // (dash + gap))
    centreline = [(-0.45, 0.45, first + k * (dash + gap), first + k * (dash + gap) + dash)
                  for k in range(dashes)]
    sides = [(-hw + 0.3, -hw + 1.2, 0.0, length), (hw - 1.2, hw - 0.3, 0.0, length)]
    return [
        painted([(-hw, hw, 0.0, length)], ASPHALT, z=PAVEMENT_Z, on=None),
        painted(rubber36 + far_end(rubber18), RUBBER, z=PAVEMENT_Z, on=0, layer=1),
        painted(white36 + far_end(white18) + centreline + sides, PAINT_WHITE, z=PAVEMENT_Z,
                on=0, layer=2),
    ]


def taxiways() -> list[Part]:
    """Parallel taxiway, five stubs to the runway and an apron; a yellow line on each paving
    face (face k of the paving part is paving[k])."""
    hw = TAXIWAY_WIDTH_M / 2.0
    x0, x1 = TAXIWAY_X_M - hw, TAXIWAY_X_M + hw
    stub_y = (60.0, 800.0, 1500.0, 2200.0, 2940.0)
    paving = [(x0, x1, stub_y[0] - hw, stub_y[-1] + hw)]
    paving += [(RUNWAY_WIDTH_M / 2.0, x0, y - hw, y + hw) for y in stub_y]
    paving.append((x1, 420.0, 1000.0, 1700.0))  # apron
    parts = [painted(paving, CONCRETE, z=PAVEMENT_Z, on=None)]
    line = (TAXIWAY_X_M - 0.15, TAXIWAY_X_M + 0.15, stub_y[0] - hw, stub_y[-1] + hw)
    parts.append(painted([line], PAINT_YELLOW, z=PAVEMENT_Z, on=0))
    for k, y in enumerate(stub_y):
        parts.append(painted([(RUNWAY_WIDTH_M / 2.0 + 4.0, x0, y - 0.15, y + 0.15)], PAINT_YELLOW,
                             z=PAVEMENT_Z, on=1 + k))
    stands = [(x1 + 30.0 + 45.0 * k - 0.15, x1 + 30.0 + 45.0 * k + 0.15, 1020.0, 1680.0)
              for k in range(4)]  # apron stand lines
    parts.append(painted(stands, PAINT_YELLOW, z=PAVEMENT_Z, on=len(paving) - 1))
    return parts


def light_units(xs: Sequence[float], y: float, z: float, colour: str,
                size: float = 0.35) -> list[Part]:
    """Light fittings: a `size` cube (no bottom) at each x, centred on y, standing at height z."""
    h = size / 2.0
    return [box(x - h, x + h, y - h, y + h, z, z + size, colour, top=colour) for x in xs]


def barrette(xs: Sequence[float], stand_m: float) -> list[Part]:
    """An approach light bar: lights at xs on a horizontal bar, on a stand `stand_m` high."""
    lo, hi = min(xs) - 0.3, max(xs) + 0.3
    return ([box(-0.1, 0.1, -0.1, 0.1, 0.0, stand_m - 0.2, STAND),
             box(lo, hi, -0.12, 0.12, stand_m - 0.2, stand_m, STAND, top=STAND, bottom=STAND)]
            + light_units(xs, 0.0, stand_m, LIGHT_WHITE))


def papi() -> list[Part]:
    """Four PAPI boxes in a row across x, 9 m apart."""
    return [box(x - 1.0, x + 1.0, -0.6, 0.6, 0.3, 1.2, "#d8d8d0", top="#404040")
            for x in (0.0, -9.0, -18.0, -27.0)]


def tree(kind: str, colour: str) -> list[Part]:
    """A billboard tree: 2 or 3 crossing vertical quads through the trunk axis, each a
    translucent front face and back face (only the side facing the eye is drawn)."""
    shapes = {  # planes, bottom width, top width, height (m), opacity
        "broadleaf": (3, 7.0, 6.0, 10.0, 0.75),
        "conifer": (2, 5.0, 0.6, 14.0, 0.85),
        "poplar": (2, 2.5, 2.0, 17.0, 0.7),
        "bush": (2, 4.0, 4.0, 3.0, 0.6),
    }
    planes, bottom, top, height, opacity = shapes[kind]
    parts = []
    for k in range(planes):
        a = math.pi * k / planes
        ux, uy = math.cos(a), math.sin(a)
        quad = [(-bottom / 2 * ux, -bottom / 2 * uy, 0.0), (bottom / 2 * ux, bottom / 2 * uy, 0.0),
                (top / 2 * ux, top / 2 * uy, height), (-top / 2 * ux, -top / 2 * uy, height)]
        normal = (uy, -ux, 0.0)  # (BR - BL) x up
        parts.append(make_part(quad, [Face((0, 1, 2, 3), colour, opacity)], facing=normal))
        parts.append(make_part(quad, [Face((3, 2, 1, 0), colour, opacity)],
                               facing=(-uy, ux, 0.0)))
    return parts


def terrain_tile(rng: random.Random, x0: float, y0: float, size: float, cell: float,
                 keep_out: Sequence[tuple[float, float, float, float]]) -> list[Part]:
    """Fields on a `cell` grid over one square tile (world metres; the tile model is placed at
    the origin). Each cell is one to three strips of crop with 3 m hedge gaps around them (the
    earth plane shows through); cells touching a keep-out rectangle (x0, x1, y0, y1) are left
    to the earth plane."""
    rects: list[tuple[float, float, float, float, str]] = []
    n = round(size / cell)
    for i in range(n):
        for j in range(n):
            cx0, cy0 = x0 + i * cell, y0 + j * cell
            cx1, cy1 = cx0 + cell, cy0 + cell
            if any(cx0 < k1 and k0 < cx1 and cy0 < l1 and l0 < cy1 for k0, k1, l0, l1 in keep_out):
                continue
            strips = rng.choice((1, 1, 2, 3))
            along_x = rng.random() < 0.5
            for s in range(strips):
                a, b = s / strips, (s + 1) / strips
                if along_x:
                    r = (cx0 + a * cell + 3.0, cx0 + b * cell - 3.0, cy0 + 3.0, cy1 - 3.0)
                else:
                    r = (cx0 + 3.0, cx1 - 3.0, cy0 + a * cell + 3.0, cy0 + b * cell - 3.0)
                rects.append((*r, rng.choice(FIELD_COLOURS)))
    if not rects:
        return []
    vertices: list[tuple[float, float, float]] = []
    faces = []
    for fx0, fx1, fy0, fy1, colour in rects:
        b = len(vertices)
        vertices += [(fx0, fy0, 0.0), (fx1, fy0, 0.0), (fx1, fy1, 0.0), (fx0, fy1, 0.0)]
        faces.append(Face((b, b + 1, b + 2, b + 3), colour))
    return [make_part(vertices, faces, facing=UP)]


# ---------------------------------------------------------------------------------------------
# Layout.

#: Field area (x0, x1, y0, y1), world metres, in square tiles of TILE_M, cells of CELL_M.
FIELDS = (-4000.0, 4000.0, -1500.0, 8500.0)
TILE_M = 1000.0
CELL_M = 250.0
#: The airfield has no fields (its grass is the earth plane); the town stands on fields.
AIRFIELD_AREA = (-420.0, 700.0, -80.0, 3200.0)
TOWN_AREAS = ((-650.0, -60.0, -1300.0, -300.0), (60.0, 650.0, -1300.0, -300.0))
#: East-west roads, in the hedge gaps of these field-grid lines (world y, metres).
ROADS_Y = (-500.0, 1500.0, 4500.0, 7500.0)


class _Scene:
    """Collects models and instances; instances hold world positions rounded to millimetres."""

    def __init__(self) -> None:
        self.models: dict[str, list[Part]] = {}
        self.instances: list[dict[str, Any]] = []

    def model(self, name: str, parts: list[Part]) -> str:
        if name not in self.models:
            self.models[name] = parts
        return name

    def place(self, model: str, x: float, y: float, name: str, heading: float = 0.0,
              z: float = 0.0) -> None:
        inst: dict[str, Any] = {"model": model, "position": [_mm(x), _mm(y), _mm(z)]}
        if heading:
            inst["hpr"] = [_mm(heading), 0.0, 0.0]
        inst["name"] = name
        self.instances.append(inst)


def _mm(v: float) -> float:
    r = round(float(v), 3)
    return 0.0 if r == 0.0 else r


def _airfield(s: _Scene) -> None:
    s.place(s.model("runway", runway()), 0.0, 0.0, "runway 36/18")
    s.place(s.model("taxiways", taxiways()), 0.0, 0.0, "taxiway A and apron")
    # Threshold lights: green units across the threshold, 3 m apart, at both ends.
    xs = [-21.0 + 3.0 * k for k in range(15)]
    s.place(s.model("threshold_lights", light_units(xs, 0.0, 0.0, LIGHT_GREEN, 0.3)), 0.0, -1.0,
            "threshold lights 36")
    s.place("threshold_lights", 0.0, RUNWAY_LENGTH_M + 1.0, "threshold lights 18", 180.0)
    s.place(s.model("papi", papi()), -40.0, 400.0, "PAPI 36")
    # Approach lights: a five-light barrette every 30 m out to 900 m, crossbars every 150 m.
    s.model("barrette", barrette([-2.1 + 1.05 * k for k in range(5)], 1.5))
    for k in range(1, 31):
        s.place("barrette", 0.0, -30.0 * k, f"approach light {30 * k} m")
    for k, half in enumerate((5.0, 8.0, 11.0, 14.0, 17.0)):
        xs = [4.0 + 1.5 * i for i in range(int((half - 4.0) / 1.5) + 1)]
        name = s.model(f"crossbar_{k + 1}", barrette(xs, 1.5))
        y = -150.0 * (k + 1)
        s.place(name, 0.0, y, f"crossbar {150 * (k + 1)} m east")
        s.place(name, 0.0, y, f"crossbar {150 * (k + 1)} m west", 180.0)
    # Buildings east of the apron face west (heading 270); west of the runway face east (90).
    s.model("hangar", gable_building(60.0, 50.0, 14.0, 20.0, "#b7bcc0", "#6f7b85",
                                     door=(48.0, 12.0, "#59626b")))
    for k, y in enumerate((420.0, 500.0, 580.0, 660.0, 740.0)):
        s.place("hangar", 480.0, y, f"hangar {k + 1}", 270.0)
    s.model("terminal", flat_roof_building(220.0, 40.0, 16.0, "#d6d0c2", "#8a8f94",
                                           band=(5.0, 12.0, "#3f566c")))
    s.place("terminal", 470.0, 1350.0, "terminal", 270.0)
    s.place(s.model("control_tower", control_tower()), 520.0, 1800.0, "control tower", 270.0)
    s.model("cargo_shed", gable_building(36.0, 60.0, 9.0, 12.0, "#c8b792", "#5e4034",
                                         door=(12.0, 6.0, "#59626b")))
    for k, y in enumerate((1900.0, 1980.0, 2060.0, 2140.0)):
        s.place("cargo_shed", 470.0, y, f"cargo shed {k + 1}", 270.0)
    s.model("fire_station", flat_roof_building(40.0, 24.0, 8.0, "#d9d4c8", "#7b7f84",
                                               band=(0.0, 5.5, "#b8322a")))
    s.place("fire_station", -160.0, 1200.0, "fire station", 90.0)
    s.model("fuel_tank", fuel_tank())
    for k, x in enumerate((-200.0, -178.0, -156.0)):
        s.place("fuel_tank", x, 1600.0, f"fuel tank {k + 1}")


def _town(s: _Scene, rng: random.Random) -> None:
    """Streets of houses on a jittered grid in each town area, a few blocks, garden trees."""
    variants = []
    for k in range(4):
        name = s.model(f"house_{k + 1}", gable_building(
            9.0 + 2.0 * k, 12.0 + k, 5.0 + 0.5 * (k % 2), 8.0 + 0.5 * k, HOUSE_WALLS[k],
            HOUSE_ROOFS[k % len(HOUSE_ROOFS)]))
        variants.append(name)
    s.model("block", flat_roof_building(30.0, 18.0, 15.0, "#c7b9a3", "#6e6a66",
                                        band=(6.0, 9.0, "#4b5b69")))
    count = 0
    for ax0, ax1, ay0, ay1 in TOWN_AREAS:
        y = ay0 + 20.0
        while y < ay1 - 20.0:
            x = ax0 + 20.0
            while x < ax1 - 20.0:
                count += 1
                if rng.random() < 0.08:
                    s.place("block", x + rng.uniform(-3, 3), y, f"town block {count}",
                            rng.choice((0.0, 90.0)))
                elif rng.random() < 0.85:
                    heading = rng.choice((0.0, 180.0)) + rng.uniform(-4.0, 4.0)
                    s.place(rng.choice(variants), x + rng.uniform(-4, 4), y + rng.uniform(-3, 3),
                            f"house {count}", heading)
                if rng.random() < 0.45:  # a garden tree behind the house
                    _plant(s, rng, rng.choice(("broadleaf", "broadleaf", "conifer", "bush")),
                           x + rng.uniform(-8, 8), y + 14.0 + rng.uniform(-2, 2),
                           f"garden tree {count}")
                x += 48.0
            y += 66.0


def _plant(s: _Scene, rng: random.Random, kind: str, x: float, y: float, name: str) -> None:
    model = f"{kind}_{rng.randrange(len(TREE_GREENS))}"
    s.place(model, x, y, name, rng.uniform(0.0, 360.0))


def _trees(s: _Scene, rng: random.Random) -> None:
    """Tree lines along the runway, woods, hedgerow trees along the field grid."""
    for kind in ("broadleaf", "conifer", "poplar", "bush"):
        for k, colour in enumerate(TREE_GREENS):
            s.model(f"{kind}_{k}", tree(kind, colour))
    n = 0
    for x in (-380.0, 640.0):  # tree lines either side of the airfield
        for y in range(-40, 3241, 30):
            n += 1
            _plant(s, rng, "broadleaf" if n % 3 else "conifer", x + rng.uniform(-3, 3),
                   y + rng.uniform(-5, 5), f"tree line {n}")
    for k in range(-14, 15):  # a poplar row across the far end
        _plant(s, rng, "poplar", 25.0 * k + rng.uniform(-2, 2), 3300.0 + rng.uniform(-2, 2),
               f"poplar {k + 15}")
    woods = ((-1500.0, 900.0, 220.0, 70), (1400.0, 2400.0, 260.0, 80), (-900.0, 4200.0, 300.0, 70),
             (1800.0, 5200.0, 320.0, 50), (-2300.0, 2600.0, 250.0, 40))
    for w, (cx, cy, radius, count) in enumerate(woods):
        for k in range(count):
            r, a = radius * math.sqrt(rng.random()), rng.uniform(0.0, 2.0 * math.pi)
            _plant(s, rng, "conifer" if rng.random() < 0.6 else "broadleaf",
                   cx + r * math.cos(a), cy + r * math.sin(a), f"wood {w + 1} tree {k + 1}")
    # Hedgerow trees along the north-south hedge lines of the field grid, ahead of the eye.
    for x in (-2500.0, -1500.0, -1000.0, 1000.0, 1500.0, 2500.0):
        for y in range(-1000, 6001, 140):
            if rng.random() < 0.45:
                _plant(s, rng, rng.choice(("broadleaf", "bush", "conifer")), x + rng.uniform(-1, 1),
                       y + rng.uniform(-20, 20), f"hedgerow tree {x:g} {y}")


def _terrain(s: _Scene, rng: random.Random) -> None:
    fx0, fx1, fy0, fy1 = FIELDS
    keep_out = (AIRFIELD_AREA,)
    k = 0
    for j in range(int((fy1 - fy0) / TILE_M)):
        for i in range(int((fx1 - fx0) / TILE_M)):
            parts = terrain_tile(rng, fx0 + i * TILE_M, fy0 + j * TILE_M, TILE_M, CELL_M, keep_out)
            if parts:
                k += 1
                s.place(s.model(f"fields_{k}", parts), 0.0, 0.0, f"fields {k}")
    # Roads run in the hedge gaps (6 m wide, centred on grid lines), so they overlap no field;
    # a road reaching the airfield stops at its boundary.
    ax0, ax1, ay0, ay1 = AIRFIELD_AREA
    for y in ROADS_Y:
        spans = [(fx0, ax0), (ax1, fx1)] if ay0 < y < ay1 else [(fx0, fx1)]
        road = painted([(x0, x1, y - 2.5, y + 2.5) for x0, x1 in spans], "#55575a", z=0.0, on=None)
        s.place(s.model(f"road_{y:g}", [road]), 0.0, 0.0, f"road y={y:g}")


def _hills(s: _Scene) -> None:
    shapes = ((21, 1800.0, 420.0), (22, 2400.0, 600.0), (23, 1500.0, 330.0), (24, 2600.0, 650.0),
              (25, 2000.0, 480.0), (26, 1700.0, 380.0), (27, 2200.0, 540.0))
    at = ((-6000.0, 12500.0), (-2500.0, 14000.0), (800.0, 11500.0), (4200.0, 14500.0),
          (7000.0, 12000.0), (-9000.0, 10500.0), (10000.0, 10000.0))
    for k, ((seed, radius, height), (x, y)) in enumerate(zip(shapes, at, strict=True)):
        name = s.model(f"hill_{k + 1}", hill(seed, radius, height, HILL_COLOURS[k % 3]))
        s.place(name, x, y, f"hill {k + 1}")


def approach_scene() -> dict[str, Any]:
    """The scene document (docs/scene-format.md); the same on every call and every machine."""
    s = _Scene()
    _airfield(s)
    _trees(s, random.Random(3601))
    _town(s, random.Random(3602))
    _terrain(s, random.Random(3603))
    _hills(s)
    return {
        "format": "ig-scene/1",
        "name": "approach to runway 36 (bench)",
        "sky": {"colour": SKY},
        "earth": {"colour": GRASS, "height_m": 0.0},
        # Sun in the south-south-west, behind the approaching aircraft.
        "lighting": {"sun_heading_deg": 200.0, "sun_elevation_deg": 35.0, "ambient": 0.4},
        "models": {name: model_doc(parts) for name, parts in s.models.items()},
        "instances": s.instances,
    }




def scene_counts(doc: dict[str, Any]) -> dict[str, int]:
    """Models, instances, and the polygons (faces of all instances) and translucent polygons the
    pipeline transforms per frame before culling."""
    faces = {name: m["faces"] for name, m in doc["models"].items()}
    placed = [faces[i["model"]] for i in doc["instances"]]
    return {
        "models": len(faces),
        "instances": len(placed),
        "polygons": sum(len(f) for f in placed),
        "translucent_polygons": sum(1 for f in placed for face in f
                                    if face.get("opacity", 1.0) < 1.0),
        "painted_polygons": sum(1 for f in placed for face in f if "on" in face),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Print the scene's counts; with --out also write it as a scene file."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the scene JSON here")
    args = parser.parse_args(argv)
    doc = approach_scene()
    print(", ".join(f"{k} {v}" for k, v in scene_counts(doc).items()))
    if args.out is not None:
        args.out.write_text(json.dumps(doc) + "\n", encoding="utf-8")
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
