from ig.v1 import frame_pb2 as _frame_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PixelFormat(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    PIXEL_FORMAT_UNSPECIFIED: _ClassVar[PixelFormat]
    PIXEL_FORMAT_RGB_F16: _ClassVar[PixelFormat]
    PIXEL_FORMAT_RGB_SRGB8: _ClassVar[PixelFormat]
PIXEL_FORMAT_UNSPECIFIED: PixelFormat
PIXEL_FORMAT_RGB_F16: PixelFormat
PIXEL_FORMAT_RGB_SRGB8: PixelFormat

class SharedImage(_message.Message):
    __slots__ = ("segment", "slot", "sequence")
    SEGMENT_FIELD_NUMBER: _ClassVar[int]
    SLOT_FIELD_NUMBER: _ClassVar[int]
    SEQUENCE_FIELD_NUMBER: _ClassVar[int]
    segment: str
    slot: int
    sequence: int
    def __init__(self, segment: _Optional[str] = ..., slot: _Optional[int] = ..., sequence: _Optional[int] = ...) -> None: ...

class SubmitChannelImageRequest(_message.Message):
    __slots__ = ("frame_number", "channel_name", "width", "height", "pixel_format", "pixels", "eyepoint", "render_time_s", "control_sample_time_unix_s", "frames_skipped", "run_id", "frame_received_unix_s", "render_start_unix_s", "render_end_unix_s", "submit_unix_s", "shared")
    FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    PIXEL_FORMAT_FIELD_NUMBER: _ClassVar[int]
    PIXELS_FIELD_NUMBER: _ClassVar[int]
    EYEPOINT_FIELD_NUMBER: _ClassVar[int]
    RENDER_TIME_S_FIELD_NUMBER: _ClassVar[int]
    CONTROL_SAMPLE_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    FRAMES_SKIPPED_FIELD_NUMBER: _ClassVar[int]
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    FRAME_RECEIVED_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    RENDER_START_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    RENDER_END_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    SUBMIT_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    SHARED_FIELD_NUMBER: _ClassVar[int]
    frame_number: int
    channel_name: str
    width: int
    height: int
    pixel_format: PixelFormat
    pixels: bytes
    eyepoint: _frame_pb2.Eyepoint
    render_time_s: float
    control_sample_time_unix_s: float
    frames_skipped: int
    run_id: str
    frame_received_unix_s: float
    render_start_unix_s: float
    render_end_unix_s: float
    submit_unix_s: float
    shared: SharedImage
    def __init__(self, frame_number: _Optional[int] = ..., channel_name: _Optional[str] = ..., width: _Optional[int] = ..., height: _Optional[int] = ..., pixel_format: _Optional[_Union[PixelFormat, str]] = ..., pixels: _Optional[bytes] = ..., eyepoint: _Optional[_Union[_frame_pb2.Eyepoint, _Mapping]] = ..., render_time_s: _Optional[float] = ..., control_sample_time_unix_s: _Optional[float] = ..., frames_skipped: _Optional[int] = ..., run_id: _Optional[str] = ..., frame_received_unix_s: _Optional[float] = ..., render_start_unix_s: _Optional[float] = ..., render_end_unix_s: _Optional[float] = ..., submit_unix_s: _Optional[float] = ..., shared: _Optional[_Union[SharedImage, _Mapping]] = ...) -> None: ...

class SubmitChannelImageResponse(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetCompositorReportRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetCompositorReportResponse(_message.Message):
    __slots__ = ("report_json", "finished", "frames_published", "frames_complete", "frames_incomplete", "frames_written", "frames_not_recorded")
    REPORT_JSON_FIELD_NUMBER: _ClassVar[int]
    FINISHED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_PUBLISHED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_COMPLETE_FIELD_NUMBER: _ClassVar[int]
    FRAMES_INCOMPLETE_FIELD_NUMBER: _ClassVar[int]
    FRAMES_WRITTEN_FIELD_NUMBER: _ClassVar[int]
    FRAMES_NOT_RECORDED_FIELD_NUMBER: _ClassVar[int]
    report_json: str
    finished: bool
    frames_published: int
    frames_complete: int
    frames_incomplete: int
    frames_written: int
    frames_not_recorded: int
    def __init__(self, report_json: _Optional[str] = ..., finished: _Optional[bool] = ..., frames_published: _Optional[int] = ..., frames_complete: _Optional[int] = ..., frames_incomplete: _Optional[int] = ..., frames_written: _Optional[int] = ..., frames_not_recorded: _Optional[int] = ...) -> None: ...

class WatchCompositesRequest(_message.Message):
    __slots__ = ("watcher", "profile_channels")
    WATCHER_FIELD_NUMBER: _ClassVar[int]
    PROFILE_CHANNELS_FIELD_NUMBER: _ClassVar[int]
    watcher: str
    profile_channels: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, watcher: _Optional[str] = ..., profile_channels: _Optional[_Iterable[str]] = ...) -> None: ...

class ChannelTiming(_message.Message):
    __slots__ = ("channel_name", "frame_received_unix_s", "render_start_unix_s", "render_end_unix_s", "submit_unix_s", "compositor_receive_unix_s")
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    FRAME_RECEIVED_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    RENDER_START_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    RENDER_END_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    SUBMIT_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    COMPOSITOR_RECEIVE_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    channel_name: str
    frame_received_unix_s: float
    render_start_unix_s: float
    render_end_unix_s: float
    submit_unix_s: float
    compositor_receive_unix_s: float
    def __init__(self, channel_name: _Optional[str] = ..., frame_received_unix_s: _Optional[float] = ..., render_start_unix_s: _Optional[float] = ..., render_end_unix_s: _Optional[float] = ..., submit_unix_s: _Optional[float] = ..., compositor_receive_unix_s: _Optional[float] = ...) -> None: ...

class RowProfile(_message.Message):
    __slots__ = ("channel_name", "luminance")
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    LUMINANCE_FIELD_NUMBER: _ClassVar[int]
    channel_name: str
    luminance: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, channel_name: _Optional[str] = ..., luminance: _Optional[_Iterable[float]] = ...) -> None: ...

class WatchCompositesResponse(_message.Message):
    __slots__ = ("frame_number", "run_id", "sim_time_s", "eyepoint", "control_sample_time_unix_s", "publish_time_unix_s", "composite_time_unix_s", "channels", "profiles", "watcher_drops", "host_frame_number")
    FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    SIM_TIME_S_FIELD_NUMBER: _ClassVar[int]
    EYEPOINT_FIELD_NUMBER: _ClassVar[int]
    CONTROL_SAMPLE_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    PUBLISH_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    COMPOSITE_TIME_UNIX_S_FIELD_NUMBER: _ClassVar[int]
    CHANNELS_FIELD_NUMBER: _ClassVar[int]
    PROFILES_FIELD_NUMBER: _ClassVar[int]
    WATCHER_DROPS_FIELD_NUMBER: _ClassVar[int]
    HOST_FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    frame_number: int
    run_id: str
    sim_time_s: float
    eyepoint: _frame_pb2.Eyepoint
    control_sample_time_unix_s: float
    publish_time_unix_s: float
    composite_time_unix_s: float
    channels: _containers.RepeatedCompositeFieldContainer[ChannelTiming]
    profiles: _containers.RepeatedCompositeFieldContainer[RowProfile]
    watcher_drops: int
    host_frame_number: int
    def __init__(self, frame_number: _Optional[int] = ..., run_id: _Optional[str] = ..., sim_time_s: _Optional[float] = ..., eyepoint: _Optional[_Union[_frame_pb2.Eyepoint, _Mapping]] = ..., control_sample_time_unix_s: _Optional[float] = ..., publish_time_unix_s: _Optional[float] = ..., composite_time_unix_s: _Optional[float] = ..., channels: _Optional[_Iterable[_Union[ChannelTiming, _Mapping]]] = ..., profiles: _Optional[_Iterable[_Union[RowProfile, _Mapping]]] = ..., watcher_drops: _Optional[int] = ..., host_frame_number: _Optional[int] = ...) -> None: ...
