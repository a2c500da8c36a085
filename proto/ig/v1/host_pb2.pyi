from ig.v1 import frame_pb2 as _frame_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class SubscribeFramesRequest(_message.Message):
    __slots__ = ("subscriber", "channel_name")
    SUBSCRIBER_FIELD_NUMBER: _ClassVar[int]
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    subscriber: str
    channel_name: str
    def __init__(self, subscriber: _Optional[str] = ..., channel_name: _Optional[str] = ...) -> None: ...

class SubscribeFramesResponse(_message.Message):
    __slots__ = ("frame",)
    FRAME_FIELD_NUMBER: _ClassVar[int]
    frame: _frame_pb2.Frame
    def __init__(self, frame: _Optional[_Union[_frame_pb2.Frame, _Mapping]] = ...) -> None: ...

class AckFrameRequest(_message.Message):
    __slots__ = ("channel_name", "frame_number", "ok", "error")
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    OK_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    channel_name: str
    frame_number: int
    ok: bool
    error: str
    def __init__(self, channel_name: _Optional[str] = ..., frame_number: _Optional[int] = ..., ok: _Optional[bool] = ..., error: _Optional[str] = ...) -> None: ...

class AckFrameResponse(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetHostStatusRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetHostStatusResponse(_message.Message):
    __slots__ = ("run_id", "frames_published", "eyepoints_rejected", "ack_timeouts", "ack_failures", "queue_drops", "subscriptions_rejected", "subscribers", "finished", "last_error", "channel_absent")
    class AckTimeoutsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class AckFailuresEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class QueueDropsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class ChannelAbsentEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    FRAMES_PUBLISHED_FIELD_NUMBER: _ClassVar[int]
    EYEPOINTS_REJECTED_FIELD_NUMBER: _ClassVar[int]
    ACK_TIMEOUTS_FIELD_NUMBER: _ClassVar[int]
    ACK_FAILURES_FIELD_NUMBER: _ClassVar[int]
    QUEUE_DROPS_FIELD_NUMBER: _ClassVar[int]
    SUBSCRIPTIONS_REJECTED_FIELD_NUMBER: _ClassVar[int]
    SUBSCRIBERS_FIELD_NUMBER: _ClassVar[int]
    FINISHED_FIELD_NUMBER: _ClassVar[int]
    LAST_ERROR_FIELD_NUMBER: _ClassVar[int]
    CHANNEL_ABSENT_FIELD_NUMBER: _ClassVar[int]
    run_id: str
    frames_published: int
    eyepoints_rejected: int
    ack_timeouts: _containers.ScalarMap[str, int]
    ack_failures: _containers.ScalarMap[str, int]
    queue_drops: _containers.ScalarMap[str, int]
    subscriptions_rejected: int
    subscribers: _containers.RepeatedScalarFieldContainer[str]
    finished: bool
    last_error: str
    channel_absent: _containers.ScalarMap[str, int]
    def __init__(self, run_id: _Optional[str] = ..., frames_published: _Optional[int] = ..., eyepoints_rejected: _Optional[int] = ..., ack_timeouts: _Optional[_Mapping[str, int]] = ..., ack_failures: _Optional[_Mapping[str, int]] = ..., queue_drops: _Optional[_Mapping[str, int]] = ..., subscriptions_rejected: _Optional[int] = ..., subscribers: _Optional[_Iterable[str]] = ..., finished: _Optional[bool] = ..., last_error: _Optional[str] = ..., channel_absent: _Optional[_Mapping[str, int]] = ...) -> None: ...
