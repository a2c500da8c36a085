"""The scene database: the pipeline's input, loaded once (load.py) and read by every frame.

Models are convex polygons in their own frame; instances place models in the world (float64
metres, x east, y north, z up); the flat FaceTable lets every drawn instance be transformed in
one pass. The atmosphere (haze, fog, clouds) and the voxel terrain hang off the Database as
their own scene types (atmosphere.py, terrain/).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .atmosphere import Clouds, Fog, Haze
from .surfaces import LOOK_SLOTS, FaceSurfaces, plain_surfaces
from .terrain.database import TerrainDatabase
from .textures import TextureStore, empty_store


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
        surface: the faces' texture codes and smooth shading (surfaces.FaceSurfaces), or None
            when every face is one flat colour.
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
    surface: FaceSurfaces | None = None

    def __post_init__(self) -> None:
        if self.layer is None:
            object.__setattr__(self, "layer", np.zeros(self.face_count, np.int16))
        if self.plane_vertex is None:
            object.__setattr__(self, "plane_vertex", self.face_index[self.face_start[:-1]].astype(np.int64))
        if self.surface is None:
            object.__setattr__(self, "surface", plain_surfaces(self.face_count))

    @property
    def face_count(self) -> int:
        return int(self.face_start.shape[0] - 1)


class FaceTable(NamedTuple):
    """Every model's faces flattened into one table, so all instances transform in one pass
    (a NamedTuple: the transform kernel takes it whole).

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
    surface: FaceSurfaces  # every face's look, texture map and Gouraud terms (surfaces.py)

    @staticmethod
    def of(models: tuple[Model, ...]) -> FaceTable:
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
            opacity=(np.zeros(0, np.float32) if empty
                     else np.concatenate([m.opacity for m in models]).astype(np.float32)),
            face_size=(np.zeros(0, np.int64) if empty
                       else np.concatenate([np.diff(m.face_start) for m in models]).astype(np.int64)),
            local_face=(np.zeros(0, np.int64) if empty
                        else np.concatenate([np.arange(m.face_count) for m in models]).astype(np.int64)),
            layer=np.zeros(0, np.int16) if empty else np.concatenate([m.layer for m in models]).astype(np.int16),
            plane_xyz=np.zeros((0, 3)) if empty else np.concatenate([m.vertices[m.plane_vertex] for m in models]),
            surface=FaceSurfaces.concatenate([m.surface for m in models if m.surface is not None]),
        )


@dataclass(frozen=True)
class TerrainLand:
    """The scene's "terrain.detail" (docs/scene-format.md): the texture codes of the land classes
    drawn over the terrain's relief colour, and the airfield pads' grass.

    Attributes:
        grass, field, rock, forest: the look-table rows of the classes' texture codes (-1:
            none); forest's textures the tree patterns' tops (the canopy).
        pad: the look-table row of the pads' texture code (-1: none).
        pad_colour: (3,) float32 linear RGB of the pads' grass (the airfield's grass faces'
            colour, lit in the cast as they are: a horizontal face in the scene's light).
        pad_covered: the scene's faces cover the pads' areas (the airfield's grass faces): the
            terrain there, hidden, takes the pad's colour without reading its texture.
        pads: (N, 5) float64 pads (x0, y0, x1, y1, blend_m), world metres: the scene's
            "areas", else the terrain database's flattened pads (its recipe's "flatten")
            moved by the terrain's offset.
        relief_luminance: the mean linear luminance of the terrain's level-0 colours (> 0):
            a class's colour keeps the relief's brightness relative to it.
        near_tree_px: a forest voxel spanning more pixels than this is drawn as polygon trees
            (scene/forest.py); 0: never.
    """

    grass: int
    field: int
    rock: int
    forest: int
    pad: int
    pad_covered: bool
    pad_colour: np.ndarray
    pads: np.ndarray
    relief_luminance: float
    near_tree_px: float = 0.0


#: Opacity steps of the fading near trees (scene/forest.py).
OPACITY_STEPS = 8


@dataclass(frozen=True)
class NearTrees:
    """The scene's near trees: which models plant them and how far they reach.

    Attributes:
        px: a forest voxel is drawn as trees while it spans more than this many pixels.
        models: (2, 3, OPACITY_STEPS) int64 model index by species (0 fir, 1 broadleaf), size
            class and opacity step (step s: opacity (s + 1) / OPACITY_STEPS).
        canopy: (K,) bool per terrain pattern whether it is a forest ("tree").
    """

    px: float
    models: np.ndarray
    canopy: np.ndarray


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
        terrain: the voxel terrain, or None.
        terrain_margin_m: a polygon within this height above or below the terrain surface is
            drawn in front of it (a runway on its pad), metres.
        terrain_land: the land's detail over the terrain (TerrainLand), or None: none drawn.
        near_trees: the polygon trees forest voxels turn into near the eye (NearTrees,
            scene/forest.py), or None: forests are voxel blocks at every range.
        haze, clouds, fog: the scene's atmosphere (atmosphere.py), each None when absent.
        textures: the texture stores the scene's texture codes name (textures.py).

        looks: (L, surfaces.LOOK_SLOTS) float64 every distinct face look (texture code and
            smooth shading) that FaceSurfaces.look indexes (surfaces.py).
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
    terrain: TerrainDatabase | None = None
    terrain_margin_m: float = 1.0
    terrain_land: TerrainLand | None = None
    near_trees: NearTrees | None = None
    haze: Haze | None = None
    clouds: Clouds | None = None
    fog: Fog | None = None
    textures: TextureStore = dataclasses.field(default_factory=empty_store)
    looks: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((1, LOOK_SLOTS)))

    @property
    def feature_count(self) -> int:
        if self.instance_model.shape[0] == 0:
            return 0
        last = int(self.instance_model[-1])
        return int(self.instance_face_base[-1]) + self.models[last].face_count
