"""What lies between the eye and every sample: seed 002's haze and seed 004's fog, packed into
one float64 array for the kernels (the haze's slots, haze.haze_params, then the fog's,
fog.fog_params), so every kernel that sees through the air takes both with one argument."""

from __future__ import annotations

import numpy as np

from .fog import fog_params
from .haze import HAZE_SLOTS, haze_params
from .types import Background, Database, View


def air_params(database: Database, view: View) -> np.ndarray:
    """The frame's air array: air[0] != 0 with haze, air[fog.F_ON] != 0 with fog."""
    out = fog_params(database.fog, view).params
    out[:HAZE_SLOTS] = haze_params(database.haze, float(view.eye[2]))
    return out


def frame_air(background: Background | None) -> np.ndarray:
    """The frame's air for the visibility and resolve kernels: the one the background stage
    built (every scene with haze or fog has that stage), else clear air."""
    if background is not None and background.air is not None:
        return background.air
    return fog_params(None, None).params
