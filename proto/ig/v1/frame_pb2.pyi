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
    __slots__ = ("frame_number", "sim_time_s", "publish_time_unix_s", "control_sample_time_unix_s", "eyepoint", "run_id", "channels")
    FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    SIM_TIME_S_FIELD_NUMBER: _ClassVar[int]
    PUBLISH_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    CONTROL_SAMPLE_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    EYEPOINT_FIELD_NUMBER: _ClassVar[int]
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    CHANNELS_FIELD_NUMBER: _ClassVar[int]
    frame_number: int
    sim_time_s: float
    publish_time_unix_s: float
    control_sample_time_unix_s: float
    eyepoint: Eyepoint
    run_id: str
    channels: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, frame_number: _Optional[int] = ..., sim_time_s: _Optional[float] = ..., publish_time_unix_s: _Optional[float] = ..., control_sample_time_unix_s: _Optional[float] = ..., eyepoint: _Optional[_Union[Eyepoint, _Mapping]] = ..., run_id: _Optional[str] = ..., channels: _Optional[_Iterable[str]] = ...) -> None: ...
