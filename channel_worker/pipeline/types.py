"""Plain data passed between the pipeline stages.

Frames (see docs/conventions.md):
- world: x east, y north, z up, metres, float64;
- eye: x right, y up, z forward (depth), metres, relative to the eyepoint;
- screen: pixels, x right, y down, (0, 0) the top-left corner of the top-left pixel,
  pixel centres at half-integers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from services.rig.frame import ChannelSpec, Eyepoint  # noqa: F401  (until the stage split)

#: Feature identity stored for samples that no polygon covers.
SKY_ID = -1
EARTH_ID = -2
#: A sample that sees the frame's Background (terrain, or the sky and earth plane as the terrain
#: stage painted them with haze): its colour is Background.rgb of that sample.
BACKGROUND_ID = -3

#: Sub-pixel precision of the rasterizer: screen coordinates are snapped to 1/SUBPIXEL pixel
#: and edge functions are evaluated exactly in int64 (watertight, see raster.py).
SUBPIXEL_BITS = 8
SUBPIXEL = 1 << SUBPIXEL_BITS


@dataclass(frozen=True)
class View:
    """Everything the stages need to know about one channel's view for one frame.

    Attributes:
        eye: eyepoint in world metres, float64 (3,).
        world_to_eye: (3, 3) float64; rows are the eye x (right), y (up), z (forward) axes
            expressed in world coordinates, so ``eye_vec = world_to_eye @ world_vec``.
        tan_left, tan_right, tan_bottom, tan_top: frustum edges as tangents (x/z, y/z).
        width, height: raster size in pixels.
        near: near clip distance along eye z, metres.
        far: far clip distance along eye z, metres.
    """

    eye: np.ndarray
    world_to_eye: np.ndarray
    tan_left: float
    tan_right: float
    tan_bottom: float
    tan_top: float
    width: int
    height: int
    near: float = 0.25
    far: float = 100_000.0


@dataclass(frozen=True)
class DrawList:
    """Instances that survived culling: indices into the database and model-to-world rotations."""

    instance_index: np.ndarray  # (N,) int64
    rotation: np.ndarray  # (N, 3, 3) float64 model -> world
    position: np.ndarray  # (N, 3) float64 world metres


@dataclass(frozen=True)
class Polygons:
    """Convex polygons in one frame (eye metres before projection, screen pixels after).

    ``verts[start[i]:start[i + 1]]`` are the vertices of polygon i in order. The winding of every
    polygon is normalised so that it is counter-clockwise as the eye sees it (front faces only
    reach here).

    Attributes:
        verts: (Nv, 3) float64 eye coordinates, or (Nv, 2) float64 screen pixels.
        start: (N + 1,) int64 offsets into verts.
        colour: (N, 3) float32 linear RGB after shading.
        opacity: (N,) float32; 1 is opaque.
        feature_id: (N,) int32 identity of the source face (see Database.face_names).
        plane: (N, 4) float64 eye-space plane (nx, ny, nz, d) with n . p = d, n pointing
            towards the eye; used to interpolate depth exactly. Faces declared to lie on
            another face (scene "on") carry that face's plane bit for bit.
        layer: (N,) int16 declared layer; where two features are at exactly the same depth
            (coplanar, sharing one plane) the higher layer is seen. None means all 0.
    """

    verts: np.ndarray
    start: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray
    feature_id: np.ndarray
    plane: np.ndarray
    layer: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.layer is None:
            object.__setattr__(self, "layer", np.zeros(self.start.shape[0] - 1, np.int16))

    def take(self, idx: np.ndarray, verts: np.ndarray, start: np.ndarray) -> "Polygons":
        """New polygons with the given vertices and the attributes of polygons idx."""
        return Polygons(verts=verts, start=start, colour=self.colour[idx],
                        opacity=self.opacity[idx], feature_id=self.feature_id[idx],
                        plane=self.plane[idx], layer=self.layer[idx])

    @property
    def count(self) -> int:
        return int(self.start.shape[0] - 1)


@dataclass(frozen=True)
class ScreenPolygons:
    """Projected polygons ready for rasterization.

    Attributes:
        fixed: (Nv, 2) int64 vertex positions in 1/SUBPIXEL pixel units (snapped).
        start: (N + 1,) int64 offsets into fixed.
        inv_z: (N, 3) float64 (A, B, C) with 1/z = A * sx + B * sy + C at screen point (sx, sy)
            in pixels, z the eye-space depth in metres.
        colour, opacity, feature_id, layer: as in Polygons.
    """

    fixed: np.ndarray
    start: np.ndarray
    inv_z: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray
    feature_id: np.ndarray
    layer: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.layer is None:
            object.__setattr__(self, "layer", np.zeros(self.start.shape[0] - 1, np.int16))

    @property
    def count(self) -> int:
        return int(self.start.shape[0] - 1)


@dataclass(frozen=True)
class SampleBuffer:
    """Per-sample visibility: which features every sample sees, nearest first.

    The store holds identities, not colours: the resolve stage shades each sample from the
    identities (so a sample costs 4 bytes when no translucent feature covers it).

    Attributes:
        offsets: (S, 2) float64 sample positions inside the pixel, pixels from its top-left.
        opaque: (H, W, S) int32 index into the frame's ScreenPolygons of the nearest opaque
            polygon covering the sample, or SKY_ID / EARTH_ID where none does.
        translucent: (H, W, S, K) int32 indices of the translucent polygons nearer than the
            opaque one, nearest first; only the first translucent_count entries are meaningful.
            (1, 1, 1, K) when the frame has no translucent polygon (every count is then 0).
        translucent_count: (H, W, S) uint8, at most K.
        polygon_range: (H, W) float32 distance from the eye (metres) to the nearest opaque
            polygon seen by any sample of the pixel, +inf where no sample sees a polygon; None
            when the frame was rendered without ranges.
        stats: counters of the visibility stage ("translucent_dropped": times a translucent
            feature was dropped from a full store; "subarea_entries_full" / "_partial":
            sub-area list entries by class; "entries_skipped_by_depth": entries never read
            because every sample already held a nearer opaque feature).
    """
    offsets: np.ndarray
    opaque: np.ndarray
    translucent: np.ndarray
    translucent_count: np.ndarray
    polygon_range: np.ndarray | None
    stats: dict[str, int] = field(default_factory=dict)

    @property
    def max_translucent(self) -> int:
        return int(self.translucent.shape[3])


@dataclass(frozen=True)
class Background:
    """What every sample sees behind the polygons, when the scene has terrain, haze, fog or
    clouds.

    Attributes:
        rgb: (H, W, 3) float32 linear colour of the pixel's background: terrain over the sky
            or the earth plane, all through the haze and fog.
        inv_z: (H, W, S) float32 1/z (eye depth, metres) a polygon must exceed to be seen in
            front of the terrain (the terrain pushed back by the scene's polygon margin); 0
            where the sample sees sky or the earth plane, which never hide a polygon.
        range_m: (H, W) float32 nearest range of the background among the pixel's samples,
            metres (+inf for sky).
        stats: counters of the terrain stage ("terrain_voxels": voxels visited, ...).
        cloud: (H, W, 5) float32 the pixel's cloud (premultiplied linear RGB, opacity, range
            where its ray enters cloud, metres), already laid over rgb; polygons beyond the
            entry range are seen through it. None when the scene has no clouds.
        air: the frame's haze and fog (air.air_params), built once by the stage; the
            visibility and resolve stages see the polygons through it. None: clear air.
    """

    rgb: np.ndarray
    inv_z: np.ndarray
    range_m: np.ndarray
    stats: dict[str, int] = field(default_factory=dict)
    cloud: np.ndarray | None = None
    air: np.ndarray | None = None


def background_arrays(background: Background | None) -> tuple:
    """What the visibility and resolve kernels take of a Background: (on, rgb, inv_z, range_m,
    cloud_on, cloud), with one-element stand-ins for what is absent."""
    if background is None:
        return (False, np.zeros((1, 1, 3), np.float32), np.zeros((1, 1, 1), np.float32),
                np.zeros((1, 1), np.float32), False, np.zeros((1, 1, 5), np.float32))
    cloud = background.cloud
    return (True, background.rgb, background.inv_z, background.range_m, cloud is not None,
            cloud if cloud is not None else np.zeros((1, 1, 5), np.float32))


@dataclass(frozen=True)
class Image:
    """One channel's resolved output.

    Attributes:
        rgb: (H, W, 3) float32 linear RGB.
        range_m: (H, W) float32 distance from the eye to the nearest surface seen in the pixel,
            metres; +inf where the pixel sees only sky. None when rendered without ranges.
    """

    rgb: np.ndarray
    range_m: np.ndarray | None


@dataclass
class StageTimes:
    """Wall-clock seconds spent in each stage of one frame, in pipeline order."""

    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def total(self) -> float:
        return float(sum(self.seconds.values()))


@dataclass(frozen=True)
class Model:
    """One model of the database: convex polygons in model coordinates (metres).

    Attributes:
        name: key in the scene file.
        vertices: (Nv, 3) float64.
        face_start: (F + 1,) int64 offsets into face_index.
        face_index: vertex indices of all faces, concatenated, counter-clockwise from the front.
        colour: (F, 3) float32 linear RGB.
        opacity: (F,) float32.
        normal: (F, 3) float64 unit outward normals.
        centre: (3,) float64 bounding-sphere centre; radius: its radius, metres.
        layer: (F,) int16 declared layer (0 unless the face lies on another face).
        plane_vertex: (F,) int64 vertex whose position fixes the face's plane offset: its own
            first vertex, or the first vertex of the face it lies on, so that coplanar faces
            share one plane bit for bit.
    """

    name: str
    vertices: np.ndarray
    face_start: np.ndarray
    face_index: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray
    normal: np.ndarray
    centre: np.ndarray
    radius: float
    layer: np.ndarray | None = None
    plane_vertex: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.layer is None:
            object.__setattr__(self, "layer", np.zeros(self.face_count, np.int16))
        if self.plane_vertex is None:
            object.__setattr__(self, "plane_vertex", self.face_index[self.face_start[:-1]].astype(np.int64))

    @property
    def face_count(self) -> int:
        return int(self.face_start.shape[0] - 1)


@dataclass(frozen=True)
class FaceTable:
    """Every model's faces flattened into one table, so all instances transform in one pass.

    Per model m: corner_count[m] face-vertex slots starting at corner_base[m] in corner_xyz,
    face_count[m] faces starting at face_base[m] in the per-face arrays.
    """

    corner_count: np.ndarray
    face_count: np.ndarray
    corner_base: np.ndarray
    face_base: np.ndarray
    corner_xyz: np.ndarray  # (C, 3) float64 model metres, each face's vertices in order
    normal: np.ndarray  # (F, 3) float64
    colour: np.ndarray  # (F, 3) float32 linear
    opacity: np.ndarray  # (F,) float32
    face_size: np.ndarray  # (F,) int64 vertices per face
    local_face: np.ndarray  # (F,) int64 index of the face within its model
    layer: np.ndarray  # (F,) int16
    plane_xyz: np.ndarray  # (F, 3) float64 model metres, the point fixing each face's plane

    @staticmethod
    def of(models: "tuple[Model, ...]") -> "FaceTable":
        corner_count = np.array([m.face_index.shape[0] for m in models], np.int64)
        face_count = np.array([m.face_count for m in models], np.int64)
        empty = not models
        return FaceTable(
            corner_count=corner_count,
            face_count=face_count,
            corner_base=np.concatenate([[0], np.cumsum(corner_count)[:-1]]).astype(np.int64),
            face_base=np.concatenate([[0], np.cumsum(face_count)[:-1]]).astype(np.int64),
            corner_xyz=np.zeros((0, 3)) if empty else np.concatenate([m.vertices[m.face_index] for m in models]),
            normal=np.zeros((0, 3)) if empty else np.concatenate([m.normal for m in models]),
            colour=np.zeros((0, 3), np.float32) if empty else np.concatenate([m.colour for m in models]),
            opacity=np.zeros(0, np.float32) if empty else np.concatenate([m.opacity for m in models]).astype(np.float32),
            face_size=np.zeros(0, np.int64) if empty else np.concatenate([np.diff(m.face_start) for m in models]).astype(np.int64),
            local_face=np.zeros(0, np.int64) if empty else np.concatenate([np.arange(m.face_count) for m in models]).astype(np.int64),
            layer=np.zeros(0, np.int16) if empty else np.concatenate([m.layer for m in models]).astype(np.int16),
            plane_xyz=np.zeros((0, 3)) if empty else np.concatenate([m.vertices[m.plane_vertex] for m in models]),
        )


@dataclass(frozen=True)
class Database:
    """The loaded scene.

    Attributes:
        models: all models, referenced by index.
        instance_model: (N,) int64 model index per instance.
        instance_position: (N, 3) float64 world metres.
        instance_rotation: (N, 3, 3) float64 model -> world.
        instance_names: display names.
        instance_face_base: (N,) int64; feature id of face k of instance i is base[i] + k.
        sky_colour, earth_colour: (3,) float32 linear RGB.
        earth_height: world z of the earth plane, metres.
        sun: (3,) float64 unit vector towards the sun, world frame.
        ambient: share of a face's colour lit regardless of the sun.
        faces: all models' faces in one flat table (FaceTable.of(models)).
        source: where the database was loaded from (for messages).
        terrain: the voxel terrain (channel_worker.terrain.database.TerrainDatabase) or None.
        terrain_margin_m: a polygon within this height above or below the terrain surface is
            drawn in front of it (a runway on its pad), metres.
        haze: channel_worker.pipeline.haze.Haze or None.
        clouds: channel_worker.pipeline.clouds.Clouds or None.
        fog: channel_worker.pipeline.fog.Fog (seed 004's layered fog) or None.
    """

    models: tuple[Model, ...]
    instance_model: np.ndarray
    instance_position: np.ndarray
    instance_rotation: np.ndarray
    instance_names: tuple[str, ...]
    instance_face_base: np.ndarray
    sky_colour: np.ndarray
    earth_colour: np.ndarray
    earth_height: float
    sun: np.ndarray
    ambient: float
    faces: FaceTable
    source: str = ""
    terrain: Any = None
    terrain_margin_m: float = 1.0
    haze: Any = None
    clouds: Any = None
    fog: Any = None

    @property
    def feature_count(self) -> int:
        if self.instance_model.shape[0] == 0:
            return 0
        last = int(self.instance_model[-1])
        return int(self.instance_face_base[-1]) + self.models[last].face_count


def rgb_array(out: np.ndarray | None, height: int, width: int) -> np.ndarray:
    """The caller's (H, W, 3) float32 colour array if it fits, else a new one.

    Raises:
        ValueError: out has the wrong shape, type or layout (named with what was expected).
    """
    if out is None:
        return np.empty((height, width, 3), np.float32)
    if out.shape != (height, width, 3) or out.dtype != np.float32 or not out.flags.c_contiguous:
        raise ValueError(f"out: expected a C-contiguous float32 array of shape {(height, width, 3)}, "
                         f"got {out.dtype} {out.shape}")
    return out


#: Default size of the per-sample translucent store.
DEFAULT_MAX_TRANSLUCENT = 4


def check_max_translucent(k: int) -> int:
    """K as an int, or ValueError naming the value (the store counts fit in a uint8)."""
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 15:
        raise ValueError(f"max_translucent: expected an integer in 1..15, got {k!r}")
    return int(k)
