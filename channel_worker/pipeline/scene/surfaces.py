"""Face surfaces: texture codes and smooth (Gouraud) shading, as the scene database holds them.

A face's look is one row of the database's look table (LOOK_* columns): the texture code of the
texture patent *An image generator* (up to three textures in priority order, the overall
intensity, the primary texture's x and y scales, the secondary and tertiary textures' common
scales and offset, their amplitudes relative to the overall intensity, the modulation of all
colours by one signal or of each colour by its own) and whether the face is shaded smoothly.
Faces that share a texture code and a smoothness share a row.

Per face the database keeps what the per-frame stages need to place the look on the screen:

- the texture map: the face's point P (model metres) lies at texture-plane coordinates
  u = U . P + ku, v = V . P + kv (metres), U and V unit vectors in the face's plane. This is the
  patent's rotation of the face into the texture plane and translation to its origin, in one
  affine map; faces of one surface that share the origin and the axes (the default: the model's
  origin and x, y axes projected into each face) continue one texture across their shared edges.
- for smooth faces (always triangles: a smooth polygon is split into a fan when loaded), the
  vertex normals and the dual basis (h1, h2) of the triangle's edges: the light, Lambert at each
  vertex, is then the linear function L(P) = L0 + (L1 - L0) h1 . (P - V0) + (L2 - L0) h2 .
  (P - V0) over the face, which the projection turns into a perspective-correct screen
  function. Gouraud shading (H. Gouraud, *Continuous shading of curved surfaces*, 1971)
  interpolated this way does not depend on how the screen is rotated; interpolation along scan
  lines over a quadrilateral does, as ARL Systems Note 77 observes, which is why smooth
  polygons are triangulated.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

#: Columns of the look table (Database.looks), one float64 row per distinct look.
LOOK_SMOOTH = 0  # 1: Gouraud shading (the face's light varies over it)
LOOK_TEXTURE = 1  # 3 columns: texture store index of the primary, secondary, tertiary (-1: none)
LOOK_INTENSITY = 4  # the overall intensity of the texture signal
LOOK_PRIMARY = 5  # 2 columns: the primary texture's repeats per metre along u and v
LOOK_DETAIL = 7  # 2 columns: the secondary and tertiary textures' repeats per metre
LOOK_OFFSET = 9  # 2 columns: their offset from the primary along u and v, metres
LOOK_AMPLITUDE = 11  # 2 columns: their amplitudes, shares of the overall intensity
LOOK_PER_COLOUR = 13  # 1: each colour modulated by its own signal (hue changes); 0: one signal
LOOK_SLOTS = 14

#: Most textures one code combines (the patent's primary, secondary and tertiary).
MAX_CODE_TEXTURES = 3

#: Faces of a smooth model whose normals differ by more than this share no vertex normal
#: (the model's edge is a crease), unless the model says otherwise.
DEFAULT_CREASE_DEG = 50.0


class FaceSurfaces(NamedTuple):
    """Per face: its look and the terms that place it on the screen (model frame).

    Attributes:
        look: (F,) int32 row of Database.looks, -1 for a plain face (one flat colour).
        tex_map: (F, 2, 4) float64 rows (Ux, Uy, Uz, ku) and (Vx, Vy, Vz, kv): texture-plane
            coordinates u = U . P + ku, v = V . P + kv, metres, of model point P.
        normals: (F, 3, 3) float64 the unit vertex normals at a smooth face's three corners.
        basis: (F, 3, 3) float64 rows h1, h2 (the dual basis of the edges V1 - V0, V2 - V0 in
            the face's plane) and V0, for smooth faces.
    """

    look: np.ndarray
    tex_map: np.ndarray
    normals: np.ndarray
    basis: np.ndarray

    @staticmethod
    def concatenate(parts: Sequence[FaceSurfaces]) -> FaceSurfaces:
        if not parts:
            return plain_surfaces(0)
        return FaceSurfaces(*(np.concatenate([getattr(p, name) for p in parts])
                              for name in FaceSurfaces._fields))


def plain_surfaces(count: int) -> FaceSurfaces:
    """The surfaces of count plain faces."""
    return FaceSurfaces(np.full(count, -1, np.int32), np.zeros((count, 2, 4)),
                        np.zeros((count, 3, 3)), np.zeros((count, 3, 3)))


def texture_axes(normal: np.ndarray, u_hint: np.ndarray | None = None,
                 rotation_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The texture plane's unit axes (U, V) in a face of unit normal `normal`: U the
    projection of u_hint into the face (default: the model's x axis, or its y axis where x
    runs nearly along the normal), V = normal x U, both turned by rotation_deg about the
    normal (the texture code's orientation).

    Raises:
        ValueError: u_hint runs along the normal (no direction in the face).
    """
    n = np.asarray(normal, np.float64)
    hints = [np.asarray(u_hint, np.float64)] if u_hint is not None else [np.array([1.0, 0.0, 0.0]),
                                                                           np.array([0.0, 1.0, 0.0])]
    for hint in hints:
        u = hint - (hint @ n) * n
        length = float(np.linalg.norm(u))
        # Guard: a hint within ~60 degrees of the normal leaves too short a projection to
        # define an axis well; the default then tries the model's y axis (never both short).
        if length >= 0.5 * float(np.linalg.norm(hint)) or (u_hint is not None and length > 1e-9):
            u = u / length
            break
    else:
        raise ValueError(f"u_axis {hints[0].tolist()} runs along the face's normal {n.tolist()}")
    v = np.cross(n, u)
    c, s = math.cos(math.radians(rotation_deg)), math.sin(math.radians(rotation_deg))
    return c * u + s * v, -s * u + c * v


def gouraud_basis(corners: np.ndarray) -> np.ndarray:
    """(3, 3) rows h1, h2, V0 of a triangle (corners (3, 3)): h1 . (Vk - V0) = [k == 1],
    h2 . (Vk - V0) = [k == 2], both in the triangle's plane.

    Guard: the Gram determinant of the two edges is positive for a triangle with area (the
    loader refuses faces without area), checked against rounding anyway.
    """
    v0 = corners[0]
    e1 = corners[1] - v0
    e2 = corners[2] - v0
    g11, g12, g22 = e1 @ e1, e1 @ e2, e2 @ e2
    det = g11 * g22 - g12 * g12
    if not det > 1e-24 * max(g11 * g22, 1e-300):
        raise ValueError("the triangle has no area")
    h1 = (g22 * e1 - g12 * e2) / det
    h2 = (g11 * e2 - g12 * e1) / det
    return np.stack([h1, h2, v0])


def vertex_normals(vertices: np.ndarray, faces: Sequence[Sequence[int]], normals: np.ndarray,
                   crease_deg: float) -> list[np.ndarray]:
    """Per face, the unit normal at each of its corners: the area-weighted mean of the normals
    of the faces meeting at that vertex whose normal lies within crease_deg of this face's."""
    areas = np.array([_area(vertices[list(f)]) for f in faces])
    users: dict[int, list[int]] = {}
    for k, face in enumerate(faces):
        for v in face:
            users.setdefault(v, []).append(k)
    cos_crease = math.cos(math.radians(crease_deg))
    out = []
    for k, face in enumerate(faces):
        corner = np.empty((len(face), 3))
        for i, v in enumerate(face):
            total = np.zeros(3)
            for j in users[v]:
                if normals[j] @ normals[k] >= cos_crease - 1e-12:
                    total += areas[j] * normals[j]
            # Guard: face k itself is always in the sum with a positive area and a unit
            # normal, and the others lie within 90 degrees of it at most... unless the crease
            # is wider than 90 degrees and normals cancel: fall back to the face's own normal.
            length = float(np.linalg.norm(total))
            corner[i] = total / length if length > 1e-12 * areas[k] else normals[k]
        out.append(corner)
    return out


def _area(pts: np.ndarray) -> float:
    nxt = np.roll(pts, -1, axis=0)
    return 0.5 * float(np.linalg.norm(np.cross(pts, nxt).sum(axis=0)))


class CodeParser:
    """Reads the scene's "texture_codes" (docs/scene-format.md) and hands out look rows.

    fail(where, message) makes the loader's error (it names the file); number(value, where,
    lo, hi) its checked number; `textures` maps each texture name of the scene to its store
    index.
    """

    def __init__(self, fail: Callable[[str, str], Exception], number: Callable[..., float],
                 textures: dict[str, int]) -> None:
        self.fail = fail
        self.number = number
        self.textures = textures
        self.codes: dict[str, tuple[np.ndarray, float]] = {}
        self.rows: list[np.ndarray] = []
        self.index: dict[tuple[str, bool], int] = {}

    def parse(self, doc: Any) -> None:
        if doc is None:
            return
        if not isinstance(doc, dict):
            raise self.fail("texture_codes", "expected an object of texture codes")
        for name, code in doc.items():
            self.codes[name] = self.code(code, f"texture_codes.{name}")

    def code(self, doc: Any, where: str) -> tuple[np.ndarray, float]:
        """(look row without the smooth flag, rotation in degrees) of one texture code."""
        keys = {"textures", "intensity", "scale_m", "detail_scale_m", "detail_offset_m",
                "amplitudes", "modulation", "rotation_deg"}
        if not isinstance(doc, dict):
            raise self.fail(where, "expected an object")
        for key in doc:
            if key not in keys:
                raise self.fail(f"{where}.{key}", "unknown key")
        names = doc.get("textures")
        if (not isinstance(names, list) or not 1 <= len(names) <= MAX_CODE_TEXTURES
                or not all(isinstance(n, str) for n in names)):
            raise self.fail(f"{where}.textures", f"expected 1 to {MAX_CODE_TEXTURES} texture names "
                                                 f"(primary first), got {names!r}"[:200])
        row = np.zeros(LOOK_SLOTS)
        row[LOOK_TEXTURE:LOOK_TEXTURE + MAX_CODE_TEXTURES] = -1.0
        for i, name in enumerate(names):
            if name not in self.textures:
                raise self.fail(f"{where}.textures[{i}]", f"{name!r} is not a texture of this scene")
            row[LOOK_TEXTURE + i] = self.textures[name]
        row[LOOK_INTENSITY] = self.number(doc.get("intensity", 1.0), f"{where}.intensity", 0.0, 4.0)
        scale = self.pair(doc.get("scale_m", [10.0, 10.0]), f"{where}.scale_m")
        detail = self.pair(doc.get("detail_scale_m", [s * 4.0 for s in scale]), f"{where}.detail_scale_m")
        # Guard: pair() refuses scales outside [1e-3, 1e6] m, so the repeats are finite.
        row[LOOK_PRIMARY:LOOK_PRIMARY + 2] = [1.0 / scale[0], 1.0 / scale[1]]
        row[LOOK_DETAIL:LOOK_DETAIL + 2] = [1.0 / detail[0], 1.0 / detail[1]]
        offset = doc.get("detail_offset_m", [0.0, 0.0])
        if not isinstance(offset, list) or len(offset) != 2:
            raise self.fail(f"{where}.detail_offset_m", f"expected [du, dv], got {offset!r}"[:200])
        row[LOOK_OFFSET:LOOK_OFFSET + 2] = [self.number(o, f"{where}.detail_offset_m[{i}]", -1e6, 1e6)
                                            for i, o in enumerate(offset)]
        amps = doc.get("amplitudes", [0.5, 0.25])
        if not isinstance(amps, list) or len(amps) != 2:
            raise self.fail(f"{where}.amplitudes", f"expected [secondary, tertiary], got {amps!r}"[:200])
        row[LOOK_AMPLITUDE:LOOK_AMPLITUDE + 2] = [self.number(a, f"{where}.amplitudes[{i}]", 0.0, 4.0)
                                                  for i, a in enumerate(amps)]
        modulation = doc.get("modulation", "mono")
        if modulation not in ("mono", "colour"):
            raise self.fail(f"{where}.modulation", f"expected \"mono\" or \"colour\", got {modulation!r}"[:200])
        row[LOOK_PER_COLOUR] = 1.0 if modulation == "colour" else 0.0
        rotation = self.number(doc.get("rotation_deg", 0.0), f"{where}.rotation_deg", -360.0, 360.0)
        return row, rotation

    def pair(self, value: Any, where: str) -> list[float]:
        if not isinstance(value, list) or len(value) != 2:
            raise self.fail(where, f"expected [along u, along v] in metres, got {value!r}"[:200])
        return [self.number(v, f"{where}[{i}]", 1e-3, 1e6) for i, v in enumerate(value)]

    def look(self, code: str | None, smooth: bool, where: str) -> tuple[int, float]:
        """(row of the look table, texture rotation in degrees) of a face; -1 for a plain one."""
        if code is None and not smooth:
            return -1, 0.0
        if code is not None and code not in self.codes:
            raise self.fail(where, f"{code!r} is not a texture code of this scene"[:200])
        key = (code or "", smooth)
        if key not in self.index:
            if code is None:
                row = np.zeros(LOOK_SLOTS)
                row[LOOK_TEXTURE:LOOK_TEXTURE + MAX_CODE_TEXTURES] = -1.0
            else:
                row = self.codes[code][0].copy()
            row[LOOK_SMOOTH] = 1.0 if smooth else 0.0
            self.index[key] = len(self.rows)
            self.rows.append(row)
        return self.index[key], self.codes[code][1] if code is not None else 0.0

    def table(self) -> np.ndarray:
        """The look table (a one-row stand-in when no face has a look)."""
        return np.array(self.rows) if self.rows else np.zeros((1, LOOK_SLOTS))
