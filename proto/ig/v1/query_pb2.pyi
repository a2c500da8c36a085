from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable
from typing import ClassVar as _ClassVar, Optional as _Optional

DESCRIPTOR: _descriptor.FileDescriptor

class HeightOfTerrainRequest(_message.Message):
    __slots__ = ("x", "y", "z_max", "up_x", "up_y", "up_z")
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_MAX_FIELD_NUMBER: _ClassVar[int]
    UP_X_FIELD_NUMBER: _ClassVar[int]
    UP_Y_FIELD_NUMBER: _ClassVar[int]
    UP_Z_FIELD_NUMBER: _ClassVar[int]
    x: _containers.RepeatedScalarFieldContainer[float]
    y: _containers.RepeatedScalarFieldContainer[float]
    z_max: _containers.RepeatedScalarFieldContainer[float]
    up_x: _containers.RepeatedScalarFieldContainer[float]
    up_y: _containers.RepeatedScalarFieldContainer[float]
    up_z: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, x: _Optional[_Iterable[float]] = ..., y: _Optional[_Iterable[float]] = ..., z_max: _Optional[_Iterable[float]] = ..., up_x: _Optional[_Iterable[float]] = ..., up_y: _Optional[_Iterable[float]] = ..., up_z: _Optional[_Iterable[float]] = ...) -> None: ...

class HeightOfTerrainResponse(_message.Message):
    __slots__ = ("valid", "height_m", "normal_x", "normal_y", "normal_z", "material", "database_warning")
    VALID_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    NORMAL_X_FIELD_NUMBER: _ClassVar[int]
    NORMAL_Y_FIELD_NUMBER: _ClassVar[int]
    NORMAL_Z_FIELD_NUMBER: _ClassVar[int]
    MATERIAL_FIELD_NUMBER: _ClassVar[int]
    DATABASE_WARNING_FIELD_NUMBER: _ClassVar[int]
    valid: _containers.RepeatedScalarFieldContainer[bool]
    height_m: _containers.RepeatedScalarFieldContainer[float]
    normal_x: _containers.RepeatedScalarFieldContainer[float]
    normal_y: _containers.RepeatedScalarFieldContainer[float]
    normal_z: _containers.RepeatedScalarFieldContainer[float]
    material: _containers.RepeatedScalarFieldContainer[int]
    database_warning: str
    def __init__(self, valid: _Optional[_Iterable[bool]] = ..., height_m: _Optional[_Iterable[float]] = ..., normal_x: _Optional[_Iterable[float]] = ..., normal_y: _Optional[_Iterable[float]] = ..., normal_z: _Optional[_Iterable[float]] = ..., material: _Optional[_Iterable[int]] = ..., database_warning: _Optional[str] = ...) -> None: ...

class LineOfSightRequest(_message.Message):
    __slots__ = ("x0", "y0", "z0", "x1", "y1", "z1", "min_opacity")
    X0_FIELD_NUMBER: _ClassVar[int]
    Y0_FIELD_NUMBER: _ClassVar[int]
    Z0_FIELD_NUMBER: _ClassVar[int]
    X1_FIELD_NUMBER: _ClassVar[int]
    Y1_FIELD_NUMBER: _ClassVar[int]
    Z1_FIELD_NUMBER: _ClassVar[int]
    MIN_OPACITY_FIELD_NUMBER: _ClassVar[int]
    x0: _containers.RepeatedScalarFieldContainer[float]
    y0: _containers.RepeatedScalarFieldContainer[float]
    z0: _containers.RepeatedScalarFieldContainer[float]
    x1: _containers.RepeatedScalarFieldContainer[float]
    y1: _containers.RepeatedScalarFieldContainer[float]
    z1: _containers.RepeatedScalarFieldContainer[float]
    min_opacity: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, x0: _Optional[_Iterable[float]] = ..., y0: _Optional[_Iterable[float]] = ..., z0: _Optional[_Iterable[float]] = ..., x1: _Optional[_Iterable[float]] = ..., y1: _Optional[_Iterable[float]] = ..., z1: _Optional[_Iterable[float]] = ..., min_opacity: _Optional[_Iterable[float]] = ...) -> None: ...

class LineOfSightResponse(_message.Message):
    __slots__ = ("hit", "range_m", "x", "y", "z", "normal_x", "normal_y", "normal_z", "material", "rgba", "database_warning")
    HIT_FIELD_NUMBER: _ClassVar[int]
    RANGE_M_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    NORMAL_X_FIELD_NUMBER: _ClassVar[int]
    NORMAL_Y_FIELD_NUMBER: _ClassVar[int]
    NORMAL_Z_FIELD_NUMBER: _ClassVar[int]
    MATERIAL_FIELD_NUMBER: _ClassVar[int]
    RGBA_FIELD_NUMBER: _ClassVar[int]
    DATABASE_WARNING_FIELD_NUMBER: _ClassVar[int]
    hit: _containers.RepeatedScalarFieldContainer[bool]
    range_m: _containers.RepeatedScalarFieldContainer[float]
    x: _containers.RepeatedScalarFieldContainer[float]
    y: _containers.RepeatedScalarFieldContainer[float]
    z: _containers.RepeatedScalarFieldContainer[float]
    normal_x: _containers.RepeatedScalarFieldContainer[float]
    normal_y: _containers.RepeatedScalarFieldContainer[float]
    normal_z: _containers.RepeatedScalarFieldContainer[float]
    material: _containers.RepeatedScalarFieldContainer[int]
    rgba: _containers.RepeatedScalarFieldContainer[int]
    database_warning: str
    def __init__(self, hit: _Optional[_Iterable[bool]] = ..., range_m: _Optional[_Iterable[float]] = ..., x: _Optional[_Iterable[float]] = ..., y: _Optional[_Iterable[float]] = ..., z: _Optional[_Iterable[float]] = ..., normal_x: _Optional[_Iterable[float]] = ..., normal_y: _Optional[_Iterable[float]] = ..., normal_z: _Optional[_Iterable[float]] = ..., material: _Optional[_Iterable[int]] = ..., rgba: _Optional[_Iterable[int]] = ..., database_warning: _Optional[str] = ...) -> None: ...
