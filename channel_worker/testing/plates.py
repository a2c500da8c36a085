"""Flat plates facing the eye at distinct depths: a scene whose visibility order is known, so
its exact box-filtered image can be computed (coverage_reference.py). Shared by the accuracy
tests and the bench's speed-against-exact-error figure."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

# (outline in units of the plate's distance from the eye, rotation in degrees, centre,
#  distance from the eye in metres, sRGB colour, opacity), nearest last.
PLATES = [
    ([[-0.35, -0.2], [0.35, -0.2], [0.35, 0.2], [-0.35, 0.2]], 17, (-0.1, 0.05), 60, "#f0f0f0", 1.0),
    ([[0.0, 0.3], [-0.25, -0.15], [0.3, -0.2]], 8, (0.25, -0.1), 50, "#e02020", 1.0),
    ([[-0.15, -0.15], [0.15, -0.15], [0.15, 0.15], [-0.15, 0.15]], 33, (-0.3, -0.2), 40, "#20c040", 1.0),
    # Slivers: about a third and half a pixel wide, longer than the raster.
    ([[-0.45, 0.0], [0.45, 0.0], [0.45, 0.004]], 3, (0.0, 0.1), 35, "#ffff00", 1.0),
    ([[-0.3, 0.0], [0.3, 0.0], [0.3, 0.006]], 71, (0.1, 0.0), 34, "#000000", 1.0),
    ([[0.0, 0.05], [-0.04, -0.03], [0.05, -0.02]], 0, (0.35, 0.25), 30, "#2040ff", 1.0),
    ([[-0.2, -0.12], [0.2, -0.12], [0.2, 0.12], [-0.2, 0.12]], -23, (0.05, -0.05), 20, "#ff00ff", 0.5),
    ([[-0.1, -0.3], [0.1, -0.3], [0.1, 0.3], [-0.1, 0.3]], 52, (-0.15, 0.15), 15, "#00ffff", 0.35),
]


def plates_model(place: Callable[[float, float, float], tuple]) -> dict:
    """One model of flat plates; place(u, v, distance) -> world point; faces towards the eye."""
    verts: list[list[float]] = []
    faces: list[dict] = []
    for outline, deg, (cu, cv), dist, colour, opacity in PLATES:
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        pts = [place(cu + c * u - s * v, cv + s * u + c * v, dist) for u, v in outline]
        a = np.array(pts)
        # Counter-clockwise seen from the eye at the origin: the normal points back at it.
        if np.dot(np.cross(a[1] - a[0], a[2] - a[0]), a[0]) > 0:
            pts = pts[::-1]
        faces.append({"indices": list(range(len(verts), len(verts) + len(pts))), "colour": colour,
                      **({"opacity": opacity} if opacity < 1.0 else {})})
        verts += [list(p) for p in pts]
    return {"vertices": verts, "faces": faces}




def overhead_scene_doc(sky: str = "#3060c0", earth: str = "#406020") -> dict:
    """The plates overhead, for an eye at (0, 0, 1.5) looking straight up (overhead_eyepoint)."""
    return {
        "format": "ig-scene/1",
        "sky": {"colour": sky},
        "earth": {"colour": earth, "height_m": 0.0},
        "lighting": {"ambient": 1.0},
        "models": {"plates": plates_model(lambda u, v, d: (u * d, v * d, d))},
        "instances": [{"model": "plates", "position": [0.0, 0.0, 1.5]}],
    }


#: Where overhead_scene_doc's plates are seen from: x, y, z metres and heading, pitch, roll.
OVERHEAD_EYEPOINT = (0.0, 0.0, 1.5, 0.0, 90.0, 0.0)
