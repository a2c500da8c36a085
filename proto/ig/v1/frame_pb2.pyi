from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Eyepoint(_message.Message):
    __slots__ = ("x", "y", "z", "heading_deg", "pitch_deg", "roll_deg")
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    HEADING_DEG_FIELD_NUMBER: _ClassVar[int]
    PITCH_DEG_FIELD_NUMBER: _ClassVar[int]
    ROLL_DEG_FIELD_NUMBER: _ClassVar[int]
    x: float
    y: float
    z: float
    heading_deg: float
    pitch_deg: float
    roll_deg: float
    def __init__(self, x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., heading_deg: _Optional[float] = ..., pitch_deg: _Optional[float] = ..., roll_deg: _Optional[float] = ...) -> None: ...

class Frame(_message.Message):
    __slots__ = ("frame_number", "sim_time_s", "publish_time_unix_s", "control_sample_time_unix_s", "eyepoint", "run_id", "channels", "host_frame_number", "environment", "views")
    FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    SIM_TIME_S_FIELD_NUMBER: _ClassVar[int]
    PUBLISH_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    CONTROL_SAMPLE_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    EYEPOINT_FIELD_NUMBER: _ClassVar[int]
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    CHANNELS_FIELD_NUMBER: _ClassVar[int]
    HOST_FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    ENVIRONMENT_FIELD_NUMBER: _ClassVar[int]
    VIEWS_FIELD_NUMBER: _ClassVar[int]
    frame_number: int
    sim_time_s: float
    publish_time_unix_s: float
    control_sample_time_unix_s: float
    eyepoint: Eyepoint
    run_id: str
    channels: _containers.RepeatedScalarFieldContainer[str]
    host_frame_number: int
    environment: Environment
    views: _containers.RepeatedCompositeFieldContainer[ChannelView]
    def __init__(self, frame_number: _Optional[int] = ..., sim_time_s: _Optional[float] = ..., publish_time_unix_s: _Optional[float] = ..., control_sample_time_unix_s: _Optional[float] = ..., eyepoint: _Optional[_Union[Eyepoint, _Mapping]] = ..., run_id: _Optional[str] = ..., channels: _Optional[_Iterable[str]] = ..., host_frame_number: _Optional[int] = ..., environment: _Optional[_Union[Environment, _Mapping]] = ..., views: _Optional[_Iterable[_Union[ChannelView, _Mapping]]] = ...) -> None: ...

class ChannelView(_message.Message):
    __slots__ = ("channel", "yaw_deg", "pitch_deg", "roll_deg", "left_deg", "right_deg", "bottom_deg", "top_deg")
    CHANNEL_FIELD_NUMBER: _ClassVar[int]
    YAW_DEG_FIELD_NUMBER: _ClassVar[int]
    PITCH_DEG_FIELD_NUMBER: _ClassVar[int]
    ROLL_DEG_FIELD_NUMBER: _ClassVar[int]
    LEFT_DEG_FIELD_NUMBER: _ClassVar[int]
    RIGHT_DEG_FIELD_NUMBER: _ClassVar[int]
    BOTTOM_DEG_FIELD_NUMBER: _ClassVar[int]
    TOP_DEG_FIELD_NUMBER: _ClassVar[int]
    channel: str
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    left_deg: float
    right_deg: float
    bottom_deg: float
    top_deg: float
    def __init__(self, channel: _Optional[str] = ..., yaw_deg: _Optional[float] = ..., pitch_deg: _Optional[float] = ..., roll_deg: _Optional[float] = ..., left_deg: _Optional[float] = ..., right_deg: _Optional[float] = ..., bottom_deg: _Optional[float] = ..., top_deg: _Optional[float] = ...) -> None: ...

class WeatherLayer(_message.Message):
    __slots__ = ("layer_id", "base_m", "thickness_m", "visibility_m", "coverage", "cloud")
    LAYER_ID_FIELD_NUMBER: _ClassVar[int]
    BASE_M_FIELD_NUMBER: _ClassVar[int]
    THICKNESS_M_FIELD_NUMBER: _ClassVar[int]
    VISIBILITY_M_FIELD_NUMBER: _ClassVar[int]
    COVERAGE_FIELD_NUMBER: _ClassVar[int]
    CLOUD_FIELD_NUMBER: _ClassVar[int]
    layer_id: int
    base_m: float
    thickness_m: float
    visibility_m: float
    coverage: float
    cloud: bool
    def __init__(self, layer_id: _Optional[int] = ..., base_m: _Optional[float] = ..., thickness_m: _Optional[float] = ..., visibility_m: _Optional[float] = ..., coverage: _Optional[float] = ..., cloud: _Optional[bool] = ...) -> None: ...

class Environment(_message.Message):
    __slots__ = ("visibility_m", "layers", "sun_x", "sun_y", "sun_z")
    VISIBILITY_M_FIELD_NUMBER: _ClassVar[int]
    LAYERS_FIELD_NUMBER: _ClassVar[int]
    SUN_X_FIELD_NUMBER: _ClassVar[int]
    SUN_Y_FIELD_NUMBER: _ClassVar[int]
    SUN_Z_FIELD_NUMBER: _ClassVar[int]
    visibility_m: float
    layers: _containers.RepeatedCompositeFieldContainer[WeatherLayer]
    sun_x: float
    sun_y: float
    sun_z: float
    def __init__(self, visibility_m: _Optional[float] = ..., layers: _Optional[_Iterable[_Union[WeatherLayer, _Mapping]]] = ..., sun_x: _Optional[float] = ..., sun_y: _Optional[float] = ..., sun_z: _Optional[float] = ...) -> None: ...
