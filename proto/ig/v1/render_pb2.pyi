from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class RenderOptions(_message.Message):
    __slots__ = ("samples", "filter", "subarea", "max_translucent", "terrain_bias", "haze", "clouds", "fog_table_subdivision", "with_range", "threads", "renderer", "texture_filter", "coverage")
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    FILTER_FIELD_NUMBER: _ClassVar[int]
    SUBAREA_FIELD_NUMBER: _ClassVar[int]
    MAX_TRANSLUCENT_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_BIAS_FIELD_NUMBER: _ClassVar[int]
    HAZE_FIELD_NUMBER: _ClassVar[int]
    CLOUDS_FIELD_NUMBER: _ClassVar[int]
    FOG_TABLE_SUBDIVISION_FIELD_NUMBER: _ClassVar[int]
    WITH_RANGE_FIELD_NUMBER: _ClassVar[int]
    THREADS_FIELD_NUMBER: _ClassVar[int]
    RENDERER_FIELD_NUMBER: _ClassVar[int]
    TEXTURE_FILTER_FIELD_NUMBER: _ClassVar[int]
    COVERAGE_FIELD_NUMBER: _ClassVar[int]
    samples: str
    filter: str
    subarea: int
    max_translucent: int
    terrain_bias: int
    haze: bool
    clouds: bool
    fog_table_subdivision: int
    with_range: bool
    threads: int
    renderer: str
    texture_filter: str
    coverage: str
    def __init__(self, samples: _Optional[str] = ..., filter: _Optional[str] = ..., subarea: _Optional[int] = ..., max_translucent: _Optional[int] = ..., terrain_bias: _Optional[int] = ..., haze: _Optional[bool] = ..., clouds: _Optional[bool] = ..., fog_table_subdivision: _Optional[int] = ..., with_range: _Optional[bool] = ..., threads: _Optional[int] = ..., renderer: _Optional[str] = ..., texture_filter: _Optional[str] = ..., coverage: _Optional[str] = ...) -> None: ...

class StageTime(_message.Message):
    __slots__ = ("stage", "seconds")
    STAGE_FIELD_NUMBER: _ClassVar[int]
    SECONDS_FIELD_NUMBER: _ClassVar[int]
    stage: str
    seconds: float
    def __init__(self, stage: _Optional[str] = ..., seconds: _Optional[float] = ...) -> None: ...

class FrameReport(_message.Message):
    __slots__ = ("stages", "counters", "parts")
    class CountersEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    STAGES_FIELD_NUMBER: _ClassVar[int]
    COUNTERS_FIELD_NUMBER: _ClassVar[int]
    PARTS_FIELD_NUMBER: _ClassVar[int]
    stages: _containers.RepeatedCompositeFieldContainer[StageTime]
    counters: _containers.ScalarMap[str, int]
    parts: _containers.RepeatedCompositeFieldContainer[StageTime]
    def __init__(self, stages: _Optional[_Iterable[_Union[StageTime, _Mapping]]] = ..., counters: _Optional[_Mapping[str, int]] = ..., parts: _Optional[_Iterable[_Union[StageTime, _Mapping]]] = ...) -> None: ...
