"""Shading of one sample: what a feature looks like from the eye, through the air.

One function for every path that turns a sample's features into a colour (the box filter
inside each sub-area during visibility, and the resolve stage's filters), so the atmosphere
is applied the same way wherever a polygon is seen.
"""

from __future__ import annotations

from numba import njit

from channel_worker.pipeline.background.haze import haze_amount
from channel_worker.pipeline.contract import F_ON
from channel_worker.pipeline.fog.fog import fog_blend


@njit(cache=True, inline="always")
def through_air(air, cloud_on, cloud, y, x, range_m, sin_el, cos_ax, r, g, b):
    """A polygon's colour seen at range_m along a ray of elevation sine sin_el and fog-axis
    cosine cos_ax: through the haze and the fog (air.air_params), then through pixel (x, y)'s
    cloud (Background.cloud) if the polygon lies beyond the cloud's entry range."""
    if air[0] != 0.0:
        h = haze_amount(air, range_m, sin_el)
        r = r * (1.0 - h) + air[3] * h
        g = g * (1.0 - h) + air[4] * h
        b = b * (1.0 - h) + air[5] * h
    if air[F_ON] != 0.0:
        r, g, b = fog_blend(air, range_m, cos_ax, r, g, b)
    if cloud_on and cloud[y, x, 3] > 0.0 and range_m > cloud[y, x, 4]:
        keep = 1.0 - cloud[y, x, 3]
        r = cloud[y, x, 0] + keep * r
        g = cloud[y, x, 1] + keep * g
        b = cloud[y, x, 2] + keep * b
    return r, g, b
