from ig.v1 import frame_pb2 as _frame_pb2
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PixelFormat(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    PIXEL_FORMAT_UNSPECIFIED: _ClassVar[PixelFormat]
    PIXEL_FORMAT_RGB_F16: _ClassVar[PixelFormat]
PIXEL_FORMAT_UNSPECIFIED: PixelFormat
PIXEL_FORMAT_RGB_F16: PixelFormat

class SubmitChannelImageRequest(_message.Message):
    __slots__ = ("frame_number", "channel_name", "width", "height", "pixel_format", "pixels", "eyepoint", "render_time_s", "control_sample_time_unix_s", "frames_skipped", "run_id")
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
    def __init__(self, frame_number: _Optional[int] = ..., channel_name: _Optional[str] = ..., width: _Optional[int] = ..., height: _Optional[int] = ..., pixel_format: _Optional[_Union[PixelFormat, str]] = ..., pixels: _Optional[bytes] = ..., eyepoint: _Optional[_Union[_frame_pb2.Eyepoint, _Mapping]] = ..., render_time_s: _Optional[float] = ..., control_sample_time_unix_s: _Optional[float] = ..., frames_skipped: _Optional[int] = ..., run_id: _Optional[str] = ...) -> None: ...

class SubmitChannelImageResponse(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetCompositorReportRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetCompositorReportResponse(_message.Message):
    __slots__ = ("report_json", "finished", "frames_published", "frames_complete", "frames_incomplete", "frames_written")
    REPORT_JSON_FIELD_NUMBER: _ClassVar[int]
    FINISHED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_PUBLISHED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_COMPLETE_FIELD_NUMBER: _ClassVar[int]
    FRAMES_INCOMPLETE_FIELD_NUMBER: _ClassVar[int]
    FRAMES_WRITTEN_FIELD_NUMBER: _ClassVar[int]
    report_json: str
    finished: bool
    frames_published: int
    frames_complete: int
    frames_incomplete: int
    frames_written: int
    def __init__(self, report_json: _Optional[str] = ..., finished: _Optional[bool] = ..., frames_published: _Optional[int] = ..., frames_complete: _Optional[int] = ..., frames_incomplete: _Optional[int] = ..., frames_written: _Optional[int] = ...) -> None: ...
