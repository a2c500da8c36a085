"""Random eye-facing quads at distinct depths: the exact-coverage scene of the edge
anti-aliasing figures (bench_visibility.py's "quads" case, the coverage tests).

Like plates.py, every quad faces the eye and no two share a depth, so the visibility order is
known and coverage_reference.py computes the exact box-filtered image. Unlike the eight
hand-placed plates, the quads are many and random (seeded): convex quadrilaterals of every
size from a few pixels to a fifth of the picture, at every edge direction, opaque, colours
uniform in [0, 1] linear, in front of a plain sky. The eye looks straight up, so no earth is
in view.
"""

from __future__ import annotations

import numpy as np

#: Where quads_scene_doc's quads are seen from: x, y, z metres and heading, pitch, roll.
QUADS_EYEPOINT = (0.0, 0.0, 1.5, 0.0, 90.0, 0.0)
#: Horizontal field of view of the quads' channel, degrees (square pixels).
QUADS_FOV_DEG = 60.0


def quads_model(count: int, seed: int) -> dict:
    """One model of `count` convex quads facing an eye at the origin looking along +z.

    A quad is four points at sorted random angles on a random ellipse (points on an ellipse
    are always in convex position), its half-size log-uniform from 0.004 to 0.12 in units of
    its distance (2 to 70 pixels at 640 across 60 degrees), centred anywhere in view, at
    distance 20 + 0.25 k metres for a shuffled k: distinct depths.
    """
    rng = np.random.default_rng(seed)
    tan_h = np.tan(np.radians(QUADS_FOV_DEG / 2.0))
    depth = 20.0 + 0.25 * rng.permutation(count)
    verts: list[list[float]] = []
    faces: list[dict] = []
    for k in range(count):
        centre = rng.uniform([-tan_h, -0.75 * tan_h], [tan_h, 0.75 * tan_h])
        size = float(np.exp(rng.uniform(np.log(0.004), np.log(0.12))))
        axes = size * np.array([1.0, rng.uniform(0.3, 1.0)])
        turn = rng.uniform(0.0, np.pi)
        # Angles at least 0.3 rad apart: no quad degenerates into a triangle after snapping.
        gaps = 0.3 + rng.dirichlet(np.ones(4)) * (2.0 * np.pi - 4 * 0.3)
        angles = rng.uniform(0.0, 2.0 * np.pi) + np.cumsum(gaps)
        c, s = np.cos(turn), np.sin(turn)
        pts = []
        for a in angles:
            u, v = axes[0] * np.cos(a), axes[1] * np.sin(a)
            pu, pv = centre[0] + c * u - s * v, centre[1] + s * u + c * v
            pts.append([float(pu * depth[k]), float(pv * depth[k]), float(depth[k])])
        q = np.array(pts)
        # Counter-clockwise seen from the eye at the origin: the normal points back at it.
        if np.dot(np.cross(q[1] - q[0], q[2] - q[0]), q[0]) > 0:
            pts = pts[::-1]
        colour = "#" + "".join(f"{int(v):02x}" for v in rng.integers(0, 256, 3))
        faces.append({"indices": list(range(len(verts), len(verts) + 4)), "colour": colour})
        verts += pts
    return {"vertices": verts, "faces": faces}


def quads_scene_doc(count: int = 200, seed: int = 2027, sky: str = "#3060c0") -> dict:
    """The quads overhead, for an eye at (0, 0, 1.5) looking straight up (QUADS_EYEPOINT)."""
    return {
        "format": "ig-scene/1",
        "sky": {"colour": sky},
        "earth": {"colour": "#406020", "height_m": 0.0},
        "lighting": {"ambient": 1.0},
        "models": {"quads": quads_model(count, seed)},
        "instances": [{"model": "quads", "position": [0.0, 0.0, 1.5]}],
    }
