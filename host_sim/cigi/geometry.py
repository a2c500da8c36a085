"""CIGI's geodetic and entity-relative coordinates to and from the rig's world, in float64.

The world is the east-north-up frame of the rig file's `cigi.origin` (services.rig.geodetic):
a CIGI position (WGS-84 latitude, longitude, height) goes through ECEF into it, and an attitude
measured against the local north and horizontal at the entity is turned by the tilt between
the entity's local frame and the origin's (host_sim.replay.attitude.local_to_world), so a host
flying 100 km from the origin sees the same horizon as one at the origin.
(host_sim.replay.attitude.local_to_world is the same turn for arrays of logged attitudes.)

Entity-relative offsets are CIGI's body axes: x forward, y right, z down, metres; azimuth is
clockwise from the forward (or north) axis, elevation up from the horizontal, degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from host_sim.replay.attitude import hpr_of_matrix
from services.rig import geodetic
from services.rig.frame import Eyepoint, hpr_matrix

Origin = tuple[float, float, float]


@dataclass(frozen=True)
class WorldPose:
    """An entity's pose in the world: position (3,) float64 metres, and the body -> world
    rotation (3, 3) whose columns are the body's right, forward and up axes."""

    position: np.ndarray
    rotation: np.ndarray
    heading_deg: float
    pitch_deg: float
    roll_deg: float

    def eyepoint(self) -> Eyepoint:
        return Eyepoint(self.position.copy(), self.heading_deg, self.pitch_deg, self.roll_deg)


@lru_cache(maxsize=8)
def origin_frame(origin: Origin) -> tuple[np.ndarray, np.ndarray]:
    """The origin's ECEF position and its ECEF -> east-north-up rotation (every pose needs both:
    computed once per origin)."""
    o = geodetic.ecef(np.array(origin[0]), np.array(origin[1]), np.array(origin[2]))
    return o, geodetic.enu_rotation(np.array(origin[0]), np.array(origin[1]))


def pose_of_geodetic(lat_deg: float, lon_deg: float, alt_m: float, yaw_deg: float, pitch_deg: float,
                     roll_deg: float, origin: Origin) -> WorldPose:
    """The world pose of a CIGI entity at a geodetic position with a local attitude.

    The same conversions as services.rig.geodetic.enu and host_sim.replay.attitude.local_to_world
    (the tests hold them equal), for one pose in scalars: the ownship is converted with every
    host message, and the arrays' overhead was most of a datagram's cost.

    Raises:
        ValueError: a value that is not finite or a latitude beyond the poles, named.
    """
    for name, v in (("lat", lat_deg), ("lon", lon_deg), ("alt", alt_m), ("yaw", yaw_deg), ("pitch", pitch_deg),
                    ("roll", roll_deg)):
        if not math.isfinite(v):
            raise ValueError(f"{name}: {v} is not finite")
    if abs(lat_deg) > 90.0:
        raise ValueError(f"lat: {lat_deg} is outside [-90, 90]")
    o, to_world = origin_frame(origin)
    here, local = geodetic.ecef_point(lat_deg, lon_deg, alt_m)
    rotation = to_world @ local.T @ hpr_matrix(yaw_deg, pitch_deg, roll_deg)
    h, p, r = hpr_of_matrix(rotation[None])[0]
    return WorldPose(to_world @ (here - o), rotation, float(h), float(p), float(r))


#: Up to this many points, conversions run point by point in scalars (a frame's few requests:
#: numpy's per-call overhead was most of a datagram's cost); beyond, as arrays.
SCALAR_POINTS = 8


def point_and_up(lat_deg: float, lon_deg: float, h_m: float, origin: Origin) -> tuple[np.ndarray, np.ndarray]:
    """The world position of one geodetic point and its local vertical (unit, world)."""
    o, to_world = origin_frame(origin)
    here, local = geodetic.ecef_point(lat_deg, lon_deg, h_m)
    return to_world @ (here - o), to_world @ local[2]


def height_of_world(point: np.ndarray, origin: Origin) -> float:
    """The geodetic height of one world point."""
    o, to_world = origin_frame(origin)
    x, y, z = to_world.T @ point + o
    return geodetic.height_of_ecef_point(float(x), float(y), float(z))


def world_of_geodetic(lat_deg: np.ndarray, lon_deg: np.ndarray, alt_m: np.ndarray, origin: Origin) -> np.ndarray:
    """(n, 3) world positions of geodetic positions."""
    return geodetic.enu(np.asarray(lat_deg, np.float64), np.asarray(lon_deg, np.float64),
                        np.asarray(alt_m, np.float64), origin)


def geodetic_of_world(points: np.ndarray, origin: Origin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(latitude deg, longitude deg, height m) arrays of (n, 3) world positions."""
    p = np.asarray(points, np.float64)
    return geodetic.geodetic_of_enu(p[:, 0], p[:, 1], p[:, 2], origin)


def world_of_body(pose: WorldPose, offset_fwd_right_down: np.ndarray) -> np.ndarray:
    """(n, 3) world positions of offsets in an entity's body axes (x forward, y right, z down)."""
    o = np.asarray(offset_fwd_right_down, np.float64).reshape(-1, 3)
    body = np.stack([o[:, 1], o[:, 0], -o[:, 2]], axis=-1)  # -> right, forward, up
    return pose.position + body @ pose.rotation.T


def body_of_world(pose: WorldPose, points: np.ndarray) -> np.ndarray:
    """(n, 3) offsets (x forward, y right, z down) in an entity's body axes of world positions."""
    rfu = (np.asarray(points, np.float64).reshape(-1, 3) - pose.position) @ pose.rotation
    return np.stack([rfu[:, 1], rfu[:, 0], -rfu[:, 2]], axis=-1)


def local_rotation(lat_deg: float, lon_deg: float, origin: Origin) -> np.ndarray:
    """(3, 3) local east-north-up at (lat, lon) -> world (origin's east-north-up)."""
    to_world = geodetic.enu_rotation(np.array(origin[0]), np.array(origin[1]))
    return to_world @ geodetic.enu_rotation(np.array(lat_deg), np.array(lon_deg)).T


def direction_of(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit (east, north, up) of an azimuth clockwise from north and an elevation, in the frame
    the angles are measured in (local ENU, or a body's right, forward, up)."""
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])


def azimuth_elevation(vectors: np.ndarray, rotation_to_local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth (clockwise from north, -180..180) and elevation, degrees, of (n, 3) world
    vectors expressed in a local frame (rotation_to_local: world -> local ENU).

    A zero vector has azimuth 0 and elevation 0 (atan2(0, 0) = 0: no division)."""
    v = np.asarray(vectors, np.float64).reshape(-1, 3) @ rotation_to_local.T
    horizontal = np.hypot(v[:, 0], v[:, 1])
    return np.degrees(np.arctan2(v[:, 0], v[:, 1])), np.degrees(np.arctan2(v[:, 2], horizontal))
