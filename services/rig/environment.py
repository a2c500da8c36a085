"""What an external simulation host (CIGI) may change of a frame besides the eyepoint: the
weather, the visibility and the sun (Environment), and a channel's view (ChannelView).

The host builds them from CIGI packets (host_sim/cigi/), the workers apply them (the
environment to the scene's atmosphere, a view to their ChannelSpec); they travel in the Frame
message (``ig.v1.Environment``, ``ig.v1.ChannelView``), converted here.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ig.v1 import frame_pb2

from .frame import ChannelSpec, check_channel


@dataclass(frozen=True)
class WeatherLayer:
    """One weather layer, world metres (CIGI Weather Control, global scope).

    Attributes:
        layer_id: the host's layer id (CIGI: 0 ground fog, 1-3 cloud layers).
        base_m: world z of the layer's base.
        thickness_m: thickness (>= 0).
        visibility_m: meteorological visibility inside the layer (> 0; Koschmieder, 2 % contrast).
        coverage: share of the sky covered, 0..1.
        cloud: a cloud layer (the host named a cloud type); otherwise a fog stratum.
    """

    layer_id: int
    base_m: float
    thickness_m: float
    visibility_m: float
    coverage: float
    cloud: bool


@dataclass(frozen=True)
class Environment:
    """The environment set by an external host; None / () leaves the scene's own.

    Attributes:
        visibility_m: meteorological visibility of the haze at its base height, metres.
        layers: enabled weather layers.
        sun: unit vector towards the sun, world frame (x east, y north, z up).
    """

    visibility_m: float | None = None
    layers: tuple[WeatherLayer, ...] = ()
    sun: tuple[float, float, float] | None = None


def check_environment(env: Environment) -> None:
    """Raise ValueError naming the first field that cannot be rendered."""
    if env.visibility_m is not None and not (math.isfinite(env.visibility_m) and env.visibility_m > 0):
        raise ValueError(f"environment.visibility_m: {env.visibility_m} is not a finite number > 0")
    for i, layer in enumerate(env.layers):
        for name in ("base_m", "thickness_m", "visibility_m", "coverage"):
            if not math.isfinite(getattr(layer, name)):
                raise ValueError(f"environment.layers[{i}].{name}: {getattr(layer, name)} is not finite")
        if layer.thickness_m < 0:
            raise ValueError(f"environment.layers[{i}].thickness_m: {layer.thickness_m} is < 0")
        if not layer.visibility_m > 0:
            raise ValueError(f"environment.layers[{i}].visibility_m: {layer.visibility_m} is not > 0")
        if not 0.0 <= layer.coverage <= 1.0:
            raise ValueError(f"environment.layers[{i}].coverage: {layer.coverage} is outside [0, 1]")
    if env.sun is not None:
        norm = math.sqrt(sum(v * v for v in env.sun))
        if not (math.isfinite(norm) and abs(norm - 1.0) < 1e-6):
            raise ValueError(f"environment.sun: {env.sun} is not a unit vector")


def environment_to_proto(env: Environment) -> frame_pb2.Environment:
    """The message of an environment."""
    msg = frame_pb2.Environment(layers=[frame_pb2.WeatherLayer(**dataclasses.asdict(layer))
                                        for layer in env.layers])
    if env.visibility_m is not None:
        msg.visibility_m = env.visibility_m
    if env.sun is not None:
        msg.sun_x, msg.sun_y, msg.sun_z = env.sun
    return msg


def environment_from_proto(msg: frame_pb2.Environment) -> Environment:
    """The Environment of a message (not checked: check_environment)."""
    sun = (msg.sun_x, msg.sun_y, msg.sun_z) if msg.HasField("sun_x") else None
    return Environment(
        visibility_m=msg.visibility_m if msg.HasField("visibility_m") else None,
        layers=tuple(WeatherLayer(layer_id=la.layer_id, base_m=la.base_m, thickness_m=la.thickness_m,
                                  visibility_m=la.visibility_m, coverage=la.coverage, cloud=la.cloud)
                     for la in msg.layers),
        sun=sun)


#: The fields of a ChannelView message that override a ChannelSpec's, by the same names.
VIEW_FIELDS = ("yaw_deg", "pitch_deg", "roll_deg", "left_deg", "right_deg", "bottom_deg", "top_deg")


def apply_view(spec: ChannelSpec, view: frame_pb2.ChannelView) -> ChannelSpec:
    """spec with the fields the view sets.

    Raises:
        ValueError: the result is not a valid channel (named as check_channel names it).
    """
    changed = {name: getattr(view, name) for name in VIEW_FIELDS if view.HasField(name)}
    if not changed:
        return spec
    result = dataclasses.replace(spec, **changed)
    check_channel(result)
    return result
