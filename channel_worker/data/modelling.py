"""A small polygon modelling toolkit for writing scene documents (docs/scene-format.md).

A model is a list of parts. A part is one of two things:

- a piece of a convex solid: every face's outward normal points away from the centroid of the
  part's vertices (a box, a prism, a pyramid, a hill);
- a decal: flat paint whose every face points one given way, the part's `facing` (markings on
  a runway, a door on a wall), usually declared "on" a face of the model it is painted on.

Faces are wound counter-clockwise seen from the front, so the right-hand (Newell) normal points
out of the model; the renderer draws only the front. The helpers below (ground_rect,
ground_rects, wall_rect, loft, prism, box, pyramid, dome) wind faces that way by construction,
and make_part() checks every face before a part exists: at least three distinct vertices, a
non-zero area, every vertex within a millimetre of the face's plane, strictly convex, and
pointing outwards (solids) or along `facing` (decals). A mistake therefore stops the generator
instead of reaching the renderer as a missing or inside-out polygon.

Vertices are rounded to millimetres when a part is made, and documents are written with a fixed
layout (render_json), so a generated file is the same, byte for byte, on every machine.

Units are metres and degrees. Part vertices are in the model frame (x right, y forward, z up),
which is the world frame (x east, y north, z up) for an instance at heading = pitch = roll = 0.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

Vec3 = tuple[float, float, float]

#: Vertex coordinates are rounded to this many decimals of a metre.
_DECIMALS = 3
#: A face vertex may lie this far off the face's plane after rounding, metres.
_PLANE_TOL_M = 1e-3


@dataclass(frozen=True)
class Face:
    """One polygon of a part; indices into the part's vertices, counter-clockwise from outside."""

    indices: tuple[int, ...]
    colour: str
    opacity: float = 1.0
    #: Index, within the model, of the face this one is painted on (scene "on"), and its layer.
    on: int | None = None
    layer: int = 1
    #: Name of the scene's texture code the face wears (scene "texture"), or None.
    texture: str | None = None


@dataclass(frozen=True)
class Part:
    """A convex piece of a model, or a decal.

    Attributes:
        vertices: model coordinates, metres (x right, y forward, z up), rounded to millimetres.
        faces: the part's polygons.
        facing: None for a piece of a convex solid (every face points away from the centroid of
            the part's vertices); for a decal, the unit vector every face's normal equals.
    """

    vertices: tuple[Vec3, ...]
    faces: tuple[Face, ...]
    facing: Vec3 | None = None


@dataclass(frozen=True)
class Instance:
    """One placement of a model.

    Attributes:
        model: name of the model placed.
        position: world position of the model's origin, metres (x east, y north, z up).
        name: unique name of the instance.
        hpr: heading, pitch, roll in degrees, applied in that order (docs/conventions.md).
    """

    model: str
    position: Vec3
    name: str
    hpr: Vec3 = (0.0, 0.0, 0.0)


class GeometryError(ValueError):
    """A part whose faces break the scene format or point the wrong way."""


# ---------------------------------------------------------------------------------------------
# Vector helpers (plain tuples: the generator is small and must be exact and repeatable).

def _sub(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _mean(points: Sequence[Sequence[float]]) -> Vec3:
    n = len(points)
    return (sum(p[0] for p in points) / n, sum(p[1] for p in points) / n,
            sum(p[2] for p in points) / n)


def _vec3(v: Sequence[float]) -> Vec3:
    if len(v) != 3:
        raise GeometryError(f"{tuple(v)} is not a 3-vector")
    return (float(v[0]), float(v[1]), float(v[2]))


def newell_normal(points: Sequence[Sequence[float]]) -> Vec3:
    """Unit normal of a polygon by Newell's method.

    Args:
        points: the polygon's vertices (x, y, z), in order, in any one frame.

    Returns:
        The right-handed unit normal, in the points' frame: it points towards a viewer who sees
        the points counter-clockwise.

    Raises:
        GeometryError: the polygon has no area.
    """
    nx = ny = nz = 0.0
    for i, p in enumerate(points):
        q = points[(i + 1) % len(points)]
        nx += (p[1] - q[1]) * (p[2] + q[2])
        ny += (p[2] - q[2]) * (p[0] + q[0])
        nz += (p[0] - q[0]) * (p[1] + q[1])
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length < 1e-9:
        raise GeometryError(f"polygon {points} has no area")
    return (nx / length, ny / length, nz / length)


def round_mm(v: float) -> float:
    """Round a coordinate in metres to millimetres, as every written coordinate is.

    Args:
        v: a coordinate, metres.

    Returns:
        v rounded to three decimals; never -0.0, which would be written as "-0.0".
    """
    r = round(v, _DECIMALS)
    return 0.0 if r == 0.0 else r


# ---------------------------------------------------------------------------------------------
# Parts. Every helper returns a checked Part.

def make_part(vertices: Iterable[Sequence[float]], faces: Iterable[Face], *,
              facing: Sequence[float] | None = None) -> Part:
    """Round the vertices to millimetres and check every face.

    Args:
        vertices: model coordinates (x right, y forward, z up), metres.
        faces: polygons indexing `vertices`, each counter-clockwise seen from outside.
        facing: None for a piece of a convex solid; for a decal, the unit vector (model frame)
            every face's normal must equal.

    Returns:
        The checked part.

    Raises:
        GeometryError: a face is degenerate, not planar, not strictly convex, or faces inwards
            (solids) or not along `facing` (decals).
    """
    verts = tuple((round_mm(p[0]), round_mm(p[1]), round_mm(p[2])) for p in vertices)
    part = Part(verts, tuple(faces), None if facing is None else _vec3(facing))
    centroid = _mean(verts)
    for k, face in enumerate(part.faces):
        pts = [verts[i] for i in face.indices]
        if len(set(face.indices)) != len(pts) or len(pts) < 3:
            raise GeometryError(f"face {k}: indices {face.indices} are not >= 3 distinct vertices")
        n = newell_normal(pts)
        centre = _mean(pts)
        off_plane = max(abs(_dot(_sub(p, centre), n)) for p in pts)
        if off_plane > _PLANE_TOL_M:
            raise GeometryError(f"face {k}: a vertex lies {off_plane:.4g} m off the plane")
        for i in range(len(pts)):
            e0 = _sub(pts[(i + 1) % len(pts)], pts[i])
            e1 = _sub(pts[(i + 2) % len(pts)], pts[(i + 1) % len(pts)])
            if _dot(_cross(e0, e1), n) <= 1e-9:
                raise GeometryError(f"face {k}: not strictly convex at vertex {face.indices[i]}")
        if part.facing is None:
            if _dot(n, _sub(centre, centroid)) <= 0.0:
                raise GeometryError(f"face {k}: normal {n} points into the solid")
        elif _dot(n, part.facing) < 1.0 - 1e-6:
            raise GeometryError(f"face {k}: normal {n} is not {part.facing}")
    return part


def ground_rect(x0: float, x1: float, y0: float, y1: float, z: float, colour: str) -> Part:
    """A rectangle lying flat at height z, facing up (+z): a decal.

    Args:
        x0, x1, y0, y1: its extent in the model frame, metres; x0 < x1, y0 < y1.
        z: its height, metres.
        colour: sRGB "#rrggbb".
    """
    return make_part([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)],
                     [Face((0, 1, 2, 3), colour)], facing=(0.0, 0.0, 1.0))


def ground_rects(rects: Iterable[tuple[float, float, float, float]], z: float, colour: str, *,
                 on: int | None = None) -> Part:
    """Several disjoint rectangles lying flat at height z, facing up (+z), as one decal part.

    Args:
        rects: (x0, x1, y0, y1) of each, model frame, metres; x0 < x1, y0 < y1.
        z: their height, metres.
        colour: sRGB "#rrggbb".
        on: index of the model face they are painted on (layer 1 above it), or None for a base
            surface.
    """
    vertices: list[Vec3] = []
    faces = []
    for x0, x1, y0, y1 in rects:
        base = len(vertices)
        vertices += [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
        faces.append(Face((base, base + 1, base + 2, base + 3), colour, on=on))
    return make_part(vertices, faces, facing=(0.0, 0.0, 1.0))


def wall_rect(x0: float, x1: float, z0: float, z1: float, y: float, colour: str, *,
              on: int | None = None) -> Part:
    """A rectangle on the plane y = const facing +y (a door or window band on a front wall).

    Args:
        x0, x1, z0, z1: its extent in the model frame, metres; x0 < x1, z0 < z1.
        y: the plane it lies in, metres.
        colour: sRGB "#rrggbb".
        on: index of the model face (the wall) it is painted on, or None.
    """
    # Seen from +y the x axis points left, so counter-clockwise runs from +x to -x along the bottom.
    return make_part([(x1, y, z0), (x0, y, z0), (x0, y, z1), (x1, y, z1)],
                     [Face((0, 1, 2, 3), colour, on=on)], facing=(0.0, 1.0, 0.0))


def facing_face(part: Part, direction: Sequence[float]) -> int:
    """Index of the part's face whose outward normal is `direction` (the wall to paint on).

    Args:
        part: the part to search.
        direction: a unit vector in the model frame.

    Raises:
        GeometryError: no face of the part points that way.
    """
    for k, face in enumerate(part.faces):
        n = newell_normal([part.vertices[i] for i in face.indices])
        if _dot(n, direction) > 1.0 - 1e-9:
            return k
    raise GeometryError(f"no face of the part faces {tuple(direction)}")


def loft(a: Sequence[Vec3], b: Sequence[Vec3], side_colours: str | Sequence[str | None], *,
         cap_a: str | None = None, cap_b: str | None = None, opacity: float = 1.0) -> Part:
    """A convex solid between two corresponding loops a and b (a prism, frustum or extrusion).

    Both loops run counter-clockwise seen from beyond b looking back towards a (for a vertical
    prism: counter-clockwise seen from above, a the bottom). Side i joins edge i -> i+1 of a to
    the same edge of b and must be planar.

    Args:
        a, b: the loops, model frame, metres, the same number of vertices each.
        side_colours: side i's colour is side_colours[i] (None leaves the side out), or one
            colour for every side.
        cap_a, cap_b: colours of the end faces; None leaves them out.
        opacity: of the sides, 0..1.

    Raises:
        GeometryError: the loops differ in length, or a face fails make_part's checks.
    """
    n = len(a)
    if len(b) != n:
        raise GeometryError(f"loops of {len(a)} and {len(b)} vertices")
    colours = [side_colours] * n if isinstance(side_colours, str) else list(side_colours)
    faces = [Face((i, (i + 1) % n, n + (i + 1) % n, n + i), c, opacity)
             for i, c in enumerate(colours) if c is not None]
    if cap_b is not None:
        faces.append(Face(tuple(range(n, 2 * n)), cap_b))
    if cap_a is not None:
        faces.append(Face(tuple(reversed(range(n))), cap_a))
    return make_part(list(a) + list(b), faces)


def prism(base: Sequence[tuple[float, float]], z0: float, z1: float,
          side_colours: str | Sequence[str | None], *, top: str | None = None,
          bottom: str | None = None, opacity: float = 1.0) -> Part:
    """A vertical prism over a convex base polygon.

    Args:
        base: (x, y) corners counter-clockwise from above, model frame, metres.
        z0, z1: heights of the bottom and top, metres; z0 < z1.
        side_colours: as for loft().
        top, bottom: colours of the caps; None leaves them out.
        opacity: of the sides, 0..1.
    """
    return loft([(x, y, z0) for x, y in base], [(x, y, z1) for x, y in base], side_colours,
                cap_a=bottom, cap_b=top, opacity=opacity)


def box(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, walls: str, *,
        top: str | None = None, bottom: str | None = None) -> Part:
    """An axis-aligned box.

    Args:
        x0, x1, y0, y1, z0, z1: its extent in the model frame, metres; each low < high.
        walls: colour of the four sides.
        top, bottom: colours of the top and bottom; None leaves them out.
    """
    return prism(rect(x0, x1, y0, y1), z0, z1, walls, top=top, bottom=bottom)


def pyramid(base: Sequence[Vec3], apex: Vec3, colour: str, *, bottom: str | None = None) -> Part:
    """A pyramid over a convex planar base.

    Args:
        base: the base's corners, counter-clockwise seen from the apex's side, model frame,
            metres.
        apex: model frame, metres.
        colour: of the sides.
        bottom: colour of the base face; None leaves it out.
    """
    n = len(base)
    faces = [Face((i, (i + 1) % n, n), colour) for i in range(n)]
    if bottom is not None:
        faces.append(Face(tuple(reversed(range(n))), bottom))
    return make_part(list(base) + [apex], faces)


def rect(x0: float, x1: float, y0: float, y1: float) -> list[tuple[float, float]]:
    """Rectangle corners (x, y), metres, counter-clockwise seen from above (+z)."""
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def ngon(cx: float, cy: float, radius: float, n: int, *, phase_deg: float = 0.0,
         z: float | None = None) -> list:
    """A regular polygon, counter-clockwise seen from above (+z).

    Args:
        cx, cy: its centre, metres.
        radius: centre to each vertex, metres.
        n: number of vertices.
        phase_deg: angle of the first vertex, degrees counter-clockwise from +x.
        z: with z given the points are (x, y, z) triples at that height, otherwise (x, y) pairs.
    """
    pts = []
    for i in range(n):
        a = math.radians(phase_deg + 360.0 * i / n)
        x, y = cx + radius * math.cos(a), cy + radius * math.sin(a)
        pts.append((x, y) if z is None else (x, y, z))
    return pts


def square(half: float, z: float) -> list[Vec3]:
    """A square about the z axis at height z, counter-clockwise seen from above (+z).

    Args:
        half: half its side, metres.
        z: its height, metres.
    """
    return [(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)]


def dome(rings: Sequence[Sequence[Vec3]], apex: Vec3, colours: Sequence[str]) -> Part:
    """A hill: triangles between successive rings and a fan up to the apex.

    Triangles are always planar, so the rings may be irregular.

    Args:
        rings: loops of the same vertex count, each counter-clockwise from above, bottom first;
            model frame, metres.
        apex: model frame, metres.
        colours: colours[k] paints band k, between ring k and ring k + 1; the last paints the fan.
    """
    n = len(rings[0])
    vertices = [p for ring in rings for p in ring] + [apex]
    faces = []
    for k in range(len(rings) - 1):
        lo, hi = k * n, (k + 1) * n
        for i in range(n):
            j = (i + 1) % n
            faces.append(Face((lo + i, lo + j, hi + j), colours[k]))
            faces.append(Face((lo + i, hi + j, hi + i), colours[k]))
    top = (len(rings) - 1) * n
    faces += [Face((top + i, top + (i + 1) % n, len(vertices) - 1), colours[-1]) for i in range(n)]
    return make_part(vertices, faces)


# ---------------------------------------------------------------------------------------------
# Scene documents.

def textured(part: Part, code: str, *, colours: Sequence[str] | None = None) -> Part:
    """The part with its faces wearing texture code `code` (those of the given colours only,
    when colours is given: a wall's texture, not its door's)."""
    faces = tuple(dataclasses.replace(f, texture=code) if colours is None or f.colour in colours else f
                  for f in part.faces)
    return dataclasses.replace(part, faces=faces)


def model_doc(parts: Sequence[Part], *, smooth: bool = False) -> dict[str, Any]:
    """One model's JSON data.

    Args:
        parts: the model's parts, in order.
        smooth: shade the model smoothly (scene "smooth": Gouraud, across edges up to the
            loader's crease angle).

    Returns:
        {"vertices", "faces"}: the parts' vertices concatenated (model frame, metres) and their
        faces with indices rebased. A face's "on" is an index among the model's faces in the
        order the parts list them.
    """
    vertices: list[list[float]] = []
    faces: list[dict[str, Any]] = []
    for part in parts:
        base = len(vertices)
        vertices += [list(v) for v in part.vertices]
        for f in part.faces:
            face: dict[str, Any] = {"indices": [base + i for i in f.indices], "colour": f.colour}
            if f.opacity != 1.0:
                face["opacity"] = f.opacity
            if f.on is not None:
                face["on"] = f.on
                face["layer"] = f.layer
            if f.texture is not None:
                face["texture"] = f.texture
            faces.append(face)
    doc: dict[str, Any] = {"vertices": vertices, "faces": faces}
    if smooth:
        doc["smooth"] = True
    return doc


def instance_doc(inst: Instance) -> dict[str, Any]:
    """One instance's JSON data: model, world position (metres), hpr (degrees; left out when all
    zero) and name."""
    doc: dict[str, Any] = {"model": inst.model, "position": [float(c) for c in inst.position]}
    if any(inst.hpr):
        doc["hpr"] = [float(a) for a in inst.hpr]
    doc["name"] = inst.name
    return doc


def render_json(doc: Any) -> str:
    """A document as JSON text, one vertex, face or instance per line, so diffs stay readable.

    Args:
        doc: plain JSON data (dicts, lists, strings, numbers, None).

    Returns:
        The text, ending in a newline; the same for the same data on every machine.
    """
    return _dump(doc, 0) + "\n"


def _dump(value: Any, indent: int) -> str:
    if _is_leafy(value):
        return json.dumps(value, ensure_ascii=False)
    pad, inner = " " * indent, " " * (indent + 2)
    if isinstance(value, dict):
        items = [f"{inner}{json.dumps(k)}: {_dump(v, indent + 2)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    items = [inner + _dump(v, indent + 2) for v in value]
    return "[\n" + ",\n".join(items) + "\n" + pad + "]"


def _is_leafy(value: Any) -> bool:
    """Whether a value goes on one line: a scalar, a list of scalars, or a small object of those
    (a face, an instance, the lighting: at most _LEAF_KEYS keys)."""
    def scalar_or_flat(v: Any) -> bool:
        return not isinstance(v, (dict, list)) or (
            isinstance(v, list) and all(not isinstance(x, (dict, list)) for x in v))
    if isinstance(value, dict):
        return len(value) <= _LEAF_KEYS and all(scalar_or_flat(v) for v in value.values())
    return scalar_or_flat(value)


#: An instance has at most four keys (model, position, hpr, name); larger objects are spread out.
_LEAF_KEYS = 4


def _loaded_faces(model: dict[str, Any]) -> list[dict[str, Any]]:
    """A model document's faces as the scene loader holds them: a smooth model's as triangles."""
    if not model.get("smooth"):
        return list(model["faces"])
    return [face for face in model["faces"] for _ in range(len(face["indices"]) - 2)]


def statistics(doc: dict[str, Any]) -> dict[str, int]:
    """Counts that describe a scene document.

    Args:
        doc: a scene document with "models" and "instances".

    Returns:
        "models", "model_faces" (faces over all models), "instances", "instance_faces" and
        "translucent_faces" (faces, and faces with opacity < 1, over all instances together:
        what the pipeline transforms per frame). A smooth model's faces count as the triangles
        the loader splits them into.
    """
    faces = {name: _loaded_faces(m) for name, m in doc["models"].items()}
    placed = [faces[i["model"]] for i in doc["instances"]]
    return {
        "models": len(faces),
        "model_faces": sum(len(f) for f in faces.values()),
        "instances": len(placed),
        "instance_faces": sum(len(f) for f in placed),
        "translucent_faces": sum(1 for f in placed for face in f if face.get("opacity", 1.0) < 1.0),
    }
