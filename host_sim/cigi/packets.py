"""CIGI packets as frozen dataclasses: the fields the IG uses, with their CCL meaning in snake case.

Bit fields are unpacked (flags into bools, enumerations into ints). A field that the packet's
layout in some version lacks (e.g. `StartOfFrame.condition_flags` before 4.0) keeps its default
and is not sent in that version. Units: degrees for angles, metres for lengths and heights,
10 microsecond ticks for timestamps. Layouts per version live in `codec`.
"""

from __future__ import annotations

from dataclasses import dataclass, field


class CigiError(ValueError):
    """A datagram that is not valid CIGI, or a packet that cannot be sent in a version.

    `cause` is a short key for counters ("truncated", "bad_size", "first_packet", "version",
    "empty", "magic", "packet_kind", "value", "sender", "byte_order").
    """

    def __init__(self, cause: str, message: str) -> None:
        super().__init__(message)
        self.cause = cause


@dataclass(frozen=True, order=True)
class Version:
    """A CIGI version as major.minor."""

    major: int
    minor: int

    def __str__(self) -> str:
        return f"{self.major}.{self.minor}"


V3_2 = Version(3, 2)
V3_3 = Version(3, 3)
V4_0 = Version(4, 0)


@dataclass(frozen=True)
class RawPacket:
    """A packet the version defines but this codec does not interpret: its id and the bytes after
    its header, re-encoded exactly (in the byte order they came in)."""

    packet_id: int
    body: bytes


# ---- Host -> IG -------------------------------------------------------------------------------

@dataclass(frozen=True)
class IGControl:
    """IG Control: first packet of every host message. `ig_mode` 0 reset/standby, 1 operate,
    2 debug; `entity_substitution` exists in 4.0 only."""

    database_number: int = 0
    ig_mode: int = 0
    timestamp_valid: bool = False
    extrapolation: bool = False
    host_frame: int = 0
    timestamp: int = 0
    last_ig_frame: int = 0
    entity_substitution: bool = False


@dataclass(frozen=True)
class EntityControl:
    """Entity Control of CIGI 3.x: state and pose in one packet (entity 0 = ownship).

    Pose: roll, pitch, yaw in degrees; lat_x, lon_y in degrees (geodetic) or metres (relative to
    the parent); alt_z in metres. `smoothing` exists from 3.3 on."""

    entity_id: int = 0
    entity_state: int = 0
    attach: bool = False
    collision_detection: bool = False
    inherit_alpha: bool = False
    ground_clamp: int = 0
    animation_direction: int = 0
    animation_loop: int = 0
    animation_state: int = 0
    smoothing: bool = False
    alpha: int = 255
    entity_type: int = 0
    parent_id: int = 0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    lat_x: float = 0.0
    lon_y: float = 0.0
    alt_z: float = 0.0


@dataclass(frozen=True)
class EntityPosition:
    """Entity Position (4.0): the pose half of 3.x's Entity Control."""

    entity_id: int = 0
    attach: bool = False
    ground_clamp: int = 0
    parent_id: int = 0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    lat_x: float = 0.0
    lon_y: float = 0.0
    alt_z: float = 0.0


@dataclass(frozen=True)
class EntityControlV4:
    """Entity Control (4.0): state, alpha and the DIS-style entity type; no pose (see
    EntityPosition). Animation Control (4.0 id 0x26) is decoded as a RawPacket."""

    entity_id: int = 0
    entity_state: int = 0
    collision_detection: bool = False
    inherit_alpha: bool = False
    smoothing: bool = False
    extended_entity_type: int = 0
    alpha: int = 255
    entity_kind: int = 0
    entity_domain: int = 0
    entity_type: int = 0
    entity_category: int = 0
    entity_subcategory: int = 0
    entity_specific: int = 0
    entity_extra: int = 0


@dataclass(frozen=True)
class ComponentControl:
    """Component Control: six 32-bit data words whose meaning depends on the component class."""

    component_id: int = 0
    instance_id: int = 0
    component_class: int = 0
    component_state: int = 0
    data: tuple[int, ...] = field(default=(0, 0, 0, 0, 0, 0))


@dataclass(frozen=True)
class ShortComponentControl:
    """Short Component Control: two 32-bit data words."""

    component_id: int = 0
    instance_id: int = 0
    component_class: int = 0
    component_state: int = 0
    data: tuple[int, ...] = field(default=(0, 0))


@dataclass(frozen=True)
class CelestialSphereControl:
    """Celestial Sphere Control. `date` is MMDDYYYY as an integer; `seconds` exists in 4.0 only."""

    hour: int = 0
    minute: int = 0
    ephemeris: bool = False
    sun_enable: bool = False
    moon_enable: bool = False
    star_enable: bool = False
    date_valid: bool = False
    date: int = 0
    star_intensity: float = 0.0
    seconds: float = 0.0


@dataclass(frozen=True)
class AtmosphereControl:
    """Atmosphere Control: humidity %, air temperature deg C, visibility m, winds m/s, wind
    direction deg, barometric pressure hPa."""

    atmospheric_model: bool = False
    humidity: int = 0
    air_temp: float = 0.0
    visibility: float = 0.0
    horiz_wind: float = 0.0
    vert_wind: float = 0.0
    wind_direction: float = 0.0
    barometric_pressure: float = 0.0


@dataclass(frozen=True)
class WeatherControl:
    """Weather Control of a global/regional layer or an entity's weather. `scope` 0 global,
    1 regional, 2 entity. The top_* fields exist in 4.0 only."""

    entity_region_id: int = 0
    layer_id: int = 0
    humidity: int = 0
    weather_enable: bool = False
    scud_enable: bool = False
    random_winds: bool = False
    random_lightning: bool = False
    cloud_type: int = 0
    scope: int = 0
    severity: int = 0
    air_temp: float = 0.0
    visibility: float = 0.0
    scud_frequency: float = 0.0
    coverage: float = 0.0
    base_elevation: float = 0.0
    thickness: float = 0.0
    transition_band: float = 0.0
    horiz_wind: float = 0.0
    vert_wind: float = 0.0
    wind_direction: float = 0.0
    barometric_pressure: float = 0.0
    aerosol_concentration: float = 0.0
    top_scud_enable: bool = False
    top_scud_frequency: float = 0.0
    top_transition_band: float = 0.0


@dataclass(frozen=True)
class ViewControl:
    """View Control: the view's offset from its entity (x, y, z metres; roll, pitch, yaw deg),
    each axis applied only when its enable is set."""

    view_id: int = 0
    group_id: int = 0
    x_enable: bool = False
    y_enable: bool = False
    z_enable: bool = False
    roll_enable: bool = False
    pitch_enable: bool = False
    yaw_enable: bool = False
    entity_id: int = 0
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0


@dataclass(frozen=True)
class ViewDefinition:
    """View Definition: near/far planes (m) and the frustum's half-angles left/right/top/bottom
    (deg), each applied only when its enable is set. `projection_type` 0 perspective,
    1 orthographic."""

    view_id: int = 0
    group_id: int = 0
    near_enable: bool = False
    far_enable: bool = False
    left_enable: bool = False
    right_enable: bool = False
    top_enable: bool = False
    bottom_enable: bool = False
    mirror_mode: int = 0
    pixel_replication: int = 0
    projection_type: int = 0
    reorder: bool = False
    view_type: int = 0
    near: float = 0.0
    far: float = 0.0
    left: float = 0.0
    right: float = 0.0
    top: float = 0.0
    bottom: float = 0.0


@dataclass(frozen=True)
class HatHotRequest:
    """HAT/HOT Request: `request_type` 0 HAT, 1 HOT, 2 extended; `coord_system` 0 geodetic
    (lat, lon deg; alt m), 1 entity-relative (metres); `update_period` 0 one-shot, n every n
    frames."""

    request_id: int = 0
    request_type: int = 0
    coord_system: int = 0
    update_period: int = 0
    entity_id: int = 0
    lat_x: float = 0.0
    lon_y: float = 0.0
    alt_z: float = 0.0


@dataclass(frozen=True)
class LosSegmentRequest:
    """Line-of-sight segment request from src to dst (geodetic deg/m, or entity-relative m)."""

    los_id: int = 0
    request_type: int = 0
    source_coord: int = 0
    dest_coord: int = 0
    response_coord: int = 0
    dest_entity_valid: bool = False
    alpha_threshold: int = 0
    entity_id: int = 0
    src_lat_x: float = 0.0
    src_lon_y: float = 0.0
    src_alt_z: float = 0.0
    dst_lat_x: float = 0.0
    dst_lon_y: float = 0.0
    dst_alt_z: float = 0.0
    material_mask: int = 0
    update_period: int = 0
    dest_entity_id: int = 0


@dataclass(frozen=True)
class LosVectorRequest:
    """Line-of-sight vector request: azimuth/elevation (deg) from the source, ranges in metres."""

    los_id: int = 0
    request_type: int = 0
    source_coord: int = 0
    response_coord: int = 0
    alpha_threshold: int = 0
    entity_id: int = 0
    azimuth: float = 0.0
    elevation: float = 0.0
    min_range: float = 0.0
    max_range: float = 0.0
    src_lat_x: float = 0.0
    src_lon_y: float = 0.0
    src_alt_z: float = 0.0
    material_mask: int = 0
    update_period: int = 0


# ---- IG -> host -------------------------------------------------------------------------------

@dataclass(frozen=True)
class StartOfFrame:
    """Start of Frame: first packet of every IG message. `condition_flags` exists in 4.0 only
    (bit 8 overframing, 9 paging, 10 excess variable-length data)."""

    database_number: int = 0
    ig_status: int = 0
    ig_mode: int = 0
    timestamp_valid: bool = False
    earth_ref_model: int = 0
    ig_frame: int = 0
    timestamp: int = 0
    last_host_frame: int = 0
    condition_flags: int = 0


@dataclass(frozen=True)
class HatHotResponse:
    """HAT/HOT Response: `response_type` 0 HAT, 1 HOT; `height` metres (f64 on the wire);
    `host_frame_lsn` the low nibble of the host frame the value was computed for."""

    request_id: int = 0
    valid: bool = False
    response_type: int = 0
    host_frame_lsn: int = 0
    height: float = 0.0


@dataclass(frozen=True)
class HatHotExtendedResponse:
    """HAT/HOT Extended Response: both heights (m), material code and the surface normal (deg)."""

    request_id: int = 0
    valid: bool = False
    host_frame_lsn: int = 0
    hat: float = 0.0
    hot: float = 0.0
    material: int = 0
    normal_azimuth: float = 0.0
    normal_elevation: float = 0.0


@dataclass(frozen=True)
class LosResponse:
    """Line-of-sight response: `range` metres to the intersection."""

    los_id: int = 0
    valid: bool = False
    entity_id_valid: bool = False
    visible: bool = False
    host_frame_lsn: int = 0
    response_count: int = 0
    entity_id: int = 0
    range: float = 0.0


@dataclass(frozen=True)
class LosExtendedResponse:
    """Line-of-sight extended response: range, intersection point, colour, material, normal."""

    los_id: int = 0
    valid: bool = False
    entity_id_valid: bool = False
    range_valid: bool = False
    visible: bool = False
    host_frame_lsn: int = 0
    response_count: int = 0
    entity_id: int = 0
    range: float = 0.0
    lat_x: float = 0.0
    lon_y: float = 0.0
    alt_z: float = 0.0
    red: int = 0
    green: int = 0
    blue: int = 0
    alpha: int = 0
    material: int = 0
    normal_azimuth: float = 0.0
    normal_elevation: float = 0.0


Packet = (IGControl | EntityControl | EntityPosition | EntityControlV4 | ComponentControl
          | ShortComponentControl | CelestialSphereControl | AtmosphereControl | WeatherControl
          | ViewControl | ViewDefinition | HatHotRequest | LosSegmentRequest | LosVectorRequest
          | StartOfFrame | HatHotResponse | HatHotExtendedResponse | LosResponse
          | LosExtendedResponse | RawPacket)


@dataclass(frozen=True)
class Message:
    """One decoded datagram: its version, byte order ('<' little, '>' big), the packets in order,
    and the count of packets skipped by id (ids the version does not define)."""

    version: Version
    byte_order: str
    packets: tuple[Packet, ...]
    skipped: dict[int, int] = field(default_factory=dict)
