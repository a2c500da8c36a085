"""What lies between the eye and every sample: the haze and the layered fog, packed into one
float64 array for the kernels (the contract's air layout: the haze's slots, haze.haze_params,
then the fog's, fog.fog_params), so every kernel that sees through the air takes both with one
argument."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.contract import HAZE_SLOTS, View
from channel_worker.pipeline.fog.fog import fog_params
from channel_worker.pipeline.scene.database import Database

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
