from ig.v1 import render_pb2 as _render_pb2
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class GetWorkerStatusRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetWorkerStatusResponse(_message.Message):
    __slots__ = ("channel_name", "subscribed", "run_id", "last_frame_number", "frames_handled", "frames_rendered", "frames_skipped", "frames_refused", "submit_failures", "ack_failures", "last_error", "translucent_dropped", "terrain_voxels_last_frame", "terrain_voxels_total", "terrain_eye_clamped", "render_options", "last_frame_report", "ready", "runs", "malformed_requests", "resubscriptions")
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    SUBSCRIBED_FIELD_NUMBER: _ClassVar[int]
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    LAST_FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    FRAMES_HANDLED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_RENDERED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_SKIPPED_FIELD_NUMBER: _ClassVar[int]
    FRAMES_REFUSED_FIELD_NUMBER: _ClassVar[int]
    SUBMIT_FAILURES_FIELD_NUMBER: _ClassVar[int]
    ACK_FAILURES_FIELD_NUMBER: _ClassVar[int]
    LAST_ERROR_FIELD_NUMBER: _ClassVar[int]
    TRANSLUCENT_DROPPED_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_VOXELS_LAST_FRAME_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_VOXELS_TOTAL_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_EYE_CLAMPED_FIELD_NUMBER: _ClassVar[int]
    RENDER_OPTIONS_FIELD_NUMBER: _ClassVar[int]
    LAST_FRAME_REPORT_FIELD_NUMBER: _ClassVar[int]
    READY_FIELD_NUMBER: _ClassVar[int]
    RUNS_FIELD_NUMBER: _ClassVar[int]
    MALFORMED_REQUESTS_FIELD_NUMBER: _ClassVar[int]
    RESUBSCRIPTIONS_FIELD_NUMBER: _ClassVar[int]
    channel_name: str
    subscribed: bool
    run_id: str
    last_frame_number: int
    frames_handled: int
    frames_rendered: int
    frames_skipped: int
    frames_refused: int
    submit_failures: int
    ack_failures: int
    last_error: str
    translucent_dropped: int
    terrain_voxels_last_frame: int
    terrain_voxels_total: int
    terrain_eye_clamped: int
    render_options: _render_pb2.RenderOptions
    last_frame_report: _render_pb2.FrameReport
    ready: bool
    runs: int
    malformed_requests: int
    resubscriptions: int
    def __init__(self, channel_name: _Optional[str] = ..., subscribed: _Optional[bool] = ..., run_id: _Optional[str] = ..., last_frame_number: _Optional[int] = ..., frames_handled: _Optional[int] = ..., frames_rendered: _Optional[int] = ..., frames_skipped: _Optional[int] = ..., frames_refused: _Optional[int] = ..., submit_failures: _Optional[int] = ..., ack_failures: _Optional[int] = ..., last_error: _Optional[str] = ..., translucent_dropped: _Optional[int] = ..., terrain_voxels_last_frame: _Optional[int] = ..., terrain_voxels_total: _Optional[int] = ..., terrain_eye_clamped: _Optional[int] = ..., render_options: _Optional[_Union[_render_pb2.RenderOptions, _Mapping]] = ..., last_frame_report: _Optional[_Union[_render_pb2.FrameReport, _Mapping]] = ..., ready: _Optional[bool] = ..., runs: _Optional[int] = ..., malformed_requests: _Optional[int] = ..., resubscriptions: _Optional[int] = ...) -> None: ...
