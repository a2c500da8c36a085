"""Height-of-terrain and line-of-sight requests of a CIGI host, as world-space queries for the
service holding the databases (ig.v1.QueryService), and their answers as CIGI responses.

A request becomes a Job when the IG frame that consumes it begins (with the pose of any entity
it is relative to at that frame, and the low nibble of the last host frame number, which the
host uses to correlate the answer); the endpoint sends a frame's jobs to the query service in
one batch per kind and turns the results into response packets for the next Start of Frame.

Geodetic heights: the rig world's vertical leans away from the local vertical by about 1 degree
per 111 km from the origin (services.rig.geodetic), so a height is asked along the point's own
vertical (the query service follows the leaning line): sampled along the world's z instead, a
point on a 30 % slope 50 km out would be off by a metre per 100 m between its height and the
ground's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ig.v1 import query_pb2
from services.rig import geodetic

from . import packets as pk
from .geometry import (
    SCALAR_POINTS,
    Origin,
    WorldPose,
    azimuth_elevation,
    body_of_world,
    direction_of,
    geodetic_of_world,
    local_rotation,
    origin_frame,
    point_and_up,
    world_of_body,
    world_of_geodetic,
)

#: Queries per RPC: half what the query service takes (1024), so that a batch of line-of-sight
#: segments (seven doubles each) stays well inside the worker's 64 KiB message limit.
MAX_QUERIES = 512

#: CIGI request types of HAT/HOT Request.
HAT, HOT, EXTENDED = 0, 1, 2


@dataclass
class HeightJob:
    """One HAT/HOT request, in the world."""

    request: pk.HatHotRequest
    lsn: int
    #: geodetic latitude, longitude and height of the point (height: HAT only)
    lat: float = 0.0
    lon: float = 0.0
    alt: float = 0.0
    known: bool = True


@dataclass
class SightJob:
    """One LOS segment or vector request, in the world."""

    request: pk.LosSegmentRequest | pk.LosVectorRequest
    lsn: int
    p0: np.ndarray | None = None
    p1: np.ndarray | None = None
    #: distance of p0 from the source (a vector's minimum range), metres
    range_offset: float = 0.0
    #: the entity a response in entity coordinates is relative to
    pose: WorldPose | None = None
    known: bool = True


Job = HeightJob | SightJob


def height_job(req: pk.HatHotRequest, lsn: int, pose: WorldPose | None, origin: Origin) -> HeightJob:
    """The job of a HAT/HOT request; pose: its entity's, for an entity-relative request (None:
    an unknown entity, answered invalid)."""
    if req.coord_system == 0:
        return HeightJob(req, lsn, req.lat_x, req.lon_y, req.alt_z)
    if pose is None:
        return HeightJob(req, lsn, known=False)
    lat, lon, h = geodetic_of_world(world_of_body(pose, np.array([req.lat_x, req.lon_y, req.alt_z])), origin)
    return HeightJob(req, lsn, float(lat[0]), float(lon[0]), float(h[0]))


def sight_job(req: pk.LosSegmentRequest | pk.LosVectorRequest, lsn: int, pose: WorldPose | None,
              origin: Origin) -> SightJob:
    """The job of a LOS request; pose: its entity's (None: unknown, answered invalid when an
    entity-relative coordinate needs it)."""
    def point(coord: int, a: float, b: float, c: float) -> np.ndarray | None:
        if coord == 0:
            return world_of_geodetic(np.array([a]), np.array([b]), np.array([c]), origin)[0]
        return None if pose is None else world_of_body(pose, np.array([a, b, c]))[0]

    needs_entity = req.source_coord == 1 or req.response_coord == 1 or \
        (isinstance(req, pk.LosSegmentRequest) and req.dest_coord == 1)
    if needs_entity and pose is None:
        return SightJob(req, lsn, known=False)
    src = point(req.source_coord, req.src_lat_x, req.src_lon_y, req.src_alt_z)
    assert src is not None
    if isinstance(req, pk.LosSegmentRequest):
        dst = point(req.dest_coord, req.dst_lat_x, req.dst_lon_y, req.dst_alt_z)
        return SightJob(req, lsn, src, dst, 0.0, pose)
    if req.source_coord == 0:
        lat, lon, _ = geodetic_of_world(src[None], origin)
        rotation = local_rotation(float(lat[0]), float(lon[0]), origin)
    else:
        assert pose is not None
        rotation = pose.rotation  # body right, forward, up -> world
    d = rotation @ direction_of(req.azimuth, req.elevation)
    lo, hi = max(0.0, float(req.min_range)), float(req.max_range)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi >= lo):
        return SightJob(req, lsn, known=False)
    return SightJob(req, lsn, src + lo * d, src + hi * d, lo, pose)


def sight_request(jobs: Sequence[SightJob]) -> query_pb2.LineOfSightRequest:
    p0 = np.array([j.p0 for j in jobs])
    p1 = np.array([j.p1 for j in jobs])
    return query_pb2.LineOfSightRequest(
        x0=p0[:, 0].tolist(), y0=p0[:, 1].tolist(), z0=p0[:, 2].tolist(),
        x1=p1[:, 0].tolist(), y1=p1[:, 1].tolist(), z1=p1[:, 2].tolist(),
        min_opacity=[j.request.alpha_threshold / 255.0 for j in jobs])


@dataclass(frozen=True)
class Surface:
    """A height query's answer: valid, geodetic height of the surface, normal (world), material."""

    valid: bool
    height: float = 0.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    material: int = 0


def vertical_lines(jobs: Sequence[HeightJob], origin: Origin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The local vertical of each job's point as the query service takes it (query.proto): the
    point (n, 3) where it crosses world z = 0, its unit direction (n, 3), and the z_max of the
    line (a HAT request counts only surfaces under its own point; HOT every surface)."""
    if len(jobs) <= SCALAR_POINTS:
        pairs = [point_and_up(j.lat, j.lon, j.alt, origin) for j in jobs]
        at_alt = np.array([p for p, _ in pairs])
        up = np.array([u for _, u in pairs])
    else:
        lat = np.array([j.lat for j in jobs])
        lon = np.array([j.lon for j in jobs])
        at_alt = world_of_geodetic(lat, lon, np.array([j.alt for j in jobs]), origin)
        # Up at each point is the third row of its ECEF -> ENU rotation; the origin's rotation
        # takes it into the world.
        up = geodetic.enu_rotation(lat, lon)[..., 2, :] @ origin_frame(origin)[1].T
    base = at_alt - (at_alt[:, 2] / up[:, 2])[:, None] * up  # up_z is near 1 anywhere a database reaches
    z_max = np.array([z if j.request.request_type != HOT else math.inf
                      for j, z in zip(jobs, at_alt[:, 2], strict=True)])
    return base, up, z_max


def heights_request(base: np.ndarray, up: np.ndarray, z_max: np.ndarray) -> query_pb2.HeightOfTerrainRequest:
    return query_pb2.HeightOfTerrainRequest(x=base[:, 0].tolist(), y=base[:, 1].tolist(), z_max=z_max.tolist(),
                                            up_x=up[:, 0].tolist(), up_y=up[:, 1].tolist(), up_z=up[:, 2].tolist())


def height_response(job: HeightJob, surface: Surface,
                    origin: Origin) -> pk.HatHotResponse | pk.HatHotExtendedResponse:
    """The response packet of a height job (invalid when its entity or the surface is unknown)."""
    req = job.request
    valid = job.known and surface.valid
    hat = job.alt - surface.height if valid else 0.0
    hot = surface.height if valid else 0.0
    if req.request_type == EXTENDED:
        az, el = 0.0, 90.0
        if valid:
            a, e = azimuth_elevation(np.array([surface.normal]), local_rotation(job.lat, job.lon, origin).T)
            az, el = float(a[0]), float(e[0])
        return pk.HatHotExtendedResponse(request_id=req.request_id, valid=valid, host_frame_lsn=job.lsn,
                                         hat=hat, hot=hot, material=surface.material if valid else 0,
                                         normal_azimuth=az, normal_elevation=el)
    response_type = HOT if req.request_type == HOT else HAT
    return pk.HatHotResponse(request_id=req.request_id, valid=valid, response_type=response_type,
                             host_frame_lsn=job.lsn, height=hot if response_type == HOT else hat)


def sight_response(job: SightJob, hit: query_pb2.LineOfSightResponse | None, i: int,
                   origin: Origin) -> pk.LosResponse | pk.LosExtendedResponse:
    """The response packet of a sight job from result i of a LineOfSight answer (None: the
    query failed; answered invalid).

    Valid says the range is meaningful (something was hit); Visible says nothing stands
    between a segment's ends (a vector: nothing within its range)."""
    req = job.request
    known = job.known and hit is not None
    struck = bool(known and hit is not None and hit.hit[i])
    visible = known and not struck
    rng = job.range_offset + hit.range_m[i] if struck and hit is not None else 0.0
    extended = req.request_type == 1
    if not extended:
        return pk.LosResponse(los_id=req.los_id, valid=struck, entity_id_valid=False, visible=visible,
                              host_frame_lsn=job.lsn, response_count=1, entity_id=0, range=rng)
    point = np.zeros(3)
    az, el, material, rgba = 0.0, 90.0, 0, 0
    if struck and hit is not None:
        point = np.array([hit.x[i], hit.y[i], hit.z[i]])
        lat, lon, _ = geodetic_of_world(point[None], origin)
        a, e = azimuth_elevation(np.array([[hit.normal_x[i], hit.normal_y[i], hit.normal_z[i]]]),
                                 local_rotation(float(lat[0]), float(lon[0]), origin).T)
        az, el, material, rgba = float(a[0]), float(e[0]), int(hit.material[i]), int(hit.rgba[i])
    if req.response_coord == 1 and job.pose is not None:
        x, y, z = body_of_world(job.pose, point[None])[0] if struck else (0.0, 0.0, 0.0)
    elif struck:
        lat, lon, h = geodetic_of_world(point[None], origin)
        x, y, z = float(lat[0]), float(lon[0]), float(h[0])
    else:
        x = y = z = 0.0
    return pk.LosExtendedResponse(
        los_id=req.los_id, valid=struck, entity_id_valid=False, range_valid=struck, visible=visible,
        host_frame_lsn=job.lsn, response_count=1, entity_id=0, range=rng, lat_x=float(x), lon_y=float(y),
        alt_z=float(z), red=(rgba >> 24) & 0xFF, green=(rgba >> 16) & 0xFF, blue=(rgba >> 8) & 0xFF,
        alpha=rgba & 0xFF, material=material, normal_azimuth=az, normal_elevation=el)
