"""The view of one channel for one frame: orientation conventions, the frustum, the screen
mapping and the horizon line.

Orientation: services.rig.frame.hpr_matrix (heading, pitch, roll applied in that order); a
channel's offset is applied in the aircraft's body frame after the aircraft's own attitude.

Horizon: the earth is an infinite plane at database.earth_height behind every feature; its
horizon is where the world-z component of a sample's ray changes sign, a straight line on the
screen at any roll. The visibility stages give a sample no polygon covers to the earth where
that component is negative, to the sky elsewhere.
"""

from __future__ import annotations

import math

import numpy as np

from channel_worker.pipeline.contract import FrameConstants, View, subpixel_offsets
from channel_worker.pipeline.scene.database import Database
from services.rig.frame import ChannelSpec, Eyepoint, check_channel, check_eyepoint, hpr_matrix
from services.rig.options import TEXTURE_FILTERS


def make_view(channel: ChannelSpec, eyepoint: Eyepoint, *, near: float = 0.25,
              far: float = 100_000.0) -> View:
    """The view of one channel from one eyepoint.

    The channel's yaw/pitch/roll offset is applied in the aircraft body frame after the
    aircraft's own attitude, so every channel of a rig shares the eyepoint and turns with it.
    """
    check_eyepoint(eyepoint)
    check_channel(channel)
    body = hpr_matrix(eyepoint.heading_deg, eyepoint.pitch_deg, eyepoint.roll_deg)
    chan = body @ hpr_matrix(channel.yaw_deg, channel.pitch_deg, channel.roll_deg)
    # Eye axes: x = channel right, y = channel up, z = channel forward.
    world_to_eye = np.stack([chan[:, 0], chan[:, 2], chan[:, 1]])
    return View(
        eye=np.asarray(eyepoint.position, dtype=np.float64).copy(),
        world_to_eye=world_to_eye,
        tan_left=math.tan(math.radians(channel.left_deg)),
        tan_right=math.tan(math.radians(channel.right_deg)),
        tan_bottom=math.tan(math.radians(channel.bottom_deg)),
        tan_top=math.tan(math.radians(channel.top_deg)),
        width=int(channel.width),
        height=int(channel.height),
        near=near,
        far=far,
    )


def screen_mapping(view: View) -> tuple[float, float, float, float]:
    """(sx_scale, sx_offset, sy_scale, sy_offset): screen = tangent * scale + offset, pixels.

    x: tan_left maps to 0 and tan_right to width; y: tan_top maps to 0 and tan_bottom to height
    (screen y grows downwards). Guard: check_channel guarantees left < right and bottom < top.
    """
    sx_scale = view.width / (view.tan_right - view.tan_left)
    sy_scale = -view.height / (view.tan_top - view.tan_bottom)
    return sx_scale, -view.tan_left * sx_scale, sy_scale, -view.tan_top * sy_scale


#: An eye at or below the earth plane is treated as this high above it (metres), so the picture
#: stays defined (earth below the horizon line) instead of flipping or dividing by zero.
MIN_HEIGHT_ABOVE_EARTH = 0.01


def earth_dz_row(view: View) -> np.ndarray:
    """(r0, r1, r2): world z of the eye ray (tx, ty, 1) is r0 tx + r1 ty + r2."""
    return np.ascontiguousarray(view.world_to_eye[:, 2])


def earth_dz_screen(view: View) -> tuple[float, float, float]:
    """(kx, ky, k0): world z of the eye ray through screen point (sx, sy) is kx sx + ky sy + k0.

    The ray is (tx, ty, 1) in eye coordinates, with tx, ty affine in sx, sy (project.py).
    """
    r0, r1, r2 = earth_dz_row(view)
    sx_scale, sx_off, sy_scale, sy_off = screen_mapping(view)
    return r0 / sx_scale, r1 / sy_scale, r2 - r0 * sx_off / sx_scale - r1 * sy_off / sy_scale


def height_above_earth(database: Database, view: View) -> float:
    """Eye height above the earth plane, metres, clamped to MIN_HEIGHT_ABOVE_EARTH."""
    return max(float(view.eye[2]) - database.earth_height, MIN_HEIGHT_ABOVE_EARTH)


def frame_constants(view: View, database: Database, offsets: np.ndarray,
                    texture_filter: str = "fade") -> FrameConstants:
    """The per-frame constants every kernel of the channel takes (contract.FrameConstants).

    Args:
        view: the channel's view for this frame.
        database: for the sky and earth colours and the earth plane's height.
        offsets: (S, 2) sample positions inside the pixel (RenderOptions.sample_offsets()).
        texture_filter: RenderOptions.texture_filter.
    """
    offsets = np.ascontiguousarray(offsets, np.float64)
    return FrameConstants(
        width=int(view.width), height=int(view.height), offsets=offsets,
        offsets_fixed=subpixel_offsets(offsets),
        mapping=np.array(screen_mapping(view), np.float64),
        horizon=np.array(earth_dz_screen(view), np.float64),
        dz_row=earth_dz_row(view), height_above=height_above_earth(database, view),
        sky=np.ascontiguousarray(database.sky_colour, np.float32),
        earth=np.ascontiguousarray(database.earth_colour, np.float32),
        world_to_eye=np.ascontiguousarray(view.world_to_eye, np.float64),
        looks=database.looks, texels=database.textures.texels, tex_level=database.textures.level,
        tex_levels=database.textures.levels, tex_finest=database.textures.finest,
        texture_filter=list(TEXTURE_FILTERS).index(texture_filter))
