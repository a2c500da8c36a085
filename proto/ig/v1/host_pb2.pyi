from ig.v1 import frame_pb2 as _frame_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class RunEndReason(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    RUN_END_REASON_UNSPECIFIED: _ClassVar[RunEndReason]
    RUN_END_REASON_COMPLETED: _ClassVar[RunEndReason]
    RUN_END_REASON_STOPPED: _ClassVar[RunEndReason]
RUN_END_REASON_UNSPECIFIED: RunEndReason
RUN_END_REASON_COMPLETED: RunEndReason
RUN_END_REASON_STOPPED: RunEndReason

class SubscribeFramesRequest(_message.Message):
    __slots__ = ("subscriber", "channel_name")
    SUBSCRIBER_FIELD_NUMBER: _ClassVar[int]
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    subscriber: str
    channel_name: str
    def __init__(self, subscriber: _Optional[str] = ..., channel_name: _Optional[str] = ...) -> None: ...

class SubscribeFramesResponse(_message.Message):
    __slots__ = ("frame", "run_end")
    FRAME_FIELD_NUMBER: _ClassVar[int]
    RUN_END_FIELD_NUMBER: _ClassVar[int]
    frame: _frame_pb2.Frame
    run_end: RunEnd
    def __init__(self, frame: _Optional[_Union[_frame_pb2.Frame, _Mapping]] = ..., run_end: _Optional[_Union[RunEnd, _Mapping]] = ...) -> None: ...

class RunEnd(_message.Message):
    __slots__ = ("reason", "host_status")
    REASON_FIELD_NUMBER: _ClassVar[int]
    HOST_STATUS_FIELD_NUMBER: _ClassVar[int]
    reason: RunEndReason
    host_status: GetHostStatusResponse
    def __init__(self, reason: _Optional[_Union[RunEndReason, str]] = ..., host_status: _Optional[_Union[GetHostStatusResponse, _Mapping]] = ...) -> None: ...

class AckFrameRequest(_message.Message):
    __slots__ = ("channel_name", "frame_number", "ok", "error", "run_id")
    CHANNEL_NAME_FIELD_NUMBER: _ClassVar[int]
    FRAME_NUMBER_FIELD_NUMBER: _ClassVar[int]
    OK_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    RUN_ID_FIELD_NUMBER: _ClassVar[int]
    channel_name: str
    frame_number: int
    ok: bool
    error: str
    run_id: str
    def __init__(self, channel_name: _Optional[str] = ..., frame_number: _Optional[int] = ..., ok: _Optional[bool] = ..., error: _Optional[str] = ..., run_id: _Optional[str] = ...) -> None: ...

class AckFrameResponse(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetHostStatusRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class GetHostStatusResponse(_message.Message):
    __slots__ = ("run_id", "frames_published", "eyepoints_rejected", "ack_timeouts", "ack_failures", "queue_drops", "subscriptions_rejected", "subscribers", "finished", "last_error", "channel_absent", "eyepoint_source", "inputs", "replay", "flight_model", "requests_refused", "late_acks", "cigi", "runs")
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
    class RequestsRefusedEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class LateAcksEntry(_message.Message):
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
    EYEPOINT_SOURCE_FIELD_NUMBER: _ClassVar[int]
    INPUTS_FIELD_NUMBER: _ClassVar[int]
    REPLAY_FIELD_NUMBER: _ClassVar[int]
    FLIGHT_MODEL_FIELD_NUMBER: _ClassVar[int]
    REQUESTS_REFUSED_FIELD_NUMBER: _ClassVar[int]
    LATE_ACKS_FIELD_NUMBER: _ClassVar[int]
    CIGI_FIELD_NUMBER: _ClassVar[int]
    RUNS_FIELD_NUMBER: _ClassVar[int]
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
    eyepoint_source: str
    inputs: _containers.RepeatedCompositeFieldContainer[InputSourceStatus]
    replay: ReplayStatus
    flight_model: FlightModelStatus
    requests_refused: _containers.ScalarMap[str, int]
    late_acks: _containers.ScalarMap[str, int]
    cigi: CigiStatus
    runs: int
    def __init__(self, run_id: _Optional[str] = ..., frames_published: _Optional[int] = ..., eyepoints_rejected: _Optional[int] = ..., ack_timeouts: _Optional[_Mapping[str, int]] = ..., ack_failures: _Optional[_Mapping[str, int]] = ..., queue_drops: _Optional[_Mapping[str, int]] = ..., subscriptions_rejected: _Optional[int] = ..., subscribers: _Optional[_Iterable[str]] = ..., finished: _Optional[bool] = ..., last_error: _Optional[str] = ..., channel_absent: _Optional[_Mapping[str, int]] = ..., eyepoint_source: _Optional[str] = ..., inputs: _Optional[_Iterable[_Union[InputSourceStatus, _Mapping]]] = ..., replay: _Optional[_Union[ReplayStatus, _Mapping]] = ..., flight_model: _Optional[_Union[FlightModelStatus, _Mapping]] = ..., requests_refused: _Optional[_Mapping[str, int]] = ..., late_acks: _Optional[_Mapping[str, int]] = ..., cigi: _Optional[_Union[CigiStatus, _Mapping]] = ..., runs: _Optional[int] = ...) -> None: ...

class CigiStatus(_message.Message):
    __slots__ = ("listen", "host_address", "version", "byte_order", "mode", "ig_mode", "messages", "refused", "packets", "unused", "skipped", "last_host_frame", "ig_frames", "stale", "stale_events", "restarts", "entities", "queries_answered", "queries_invalid", "queries_failed", "periodic_requests", "messages_dropped", "responses_deferred", "last_error", "responses_dropped", "ownship", "query_database")
    class RefusedEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class PacketsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class UnusedEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    LISTEN_FIELD_NUMBER: _ClassVar[int]
    HOST_ADDRESS_FIELD_NUMBER: _ClassVar[int]
    VERSION_FIELD_NUMBER: _ClassVar[int]
    BYTE_ORDER_FIELD_NUMBER: _ClassVar[int]
    MODE_FIELD_NUMBER: _ClassVar[int]
    IG_MODE_FIELD_NUMBER: _ClassVar[int]
    MESSAGES_FIELD_NUMBER: _ClassVar[int]
    REFUSED_FIELD_NUMBER: _ClassVar[int]
    PACKETS_FIELD_NUMBER: _ClassVar[int]
    UNUSED_FIELD_NUMBER: _ClassVar[int]
    SKIPPED_FIELD_NUMBER: _ClassVar[int]
    LAST_HOST_FRAME_FIELD_NUMBER: _ClassVar[int]
    IG_FRAMES_FIELD_NUMBER: _ClassVar[int]
    STALE_FIELD_NUMBER: _ClassVar[int]
    STALE_EVENTS_FIELD_NUMBER: _ClassVar[int]
    RESTARTS_FIELD_NUMBER: _ClassVar[int]
    ENTITIES_FIELD_NUMBER: _ClassVar[int]
    QUERIES_ANSWERED_FIELD_NUMBER: _ClassVar[int]
    QUERIES_INVALID_FIELD_NUMBER: _ClassVar[int]
    QUERIES_FAILED_FIELD_NUMBER: _ClassVar[int]
    PERIODIC_REQUESTS_FIELD_NUMBER: _ClassVar[int]
    MESSAGES_DROPPED_FIELD_NUMBER: _ClassVar[int]
    RESPONSES_DEFERRED_FIELD_NUMBER: _ClassVar[int]
    LAST_ERROR_FIELD_NUMBER: _ClassVar[int]
    RESPONSES_DROPPED_FIELD_NUMBER: _ClassVar[int]
    OWNSHIP_FIELD_NUMBER: _ClassVar[int]
    QUERY_DATABASE_FIELD_NUMBER: _ClassVar[int]
    listen: str
    host_address: str
    version: str
    byte_order: str
    mode: str
    ig_mode: str
    messages: int
    refused: _containers.ScalarMap[str, int]
    packets: _containers.ScalarMap[str, int]
    unused: _containers.ScalarMap[str, int]
    skipped: int
    last_host_frame: int
    ig_frames: int
    stale: bool
    stale_events: int
    restarts: int
    entities: int
    queries_answered: int
    queries_invalid: int
    queries_failed: int
    periodic_requests: int
    messages_dropped: int
    responses_deferred: int
    last_error: str
    responses_dropped: int
    ownship: str
    query_database: str
    def __init__(self, listen: _Optional[str] = ..., host_address: _Optional[str] = ..., version: _Optional[str] = ..., byte_order: _Optional[str] = ..., mode: _Optional[str] = ..., ig_mode: _Optional[str] = ..., messages: _Optional[int] = ..., refused: _Optional[_Mapping[str, int]] = ..., packets: _Optional[_Mapping[str, int]] = ..., unused: _Optional[_Mapping[str, int]] = ..., skipped: _Optional[int] = ..., last_host_frame: _Optional[int] = ..., ig_frames: _Optional[int] = ..., stale: _Optional[bool] = ..., stale_events: _Optional[int] = ..., restarts: _Optional[int] = ..., entities: _Optional[int] = ..., queries_answered: _Optional[int] = ..., queries_invalid: _Optional[int] = ..., queries_failed: _Optional[int] = ..., periodic_requests: _Optional[int] = ..., messages_dropped: _Optional[int] = ..., responses_deferred: _Optional[int] = ..., last_error: _Optional[str] = ..., responses_dropped: _Optional[int] = ..., ownship: _Optional[str] = ..., query_database: _Optional[str] = ...) -> None: ...

class InputSourceStatus(_message.Message):
    __slots__ = ("name", "accepted", "rejected", "stale", "last_input_age_s", "last_rejection", "counters", "values")
    class RejectedEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class CountersEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class ValuesEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    NAME_FIELD_NUMBER: _ClassVar[int]
    ACCEPTED_FIELD_NUMBER: _ClassVar[int]
    REJECTED_FIELD_NUMBER: _ClassVar[int]
    STALE_FIELD_NUMBER: _ClassVar[int]
    LAST_INPUT_AGE_S_FIELD_NUMBER: _ClassVar[int]
    LAST_REJECTION_FIELD_NUMBER: _ClassVar[int]
    COUNTERS_FIELD_NUMBER: _ClassVar[int]
    VALUES_FIELD_NUMBER: _ClassVar[int]
    name: str
    accepted: int
    rejected: _containers.ScalarMap[str, int]
    stale: bool
    last_input_age_s: float
    last_rejection: str
    counters: _containers.ScalarMap[str, int]
    values: _containers.ScalarMap[str, float]
    def __init__(self, name: _Optional[str] = ..., accepted: _Optional[int] = ..., rejected: _Optional[_Mapping[str, int]] = ..., stale: _Optional[bool] = ..., last_input_age_s: _Optional[float] = ..., last_rejection: _Optional[str] = ..., counters: _Optional[_Mapping[str, int]] = ..., values: _Optional[_Mapping[str, float]] = ...) -> None: ...

class ReplayStatus(_message.Message):
    __slots__ = ("path", "format", "records", "problems", "attitude_estimated", "log_duration_s", "log_time_s", "loops")
    class ProblemsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    PATH_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    RECORDS_FIELD_NUMBER: _ClassVar[int]
    PROBLEMS_FIELD_NUMBER: _ClassVar[int]
    ATTITUDE_ESTIMATED_FIELD_NUMBER: _ClassVar[int]
    LOG_DURATION_S_FIELD_NUMBER: _ClassVar[int]
    LOG_TIME_S_FIELD_NUMBER: _ClassVar[int]
    LOOPS_FIELD_NUMBER: _ClassVar[int]
    path: str
    format: str
    records: int
    problems: _containers.ScalarMap[str, int]
    attitude_estimated: bool
    log_duration_s: float
    log_time_s: float
    loops: int
    def __init__(self, path: _Optional[str] = ..., format: _Optional[str] = ..., records: _Optional[int] = ..., problems: _Optional[_Mapping[str, int]] = ..., attitude_estimated: _Optional[bool] = ..., log_duration_s: _Optional[float] = ..., log_time_s: _Optional[float] = ..., loops: _Optional[int] = ...) -> None: ...

class FlightModelStatus(_message.Message):
    __slots__ = ("steps", "speed_mps", "on_ground")
    STEPS_FIELD_NUMBER: _ClassVar[int]
    SPEED_MPS_FIELD_NUMBER: _ClassVar[int]
    ON_GROUND_FIELD_NUMBER: _ClassVar[int]
    steps: int
    speed_mps: float
    on_ground: bool
    def __init__(self, steps: _Optional[int] = ..., speed_mps: _Optional[float] = ..., on_ground: _Optional[bool] = ...) -> None: ...
