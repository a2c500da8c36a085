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


#: The overdraw scenes' channel: 1280 x 1024 pixels across OVERDRAW_FOV_DEG (square pixels).
OVERDRAW_SIZE = (1280, 1024)
OVERDRAW_FOV_DEG = 60.0


def overdraw_model(depth_complexity: float, *, count: int = 10_000, translucent: float = 0.0,
                   seed: int = 2028, width: int = OVERDRAW_SIZE[0],
                   height: int = OVERDRAW_SIZE[1], fov_deg: float = OVERDRAW_FOV_DEG) -> dict:
    """`count` eye-facing convex quads whose projected areas add up to `depth_complexity` times
    the picture, in random depth order: the overdraw scene of bench_visibility.py.

    Sizes are log-uniform over a factor of 30 (small and large quads together), then scaled
    by one common factor so that the summed screen area is depth_complexity * width * height
    (area of the quad in the plane z = 1, times the focal length in pixels squared). Centres
    are uniform over the view, so a large quad may reach past the picture's edge. Depths are
    20 + 0.25 k metres for a shuffled k, as in quads_model: distinct, so the visibility order
    is known and the exact-coverage reference applies. A fraction `translucent` of the quads
    (chosen at random) has opacity uniform in 0.3..0.8; the rest are opaque.
    """
    rng = np.random.default_rng(seed)
    tan_h = np.tan(np.radians(fov_deg / 2.0))
    tan_v = tan_h * height / width
    focal = width / (2.0 * tan_h)
    depth = 20.0 + 0.25 * rng.permutation(count)
    size = np.exp(rng.uniform(np.log(1.0), np.log(30.0), count))
    ratio = rng.uniform(0.3, 1.0, count)
    turn = rng.uniform(0.0, np.pi, count)
    gaps = 0.3 + rng.dirichlet(np.ones(4), count) * (2.0 * np.pi - 4 * 0.3)
    angles = rng.uniform(0.0, 2.0 * np.pi, count)[:, None] + np.cumsum(gaps, axis=1)
    u = np.cos(angles) * size[:, None]
    v = np.sin(angles) * (size * ratio)[:, None]
    c, s = np.cos(turn)[:, None], np.sin(turn)[:, None]
    pu, pv = c * u - s * v, s * u + c * v
    # Shoelace area of each quad at unit size in the plane z = 1 (angles are increasing: > 0).
    area = 0.5 * np.abs(np.sum(pu * np.roll(pv, -1, 1) - np.roll(pu, -1, 1) * pv, axis=1))
    scale = np.sqrt(depth_complexity * width * height / (area.sum() * focal * focal))
    centre = rng.uniform([-tan_h, -tan_v], [tan_h, tan_v], (count, 2))
    see_through = rng.random(count) < translucent
    alpha = rng.uniform(0.3, 0.8, count)
    colours = rng.integers(0, 256, (count, 3))
    verts: list[list[float]] = []
    faces: list[dict] = []
    for k in range(count):
        d = float(depth[k])
        q = np.stack([(centre[k, 0] + scale * pu[k]) * d, (centre[k, 1] + scale * pv[k]) * d,
                      np.full(4, d)], axis=1)
        # Counter-clockwise seen from the eye at the origin: the normal points back at it.
        if np.dot(np.cross(q[1] - q[0], q[2] - q[0]), q[0]) > 0:
            q = q[::-1]
        face: dict = {"indices": list(range(len(verts), len(verts) + 4)),
                      "colour": "#" + "".join(f"{int(x):02x}" for x in colours[k])}
        if see_through[k]:
            face["opacity"] = round(float(alpha[k]), 3)
        faces.append(face)
        verts += q.tolist()
    return {"vertices": verts, "faces": faces}


def overdraw_scene_doc(depth_complexity: float, *, translucent: float = 0.0, count: int = 10_000,
                       seed: int = 2028, sky: str = "#3060c0") -> dict:
    """overdraw_model's quads overhead, for an eye at QUADS_EYEPOINT looking straight up, at
    OVERDRAW_SIZE across OVERDRAW_FOV_DEG."""
    return {
        "format": "ig-scene/1",
        "sky": {"colour": sky},
        "earth": {"colour": "#406020", "height_m": 0.0},
        "lighting": {"ambient": 1.0},
        "models": {"quads": overdraw_model(depth_complexity, count=count, translucent=translucent,
                                           seed=seed)},
        "instances": [{"model": "quads", "position": [0.0, 0.0, 1.5]}],
    }
