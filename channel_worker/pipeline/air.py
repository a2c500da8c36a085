"""What lies between the eye and every sample: seed 002's haze and seed 004's fog, packed into
one float64 array for the kernels (the haze's slots, haze.haze_params, then the fog's,
fog.fog_params), so every kernel that sees through the air takes both with one argument."""

from __future__ import annotations

import numpy as np

from .fog import fog_params
from .haze import HAZE_SLOTS, haze_params
from .types import Database, View


def air_params(database: Database, view: View) -> np.ndarray:
    """The frame's air array: air[0] != 0 with haze, air[fog.F_ON] != 0 with fog."""
    out = fog_params(database.fog, view).params
    out[:HAZE_SLOTS] = haze_params(database.haze, float(view.eye[2]))
    return out


def no_air() -> np.ndarray:
    """The air array of a frame seen through clear air (kernels that shade nothing)."""
    return fog_params(None, None).params
