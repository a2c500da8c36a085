"""What lies between the eye and every sample: the haze and the layered fog, packed into one
float64 array for the kernels (the contract's air layout: the haze's slots, haze.haze_params,
then the fog's, fog.fog_params), so every kernel that sees through the air takes both with one
argument; and what that air makes of the sky and the earth plane, by elevation."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import F_ON, F_WORLD_AXIS, HAZE_SLOTS, FrameConstants, View
from channel_worker.pipeline.fog.fog import fog_params
from channel_worker.pipeline.scene.database import Database

from ._groups import SkyTable
from ._sky_kernels import SKY_TABLE_SIZE, sky_table_kernel
from .haze import haze_params


def air_params(database: Database, view: View, fog_table_subdivision: int) -> np.ndarray:
    """The frame's air array: air[0] != 0 with haze, air[F_ON] != 0 with fog.

    Args:
        fog_table_subdivision: resample planes per fog sample-plane spacing
            (RenderOptions.fog_table_subdivision), where the scene sets no table spacing.
    """
    out = fog_params(database.fog, view, subdivision=fog_table_subdivision).params
    out[:HAZE_SLOTS] = haze_params(database.haze, float(view.eye[2]))
    return out


def sky_table(frame: FrameConstants, air: np.ndarray) -> SkyTable:
    """The sky and the earth plane through the frame's air at SKY_TABLE_SIZE elevations, so
    that a pixel's costs one interpolated read: where the air depends on elevation alone (the
    haze always does; fog where its strata are stacked along the vertical). Fog along a
    tilted axis depends on azimuth too: then the table is a stand-in and every pixel is
    computed (_sky_kernels.backdrop)."""
    axis = air[F_WORLD_AXIS:F_WORLD_AXIS + 3]
    if air[F_ON] != 0.0 and (axis[0] != 0.0 or axis[1] != 0.0):
        stand_in = np.zeros((1, 3))
        return SkyTable(False, stand_in, stand_in)
    sky = np.empty((SKY_TABLE_SIZE, 3))
    earth = np.empty((SKY_TABLE_SIZE, 3))
    sky_table_kernel(frame, air, sky, earth)
    return SkyTable(True, sky, earth)
