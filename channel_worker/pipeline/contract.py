"""The pipeline's contract: what one stage hands the next, for one channel and one frame.

Like llvmpipe's binned scene header, this is the one module both sides of every stage boundary
read: the frame constants every kernel shares, the polygons as each geometry stage leaves them,
the per-sub-area feature lists, the background every sample starts from, and the sample store.
The scene database (scene/database.py) is the pipeline's input; render.py calls the stages in
order (docs/architecture.md draws the flow).

The values that kernels take are NamedTuples of arrays and numbers (FrameConstants,
ScreenPolygons, Edges, Bins, Background): numba passes them whole, so a kernel takes a handful of
grouped values instead of dozens of loose arrays, and a field added here reaches every kernel
that takes the group.

Frames (docs/conventions.md):
- world: x east, y north, z up, metres, float64;
- eye: x right, y up, z forward (depth), metres, relative to the eyepoint;
- screen: pixels, x right, y down, (0, 0) the top-left corner of the top-left pixel,
  pixel centres at half-integers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: Feature identity stored for samples that no polygon covers.
SKY_ID = -1
EARTH_ID = -2
#: A sample that sees the frame's Background (terrain, or the sky and earth plane as the
#: background stage painted them through haze and fog): its colour is Background.rgb there.
BACKGROUND_ID = -3

#: Sub-pixel precision of the rasterizer: screen coordinates are snapped to 1/SUBPIXEL pixel
#: and edge functions are evaluated exactly in int64 (watertight, see binning/edges.py).
SUBPIXEL_BITS = 8
SUBPIXEL = 1 << SUBPIXEL_BITS


def subpixel_offsets(offsets: np.ndarray) -> np.ndarray:
    """(S, 2) int64 sample offsets in 1/SUBPIXEL units (every named pattern lies on that grid
    exactly, so rounding changes none of them)."""
    return np.round(np.asarray(offsets, np.float64) * SUBPIXEL).astype(np.int64)


#: The frame's air (background.air.air_params): one float64 array that every kernel seeing
#: through the atmosphere takes. First the haze's HAZE_SLOTS (background.haze.haze_params:
#: [on, beta at the eye, 1 / scale height, r, g, b, eye z]), all zero without haze; then the
#: fog block (fog.fog.fog_params), whose flag F_ON is zero without fog.
HAZE_SLOTS = 7


#: Layout of the fog block (fog_params): flag, colour, the axis in eye tangents (a ray (tx,
#: ty, 1) has axis component F_AXIS . (tx, ty, 1)), the table's spacing and eye entry,
#: sigma at the eye and beyond each end, the integrals from the eye to each end of the table,
#: the world axis, the eye cells' turning points, then the table: per resample plane the
#: average to it and sigma on it (the slope of the integral, limited).
#: The block follows the haze's slots in the kernels' one "air" array (background.air.air_params), so
#: every kernel that takes the haze takes the fog with it; the indices are into that array.
F_ON = HAZE_SLOTS
F_RGB = F_ON + 1
F_AXIS = F_ON + 4
F_INV_DT = F_ON + 7
F_DT = F_ON + 8
F_J0 = F_ON + 9
F_N = F_ON + 10
F_SIG_EYE = F_ON + 11
F_SIG_LO = F_ON + 12
F_SIG_HI = F_ON + 13
F_INT_LO = F_ON + 14
F_INT_HI = F_ON + 15
F_WORLD_AXIS = F_ON + 16
F_TURN_UP = F_ON + 19  # the eye's cells: where their cubic first turns back (or inf), and
F_PEAK_UP = F_ON + 20  # its value there (I / dt) (_eye_cell_turn)
F_TURN_DN = F_ON + 21
F_PEAK_DN = F_ON + 22
F_COARSENED = F_ON + 23  # 1 where the table spacing was widened (MAX_TABLE), for the stats
F_TABLE = F_ON + 24


class FrameConstants(NamedTuple):
    """What every kernel of one channel's frame needs to know of the view and the scene's
    backdrop, computed once per frame (geometry.view.frame_constants).

    Attributes:
        width, height: raster size, pixels.
        offsets: (S, 2) float64 sample positions inside a pixel, pixels from its top-left.
        offsets_fixed: (S, 2) int64 the same in 1/SUBPIXEL units (every pattern lies on that
            grid exactly).
        mapping: (4,) float64 (sx_scale, sx_off, sy_scale, sy_off): screen = tangent * scale +
            offset, pixels; eye ray (tx, ty, 1) passes through screen point (sx, sy).
        horizon: (3,) float64 (kx, ky, k0): world z of the eye ray through screen point
            (sx, sy) is kx sx + ky sy + k0 (negative below the horizon).
        dz_row: (3,) float64 world z of eye ray (tx, ty, 1) is dz_row . (tx, ty, 1).
        height_above: eye height above the earth plane, metres (at least
            geometry.view.MIN_HEIGHT_ABOVE_EARTH).
        sky, earth: (3,) float32 linear RGB of the sky and the earth plane.
        world_to_eye: (3, 3) float64, as View.world_to_eye.
        looks: (L, LOOK_SLOTS) float64 the scene's look table (scene/surfaces.py).
        texels, tex_level, tex_levels, tex_finest: the scene's TextureStore's (scene/textures.py)
            texels, level, levels and finest, flat: numba's parallel loops take the fields of a tuple
            argument, not of a tuple nested in it.
        texture_filter: index of RenderOptions.texture_filter in the options' registry
            (services.rig.options.TEXTURE_FILTERS).
    """

    width: int
    height: int
    offsets: np.ndarray
    offsets_fixed: np.ndarray
    mapping: np.ndarray
    horizon: np.ndarray
    dz_row: np.ndarray
    height_above: float
    sky: np.ndarray
    earth: np.ndarray
    world_to_eye: np.ndarray
    looks: np.ndarray
    texels: np.ndarray
    tex_level: np.ndarray
    tex_levels: np.ndarray
    tex_finest: np.ndarray
    texture_filter: int


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
            (coplanar, sharing one plane) the higher layer is seen.
        look: (N,) int32 row of the database's look table (scene/surfaces.py), -1 for a plain
            face; None when every polygon of the frame is plain (then colour is all there is).
        surface: (N, 3, 4) float64 with look: the face's texture-plane coordinates u, v
            (metres) and its light (Gouraud faces; 1 otherwise), each as G . p + k of the eye
            point p on the face (rows (Gx, Gy, Gz, k)); colour is then the unlit colour of
            a Gouraud face.
    """

    verts: np.ndarray
    start: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray
    feature_id: np.ndarray
    plane: np.ndarray
    layer: np.ndarray
    look: np.ndarray | None = None
    surface: np.ndarray | None = None

    def take(self, idx: np.ndarray, verts: np.ndarray, start: np.ndarray) -> Polygons:
        """New polygons with the given vertices and the attributes of polygons idx."""
        return Polygons(verts=verts, start=start, colour=self.colour[idx],
                        opacity=self.opacity[idx], feature_id=self.feature_id[idx],
                        plane=self.plane[idx], layer=self.layer[idx],
                        look=None if self.look is None else self.look[idx],
                        surface=None if self.surface is None else self.surface[idx])

    @property
    def polygon_count(self) -> int:
        return int(self.start.shape[0] - 1)


class ScreenPolygons(NamedTuple):
    """Projected polygons ready for binning and visibility.

    Attributes:
        fixed: (Nv, 2) int64 vertex positions in 1/SUBPIXEL pixel units (snapped).
        start: (N + 1,) int64 offsets into fixed.
        inv_z: (N, 3) float64 (A, B, C) with 1/z = A * sx + B * sy + C at screen point (sx, sy)
            in pixels, z the eye-space depth in metres.
        colour: (N, 3) float32 linear RGB after lighting.
        opacity: (N,) float32; 1 is opaque.
        feature_id: (N,) int32 identity of the source face.
        layer: (N,) int16 declared layer (Polygons.layer).
        look: (N,) int32 row of the database's look table, -1 for a plain polygon; an empty
            array when every polygon of the frame is plain (kernels then never read it).
        surface: (N, 9) float64 with look: Polygons.surface's u, v and light times 1/z, as
            screen planes (A, B, C) each (value / z = A sx + B sy + C), so that
            value = (A sx + B sy + C) / (1/z) at screen point (sx, sy): perspective-correct.
    """

    fixed: np.ndarray
    start: np.ndarray
    inv_z: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray
    feature_id: np.ndarray
    layer: np.ndarray
    look: np.ndarray = np.full(0, -1, np.int32)
    surface: np.ndarray = np.zeros((1, 9))

    @property
    def textured(self) -> bool:
        """Some polygon has a look (a texture or smooth shading)."""
        return bool(self.look.shape[0] > 0 and (self.look >= 0).any())

    @property
    def polygon_count(self) -> int:
        return int(self.start.shape[0] - 1)


class Edges(NamedTuple):
    """Edge equations, one row per polygon vertex (the edge from it to the next vertex).

    Attributes:
        e, f, g: (Nv,) float64 normalised line equation, pixels; d > 0 inside.
        ia, ib, ic: (Nv,) int64 exact edge function in 1/SUBPIXEL units; E > 0 inside.
        bias: (Nv,) int64 0 for top/left edges (a sample on the edge is inside), else 1.
        x0, x1, y0, y1: (N,) int64 first/last pixel column and row that can hold a covered
            sample, clipped to the raster.
        nearest_inv_z: (N,) float64 largest 1/z over the polygon (its nearest point).
    """

    e: np.ndarray
    f: np.ndarray
    g: np.ndarray
    ia: np.ndarray
    ib: np.ndarray
    ic: np.ndarray
    bias: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    y0: np.ndarray
    y1: np.ndarray
    nearest_inv_z: np.ndarray


class Bins(NamedTuple):
    """Per-sub-area feature lists, concatenated.

    Attributes:
        size: sub-area edge length, pixels.
        tiles_x, tiles_y: number of sub-areas across and down.
        start: (tiles_x * tiles_y + 1,) int64; the list of sub-area t (row-major) is
            entries start[t]:start[t + 1].
        polygon: (M,) int32 polygon index of each entry, nearest first within a list.
        full: (M,) bool, the polygon covers the whole sub-area.
    """

    size: int
    tiles_x: int
    tiles_y: int
    start: np.ndarray
    polygon: np.ndarray
    full: np.ndarray

    def counters(self) -> dict[str, int]:
        """Sub-area list entries by class, and the longest list."""
        full = int(self.full.sum())
        return {"subarea_entries_full": full,
                "subarea_entries_partial": int(self.full.shape[0]) - full,
                "subarea_list_max": int(np.diff(self.start).max(initial=0))}


class Background(NamedTuple):
    """What every sample sees behind the polygons (the background stage's output).

    A scene with terrain, haze, fog or clouds has one (on); any other gets no_background(), whose
    arrays are one-element stand-ins, so the kernels take one type either way.

    Attributes:
        on: the background stage ran: samples no polygon covers see rgb, and polygons are
            depth-tested against inv_z.
        rgb: (H, W, 3) float32 linear colour of the pixel's background: terrain over the sky
            or the earth plane, all through the haze and fog.
        inv_z: (H, W, S) float32 1/z (eye depth, metres) a polygon must exceed to be seen in
            front of the terrain (the terrain pushed back by the scene's polygon margin); 0
            where the sample sees sky or the earth plane, which never hide a polygon.
        range_m: (H, W) float32 nearest range of the background among the pixel's samples,
            metres (+inf for sky).
        cloud_on: the scene has clouds: cloud holds every pixel's.
        cloud: (H, W, 5) float32 the pixel's cloud (premultiplied linear RGB, opacity, range
            where its ray enters cloud, metres), already laid over rgb; polygons beyond the
            entry range are seen through it.
        air: the frame's haze and fog (the air layout above), built once by the stage; the
            visibility and resolve stages see the polygons through it (all zero: clear air).
    """

    on: bool
    rgb: np.ndarray
    inv_z: np.ndarray
    range_m: np.ndarray
    cloud_on: bool
    cloud: np.ndarray
    air: np.ndarray


def clear_air() -> np.ndarray:
    """The air array of a frame without haze or fog."""
    return np.zeros(F_TABLE + 1, np.float64)


def no_background() -> Background:
    """The Background of a scene with neither terrain, haze, fog nor clouds."""
    return Background(False, np.zeros((1, 1, 3), np.float32), np.zeros((1, 1, 1), np.float32),
                      np.zeros((1, 1), np.float32), False, no_cloud(), clear_air())


def no_cloud() -> np.ndarray:
    """The stand-in cloud array of a frame without clouds."""
    return np.zeros((1, 1, 5), np.float32)


@dataclass(frozen=True)
class SampleBuffer:
    """Per-sample visibility: which features every sample sees, nearest first.

    The store holds identities, not colours: the resolve stage shades each sample from the
    identities (so a sample costs 4 bytes when no translucent feature covers it).

    Attributes:
        offsets: (S, 2) float64 sample positions inside the pixel, pixels from its top-left.
        opaque: (H, W, S) int32 index into the frame's ScreenPolygons of the nearest opaque
            polygon covering the sample, or SKY_ID / EARTH_ID / BACKGROUND_ID where none does.
        translucent: (H, W, S, K) int32 indices of the translucent polygons nearer than the
            opaque one, nearest first; only the first translucent_count entries are meaningful.
            (1, 1, 1, K) when the frame has no translucent polygon (every count is then 0).
        translucent_count: (H, W, S) uint8, at most K.
        polygon_range: (H, W) float32 distance from the eye (metres) to the nearest opaque
            polygon seen by any sample of the pixel, +inf where no sample sees a polygon; None
            when the frame was rendered without ranges.
    """

    offsets: np.ndarray
    opaque: np.ndarray
    translucent: np.ndarray
    translucent_count: np.ndarray
    polygon_range: np.ndarray | None

    @property
    def max_translucent(self) -> int:
        return int(self.translucent.shape[3])


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
