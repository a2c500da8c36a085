"""CIGI datagrams <-> typed packets, for versions 3.2, 3.3 and 4.0, in either byte order.

Layouts (field order and offsets) were read from these public sources and written here anew:
- CCL 3.3.3 (Boeing CIGI Class Library, repo Hadron/cigi-ccl): the Pack()/Unpack() bodies of
  source/Cigi*V3*.cpp, ids and sizes in include/Cigi*.h, version and byte-order detection in
  source/CigiIncomingMsg.cpp (CheckFirstPacket);
- CCL 4.0.0 rev 2 (repo captainflasmr/cigi-ccl_4_0): source/Cigi*V4.cpp and
  source/CigiIncomingMsg.cpp (the 4.0 header and byte-order rule); the SISO 4.0 text is not public;
- the Wireshark dissector (wireshark/wireshark epan/dissectors/packet-cigi.c) for 3.x;
- /work/shared/reference/cigi-wire-format.md, which summarises them.

Byte order: CIGI 3 senders write in their native order and mark IG Control / Start of Frame with
the magic 0x8000 at bytes 6..7; CIGI 4 has no magic and the first packet's size field tells
(CCL: a zero low-address byte means big-endian). A reply must use the sender's version and order.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, fields
from typing import Any

from host_sim.cigi.packets import (
    V3_2,
    V3_3,
    V4_0,
    AtmosphereControl,
    CelestialSphereControl,
    CigiError,
    ComponentControl,
    EntityControl,
    EntityControlV4,
    EntityPosition,
    HatHotExtendedResponse,
    HatHotRequest,
    HatHotResponse,
    IGControl,
    LosExtendedResponse,
    LosResponse,
    LosSegmentRequest,
    LosVectorRequest,
    Message,
    Packet,
    RawPacket,
    ShortComponentControl,
    StartOfFrame,
    Version,
    ViewControl,
    ViewDefinition,
    WeatherControl,
)

__all__ = ["SUPPORTED_VERSIONS", "CigiError", "Message", "Version", "bench_decode", "decode", "encode",
           "packet_name"]

SUPPORTED_VERSIONS = (V3_2, V3_3, V4_0)
BYTE_SWAP_MAGIC = 0x8000


# ---- the layout language ----------------------------------------------------------------------
# A layout is the packet after its header, in wire order: (struct format, what it holds).
# What it holds: a field name; "_major"/"_minor"/"_magic" (written from the version, checked by
# decode's header logic, never a field); a Bits tuple for a byte of bit fields; a Seq for a run
# of words that make one tuple field; None for reserved bytes ("x" formats).

@dataclass(frozen=True)
class Bit:
    name: str
    shift: int
    width: int
    is_bool: bool


def flag(name: str, shift: int) -> Bit:
    return Bit(name, shift, 1, True)


def bits(name: str, shift: int, width: int) -> Bit:
    return Bit(name, shift, width, False)


@dataclass(frozen=True)
class Seq:
    name: str
    count: int


Slot = str | tuple[Bit, ...] | Seq | None
LayoutSpec = list[tuple[str, Slot]]



def _floats(*names: str) -> LayoutSpec:
    return [("f", n) for n in names]


def _doubles(*names: str) -> LayoutSpec:
    return [("d", n) for n in names]


# IG Control. 3.2/3.3: CigiIGCtrlV3_2/V3_3 Pack(); 4.0: CigiIGCtrlV4::Pack() (host frame, then
# last IG frame, then timestamp: the order changed in 4.0).
_IG_MODE_BITS = (bits("ig_mode", 0, 2), flag("timestamp_valid", 2), flag("extrapolation", 3), bits("_minor", 4, 4))
IG_CONTROL_V3: LayoutSpec = [
    ("B", "_major"), ("b", "database_number"), ("B", _IG_MODE_BITS), ("x", None), ("H", "_magic"),
    ("I", "host_frame"), ("I", "timestamp"), ("I", "last_ig_frame"), ("4x", None)]
IG_CONTROL_V4: LayoutSpec = [
    ("B", "_major"), ("b", "database_number"), ("B", (flag("entity_substitution", 0),)), ("B", _IG_MODE_BITS),
    ("I", "host_frame"), ("I", "last_ig_frame"), ("I", "timestamp"), ("4x", None)]

# Start of Frame. 3.2/3.3: CigiSOFV3_2::Pack(); 4.0: CigiSOFV4::Pack() (no IG status byte,
# condition flags as a u16 at 20).
_SOF_BITS = (bits("ig_mode", 0, 2), flag("timestamp_valid", 2), bits("earth_ref_model", 3, 1), bits("_minor", 4, 4))
SOF_V3: LayoutSpec = [
    ("B", "_major"), ("b", "database_number"), ("B", "ig_status"), ("B", _SOF_BITS), ("H", "_magic"),
    ("I", "ig_frame"), ("I", "timestamp"), ("I", "last_host_frame"), ("4x", None)]
SOF_V4: LayoutSpec = [
    ("B", "_major"), ("b", "database_number"), ("x", None), ("B", _SOF_BITS),
    ("I", "ig_frame"), ("I", "timestamp"), ("I", "last_host_frame"), ("H", "condition_flags"), ("2x", None)]

# Entity Control 3.x: CigiEntityCtrlV3::Pack() (3.0-3.2) and CigiEntityCtrlV3_3::Pack(), which
# only adds the smoothing bit (byte 5 bit 4).
_POSE: LayoutSpec = _floats("roll", "pitch", "yaw") + _doubles("lat_x", "lon_y", "alt_z")


def _entity_control_v3(smoothing: bool) -> LayoutSpec:
    anim: tuple[Bit, ...] = (bits("animation_direction", 0, 1), bits("animation_loop", 1, 1),
                             bits("animation_state", 2, 2))
    if smoothing:
        anim = (*anim, flag("smoothing", 4))
    return [("H", "entity_id"),
            ("B", (bits("entity_state", 0, 2), flag("attach", 2), flag("collision_detection", 3),
                   flag("inherit_alpha", 4), bits("ground_clamp", 5, 2))),
            ("B", anim), ("B", "alpha"), ("x", None), ("H", "entity_type"), ("H", "parent_id"), *_POSE]


# 4.0 split: CigiEntityPositionCtrlV4::Pack() and CigiEntityCtrlV4::Pack().
ENTITY_POSITION_V4: LayoutSpec = [
    ("B", (flag("attach", 0), bits("ground_clamp", 1, 2))), ("x", None), ("H", "entity_id"), ("H", "parent_id"),
    ("2x", None), *_POSE]
ENTITY_CONTROL_V4: LayoutSpec = [
    ("B", (bits("entity_state", 0, 2), flag("collision_detection", 2), flag("inherit_alpha", 3),
           flag("smoothing", 4), bits("extended_entity_type", 5, 1))),
    ("B", "alpha"), ("H", "entity_id"), ("B", "entity_kind"), ("B", "entity_domain"), ("H", "entity_type"),
    ("B", "entity_category"), ("B", "entity_subcategory"), ("B", "entity_specific"), ("B", "entity_extra")]


# Component Control: CigiCompCtrlV3 (class in 4 bits), CigiCompCtrlV3_3 (6 bits), CigiCompCtrlV4.
def _component_v3(class_width: int, words: int) -> LayoutSpec:
    return [("H", "component_id"), ("H", "instance_id"), ("B", (bits("component_class", 0, class_width),)),
            ("B", "component_state"), (f"{words}I", Seq("data", words))]


def _component_v4(words: int) -> LayoutSpec:
    return [("H", "component_id"), ("B", (bits("component_class", 0, 6),)), ("B", "component_state"),
            ("H", "instance_id"), ("6x", None), (f"{words}I", Seq("data", words))]


# Celestial Sphere Control: CigiCelestialCtrlV3 / CigiCelestialCtrlV4 (adds seconds).
_CELESTIAL_BITS = (flag("ephemeris", 0), flag("sun_enable", 1), flag("moon_enable", 2), flag("star_enable", 3),
                   flag("date_valid", 4))
CELESTIAL_V3: LayoutSpec = [
    ("B", "hour"), ("B", "minute"), ("B", _CELESTIAL_BITS), ("3x", None), ("I", "date"), ("f", "star_intensity")]
CELESTIAL_V4: LayoutSpec = [
    ("B", _CELESTIAL_BITS), ("x", None), ("B", "hour"), ("B", "minute"), ("f", "seconds"), ("I", "date"),
    ("f", "star_intensity"), ("4x", None)]

# Atmosphere Control: CigiAtmosCtrl (3.x) / CigiAtmosCtrlV4 (humidity in 7 bits, enable in bit 7).
_ATMOS_FLOATS = _floats("air_temp", "visibility", "horiz_wind", "vert_wind", "wind_direction", "barometric_pressure")
ATMOS_V3: LayoutSpec = [("B", (flag("atmospheric_model", 0),)), ("B", "humidity"), *_ATMOS_FLOATS, ("4x", None)]
ATMOS_V4: LayoutSpec = [("B", (bits("humidity", 0, 7), flag("atmospheric_model", 7))), ("3x", None), *_ATMOS_FLOATS]

# Weather Control: CigiWeatherCtrlV3 / CigiWeatherCtrlV4 (adds top scud and top transition band).
_WEATHER_FLAGS = (flag("weather_enable", 0), flag("scud_enable", 1), flag("random_winds", 2),
                  flag("random_lightning", 3), bits("cloud_type", 4, 4))
_WEATHER_FLOATS = _floats("air_temp", "visibility", "scud_frequency", "coverage", "base_elevation", "thickness",
                          "transition_band", "horiz_wind", "vert_wind", "wind_direction", "barometric_pressure",
                          "aerosol_concentration")
WEATHER_V3: LayoutSpec = [
    ("H", "entity_region_id"), ("B", "layer_id"), ("B", "humidity"), ("B", _WEATHER_FLAGS),
    ("B", (bits("scope", 0, 2), bits("severity", 2, 3))), *_WEATHER_FLOATS]
WEATHER_V4: LayoutSpec = [
    ("B", "layer_id"), ("B", "humidity"), ("B", _WEATHER_FLAGS),
    ("B", (bits("scope", 0, 2), bits("severity", 2, 3), flag("top_scud_enable", 5))),
    ("H", "entity_region_id"), ("2x", None), *_WEATHER_FLOATS,
    ("f", "top_scud_frequency"), ("f", "top_transition_band"), ("4x", None)]

# View Control: CigiViewCtrlV3 / CigiViewCtrlV4.
_VIEW_BITS = (flag("x_enable", 0), flag("y_enable", 1), flag("z_enable", 2), flag("roll_enable", 3),
              flag("pitch_enable", 4), flag("yaw_enable", 5))
_VIEW_FLOATS = _floats("x", "y", "z", "roll", "pitch", "yaw")
VIEW_CONTROL_V3: LayoutSpec = [("H", "view_id"), ("B", "group_id"), ("B", _VIEW_BITS), ("H", "entity_id"),
                               *_VIEW_FLOATS]
VIEW_CONTROL_V4: LayoutSpec = [("B", "group_id"), ("B", _VIEW_BITS), ("H", "view_id"), ("H", "entity_id"),
                               ("2x", None), *_VIEW_FLOATS, ("4x", None)]

# View Definition: CigiViewDefV3 / CigiViewDefV4.
_VIEWDEF_BITS1 = (flag("near_enable", 0), flag("far_enable", 1), flag("left_enable", 2), flag("right_enable", 3),
                  flag("top_enable", 4), flag("bottom_enable", 5), bits("mirror_mode", 6, 2))
_VIEWDEF_BITS2 = (bits("pixel_replication", 0, 3), bits("projection_type", 3, 1), flag("reorder", 4),
                  bits("view_type", 5, 3))
_VIEWDEF_FLOATS = _floats("near", "far", "left", "right", "top", "bottom")
VIEW_DEF_V3: LayoutSpec = [("H", "view_id"), ("B", "group_id"), ("B", _VIEWDEF_BITS1), ("B", _VIEWDEF_BITS2),
                           ("x", None), *_VIEWDEF_FLOATS]
VIEW_DEF_V4: LayoutSpec = [("H", "view_id"), ("B", "group_id"), ("B", _VIEWDEF_BITS1), ("B", _VIEWDEF_BITS2),
                           ("3x", None), *_VIEWDEF_FLOATS, ("4x", None)]

# HAT/HOT Request: CigiHatHotReqV3_2 / CigiHatHotReqV4.
_HATHOT_REQ_BITS = (bits("request_type", 0, 2), bits("coord_system", 2, 1))
_LLA = _doubles("lat_x", "lon_y", "alt_z")
HAT_HOT_REQ_V3: LayoutSpec = [("H", "request_id"), ("B", _HATHOT_REQ_BITS), ("B", "update_period"),
                              ("H", "entity_id"), *_LLA]
HAT_HOT_REQ_V4: LayoutSpec = [("H", "request_id"), ("H", "entity_id"), ("B", _HATHOT_REQ_BITS),
                              ("B", "update_period"), ("6x", None), *_LLA]

# HAT/HOT Response and Extended Response: CigiHatHotRespV3_2 / XRespV3_2 / RespV4 / XRespV4.
_HATHOT_RESP_BITS = (flag("valid", 0), bits("response_type", 1, 1), bits("host_frame_lsn", 4, 4))
_HATHOT_XRESP_BITS = (flag("valid", 0), bits("host_frame_lsn", 4, 4))
_XRESP_TAIL: LayoutSpec = [*_doubles("hat", "hot"), ("I", "material"),
                           *_floats("normal_azimuth", "normal_elevation"), ("4x", None)]
HAT_HOT_RESP_V3: LayoutSpec = [("H", "request_id"), ("B", _HATHOT_RESP_BITS), ("3x", None), ("d", "height")]
HAT_HOT_RESP_V4: LayoutSpec = [("B", _HATHOT_RESP_BITS), ("x", None), ("H", "request_id"), ("d", "height")]
HAT_HOT_XRESP_V3: LayoutSpec = [("H", "request_id"), ("B", _HATHOT_XRESP_BITS), ("3x", None), *_XRESP_TAIL]
HAT_HOT_XRESP_V4: LayoutSpec = [("B", _HATHOT_XRESP_BITS), ("x", None), ("H", "request_id"), *_XRESP_TAIL]

# LOS Segment / Vector Request: CigiLosSegReqV3_2, CigiLosVectReqV3_2, ...V4.
_LOS_SEG_BITS = (bits("request_type", 0, 1), bits("source_coord", 1, 1), bits("dest_coord", 2, 1),
                 bits("response_coord", 3, 1), flag("dest_entity_valid", 4))
_SEG_POINTS = _doubles("src_lat_x", "src_lon_y", "src_alt_z", "dst_lat_x", "dst_lon_y", "dst_alt_z")
LOS_SEG_V3: LayoutSpec = [
    ("H", "los_id"), ("B", _LOS_SEG_BITS), ("B", "alpha_threshold"), ("H", "entity_id"), *_SEG_POINTS,
    ("I", "material_mask"), ("B", "update_period"), ("x", None), ("H", "dest_entity_id")]
LOS_SEG_V4: LayoutSpec = [
    ("H", "los_id"), ("H", "entity_id"), ("B", _LOS_SEG_BITS), ("B", "alpha_threshold"), ("H", "dest_entity_id"),
    ("B", "update_period"), ("3x", None), *_SEG_POINTS, ("I", "material_mask"), ("4x", None)]
_LOS_VECT_BITS = (bits("request_type", 0, 1), bits("source_coord", 1, 1), bits("response_coord", 2, 1))
_VECT = _floats("azimuth", "elevation", "min_range", "max_range") + _doubles("src_lat_x", "src_lon_y", "src_alt_z")
LOS_VECT_V3: LayoutSpec = [
    ("H", "los_id"), ("B", _LOS_VECT_BITS), ("B", "alpha_threshold"), ("H", "entity_id"), *_VECT,
    ("I", "material_mask"), ("B", "update_period"), ("3x", None)]
LOS_VECT_V4: LayoutSpec = [
    ("H", "los_id"), ("H", "entity_id"), ("B", _LOS_VECT_BITS), ("B", "alpha_threshold"), ("B", "update_period"),
    ("5x", None), *_VECT, ("I", "material_mask"), ("4x", None)]

# LOS Response / Extended Response: CigiLosRespV3_2, CigiLosXRespV3_2, ...V4.
_LOS_RESP_BITS = (flag("valid", 0), flag("entity_id_valid", 1), flag("visible", 2), bits("host_frame_lsn", 4, 4))
_LOS_XRESP_BITS = (flag("valid", 0), flag("entity_id_valid", 1), flag("range_valid", 2), flag("visible", 3),
                   bits("host_frame_lsn", 4, 4))
_LOS_XTAIL: LayoutSpec = [("d", "range"), *_doubles("lat_x", "lon_y", "alt_z"), ("B", "red"), ("B", "green"),
                          ("B", "blue"), ("B", "alpha"), ("I", "material"),
                          *_floats("normal_azimuth", "normal_elevation")]
LOS_RESP_V3: LayoutSpec = [("H", "los_id"), ("B", _LOS_RESP_BITS), ("B", "response_count"), ("H", "entity_id"),
                           ("d", "range")]
LOS_RESP_V4: LayoutSpec = [("H", "los_id"), ("H", "entity_id"), ("B", _LOS_RESP_BITS), ("B", "response_count"),
                           ("6x", None), ("d", "range")]
LOS_XRESP_V3: LayoutSpec = [("H", "los_id"), ("B", _LOS_XRESP_BITS), ("B", "response_count"), ("H", "entity_id"),
                            *_LOS_XTAIL]
LOS_XRESP_V4: LayoutSpec = [("H", "los_id"), ("H", "entity_id"), ("B", _LOS_XRESP_BITS), ("B", "response_count"),
                            ("6x", None), *_LOS_XTAIL]

# (kind, packet id, layout) per version family. Ids and sizes: CCL include/Cigi*.h (3.x) and the
# reference's 4.0 table (CCL 4.0 constructors and headers).
_V3_COMMON: list[tuple[type, int, LayoutSpec]] = [
    (IGControl, 1, IG_CONTROL_V3),
    (CelestialSphereControl, 9, CELESTIAL_V3),
    (AtmosphereControl, 10, ATMOS_V3),
    (WeatherControl, 12, WEATHER_V3),
    (ViewControl, 16, VIEW_CONTROL_V3),
    (ViewDefinition, 21, VIEW_DEF_V3),
    (HatHotRequest, 24, HAT_HOT_REQ_V3),
    (LosSegmentRequest, 25, LOS_SEG_V3),
    (LosVectorRequest, 26, LOS_VECT_V3),
    (StartOfFrame, 101, SOF_V3),
    (HatHotResponse, 102, HAT_HOT_RESP_V3),
    (HatHotExtendedResponse, 103, HAT_HOT_XRESP_V3),
    (LosResponse, 104, LOS_RESP_V3),
    (LosExtendedResponse, 105, LOS_XRESP_V3),
]
KINDS: dict[Version, list[tuple[type, int, LayoutSpec]]] = {
    V3_2: _V3_COMMON + [
        (EntityControl, 2, _entity_control_v3(smoothing=False)),
        (ComponentControl, 4, _component_v3(4, 6)),
        (ShortComponentControl, 5, _component_v3(4, 2)),
    ],
    V3_3: _V3_COMMON + [
        (EntityControl, 2, _entity_control_v3(smoothing=True)),
        (ComponentControl, 4, _component_v3(6, 6)),
        (ShortComponentControl, 5, _component_v3(6, 2)),
    ],
    V4_0: [
        (IGControl, 0x0000, IG_CONTROL_V4),
        (EntityPosition, 0x01, ENTITY_POSITION_V4),
        (ComponentControl, 0x03, _component_v4(6)),
        (ShortComponentControl, 0x04, _component_v4(2)),
        (CelestialSphereControl, 0x08, CELESTIAL_V4),
        (AtmosphereControl, 0x09, ATMOS_V4),
        (WeatherControl, 0x0B, WEATHER_V4),
        (ViewControl, 0x0F, VIEW_CONTROL_V4),
        (ViewDefinition, 0x14, VIEW_DEF_V4),
        (HatHotRequest, 0x17, HAT_HOT_REQ_V4),
        (LosSegmentRequest, 0x18, LOS_SEG_V4),
        (LosVectorRequest, 0x19, LOS_VECT_V4),
        (EntityControlV4, 0x25, ENTITY_CONTROL_V4),
        (StartOfFrame, 0xFFFF, SOF_V4),
        (HatHotResponse, 0x0FFF, HAT_HOT_RESP_V4),
        (HatHotExtendedResponse, 0x0FFE, HAT_HOT_XRESP_V4),
        (LosResponse, 0x0FFD, LOS_RESP_V4),
        (LosExtendedResponse, 0x0FFC, LOS_XRESP_V4),
    ],
}

# Packets decoded as RawPacket: id -> (name, total size or None when variable or unconfirmed).
_RAW_V3_2: dict[int, tuple[str, int | None]] = {
    3: ("Conformal Clamped Entity Control", 24), 6: ("Articulated Part Control", 32),
    7: ("Short Articulated Part Control", 16), 8: ("Rate Control", 32), 11: ("Environmental Region Control", 48),
    13: ("Maritime Surface Conditions Control", 24), 14: ("Wave Control", 32),
    15: ("Terrestrial Surface Conditions Control", 8), 17: ("Sensor Control", 24),
    18: ("Motion Tracker Control", 8), 19: ("Earth Reference Model Definition", 24),
    20: ("Trajectory Definition", 24), 22: ("Collision Detection Segment Definition", 40),
    23: ("Collision Detection Volume Definition", 48), 27: ("Position Request", 8),
    28: ("Environmental Conditions Request", 32),
    106: ("Sensor Response", 24), 107: ("Sensor Extended Response", 48), 108: ("Position Response", 48),
    109: ("Weather Conditions Response", 32), 110: ("Aerosol Concentration Response", 8),
    111: ("Maritime Surface Conditions Response", 16), 112: ("Terrestrial Surface Conditions Response", 8),
    113: ("Collision Detection Segment Notification", 16), 114: ("Collision Detection Volume Notification", 16),
    115: ("Animation Stop Notification", 8), 116: ("Event Notification", 16), 117: ("Image Generator Message", None),
}
# 3.3 added the symbology packets (CCL CigiSymbol*V3_3).
_RAW_V3_3 = {**_RAW_V3_2,
             29: ("Symbol Surface Definition", 56), 30: ("Symbol Text Definition", None),
             31: ("Symbol Circle Definition", None), 32: ("Symbol Line Definition", None),
             33: ("Symbol Clone", 8), 34: ("Symbol Control", 40), 35: ("Short Symbol Control", 16)}
# 4.0: Animation Control (0x26, 16 bytes), the textured symbols (0x23, 0x24) and IG Message
# (0x0FF0) are confirmed from the CCL 4.0 headers; the other ids follow the 4.0 numbering
# (host->IG from 0 up, IG->host from 0x0FFF down) and their sizes are not checked.
_RAW_V4: dict[int, tuple[str, int | None]] = {
    0x02: ("Conformal Clamped Entity Position", None), 0x05: ("Articulated Part Control", None),
    0x06: ("Short Articulated Part Control", None), 0x07: ("Velocity Control", None),
    0x0A: ("Environmental Region Control", None), 0x0C: ("Maritime Surface Conditions Control", None),
    0x0D: ("Wave Control", None), 0x0E: ("Terrestrial Surface Conditions Control", None),
    0x10: ("Sensor Control", None), 0x11: ("Motion Tracker Control", None),
    0x12: ("Earth Reference Model Definition", None), 0x13: ("Acceleration Control", None),
    0x15: ("Collision Detection Segment Definition", None), 0x16: ("Collision Detection Volume Definition", None),
    0x1A: ("Position Request", None), 0x1B: ("Environmental Conditions Request", None),
    0x1C: ("Symbol Surface Definition", None), 0x1D: ("Symbol Text Definition", None),
    0x1E: ("Symbol Circle Definition", None), 0x1F: ("Symbol Polygon Definition", None),
    0x20: ("Symbol Clone", None), 0x21: ("Symbol Control", None), 0x22: ("Short Symbol Control", None),
    0x23: ("Symbol Textured Circle Definition", None), 0x24: ("Symbol Textured Polygon Definition", None),
    0x26: ("Animation Control", 16),
    0x0FFB: ("Sensor Response", None), 0x0FFA: ("Sensor Extended Response", None),
    0x0FF9: ("Position Response", None), 0x0FF8: ("Weather Conditions Response", None),
    0x0FF7: ("Aerosol Concentration Response", None), 0x0FF6: ("Maritime Surface Conditions Response", None),
    0x0FF5: ("Terrestrial Surface Conditions Response", None),
    0x0FF4: ("Collision Detection Segment Notification", None),
    0x0FF3: ("Collision Detection Volume Notification", None), 0x0FF2: ("Animation Stop Notification", None),
    0x0FF1: ("Event Notification", None), 0x0FF0: ("Image Generator Message", None),
}
RAW_PACKETS: dict[Version, dict[int, tuple[str, int | None]]] = {V3_2: _RAW_V3_2, V3_3: _RAW_V3_3, V4_0: _RAW_V4}

_NAMES = {
    IGControl: "IG Control", EntityControl: "Entity Control", EntityPosition: "Entity Position",
    EntityControlV4: "Entity Control", ComponentControl: "Component Control",
    ShortComponentControl: "Short Component Control", CelestialSphereControl: "Celestial Sphere Control",
    AtmosphereControl: "Atmosphere Control", WeatherControl: "Weather Control", ViewControl: "View Control",
    ViewDefinition: "View Definition", HatHotRequest: "HAT/HOT Request", LosSegmentRequest: "LOS Segment Request",
    LosVectorRequest: "LOS Vector Request", StartOfFrame: "Start of Frame", HatHotResponse: "HAT/HOT Response",
    HatHotExtendedResponse: "HAT/HOT Extended Response", LosResponse: "LOS Response",
    LosExtendedResponse: "LOS Extended Response",
}


# ---- compiled layouts -------------------------------------------------------------------------

class _Layout:
    """One packet kind in one version and byte order: a precompiled struct and the slot plan."""

    def __init__(self, kind: type, packet_id: int, spec: LayoutSpec, version: Version, order: str) -> None:
        self.kind = kind
        self.packet_id = packet_id
        self.name = _NAMES[kind]
        self.v4 = version.major >= 4
        header = "HH" if self.v4 else "BB"
        self.struct = struct.Struct(order + header + "".join(fmt for fmt, _ in spec))
        self.size = self.struct.size
        self.spec = spec
        self.slots: list[Slot] = [slot for _, slot in spec if slot is not None]
        self.constants = {"_major": version.major, "_minor": version.minor, "_magic": BYTE_SWAP_MAGIC}
        self.header = (self.size, packet_id) if self.v4 else (packet_id, self.size)
        self._check_fields(spec)

    def _check_fields(self, spec: LayoutSpec) -> None:
        """Every named slot is a field of the dataclass (catches typos in the tables at import)."""
        names = {f.name for f in fields(self.kind)}
        for _, slot in spec:
            for name in _slot_names(slot):
                if not name.startswith("_") and name not in names:
                    raise AssertionError(f"{self.kind.__name__} has no field {name!r}")

    def decode(self, buf: bytes | memoryview, offset: int) -> Any:
        values = self.struct.unpack_from(buf, offset)
        kwargs: dict[str, Any] = {}
        i = 2
        for slot in self.slots:
            if type(slot) is str:
                if slot[0] != "_":
                    kwargs[slot] = values[i]
                i += 1
            elif type(slot) is tuple:
                byte = values[i]
                for bit in slot:
                    if bit.name[0] != "_":
                        x = (byte >> bit.shift) & ((1 << bit.width) - 1)
                        kwargs[bit.name] = bool(x) if bit.is_bool else x
                i += 1
            else:
                assert isinstance(slot, Seq)
                kwargs[slot.name] = tuple(values[i:i + slot.count])
                i += slot.count
        return self.kind(**kwargs)

    def encode(self, packet: Any) -> bytes:
        values: list[Any] = list(self.header)
        for slot in self.slots:
            if type(slot) is str:
                values.append(self.constants[slot] if slot[0] == "_" else getattr(packet, slot))
            elif type(slot) is tuple:
                values.append(self._pack_bits(packet, slot))
            else:
                assert isinstance(slot, Seq)
                seq = tuple(getattr(packet, slot.name))
                if len(seq) != slot.count:
                    raise CigiError("value", f"{self.name}: {slot.name} has {len(seq)} words, expected {slot.count}")
                values.extend(seq)
        try:
            return self.struct.pack(*values)
        except (struct.error, OverflowError, TypeError) as exc:
            raise CigiError("value", f"{self.name}: {self._bad_field(packet)} ({exc})") from None

    def _pack_bits(self, packet: Any, slot: tuple[Bit, ...]) -> int:
        byte = 0
        for bit in slot:
            x = self.constants[bit.name] if bit.name[0] == "_" else getattr(packet, bit.name)
            if not isinstance(x, int) or not 0 <= x < (1 << bit.width):
                raise CigiError("value", f"{self.name}: {bit.name} = {x!r} does not fit in {bit.width} bit(s)")
            byte |= int(x) << bit.shift
        return byte

    def _bad_field(self, packet: Any) -> str:
        """Name the field that struct refused, by packing each alone (only on the error path)."""
        order = self.struct.format[0]
        for fmt, slot in self.spec:
            name = slot.name if isinstance(slot, Seq) else slot
            if not isinstance(name, str) or name.startswith("_"):
                continue
            value = getattr(packet, name)
            try:
                struct.pack(order + fmt, *(value if isinstance(value, tuple) else (value,)))
            except (struct.error, OverflowError, TypeError):
                return f"{name} = {value!r} does not fit its {fmt!r} field"
        return "a field does not fit"


def _slot_names(slot: Slot) -> list[str]:
    if isinstance(slot, str):
        return [slot]
    if isinstance(slot, tuple):
        return [bit.name for bit in slot]
    if isinstance(slot, Seq):
        return [slot.name]
    return []


def _compile() -> tuple[dict[tuple[Version, str], dict[int, _Layout]], dict[tuple[Version, str], dict[type, _Layout]]]:
    by_id: dict[tuple[Version, str], dict[int, _Layout]] = {}
    by_kind: dict[tuple[Version, str], dict[type, _Layout]] = {}
    for version, kinds in KINDS.items():
        for order in "<>":
            layouts = [_Layout(kind, pid, spec, version, order) for kind, pid, spec in kinds]
            by_id[version, order] = {lay.packet_id: lay for lay in layouts}
            by_kind[version, order] = {lay.kind: lay for lay in layouts}
    return by_id, by_kind


_BY_ID, _BY_KIND = _compile()
_HEADER_V4 = {"<": struct.Struct("<HH"), ">": struct.Struct(">HH")}
_FIRST_ID = {("host", 3): 1, ("ig", 3): 101, ("host", 4): 0x0000, ("ig", 4): 0xFFFF}
_FIRST_NAME = {"host": "IG Control", "ig": "Start of Frame"}


def packet_name(version: Version, packet_id: int) -> str:
    """The standard's name of a packet id in a version ("unknown" when it defines none)."""
    layout = _BY_ID[version, "<"].get(packet_id)
    if layout is not None:
        return layout.name
    raw = RAW_PACKETS[version].get(packet_id)
    return raw[0] if raw else "unknown"


def name_of(packet: object, version: Version) -> str:
    """The standard's name of a decoded packet ("HAT/HOT Request"), for counting."""
    if isinstance(packet, RawPacket):
        return packet_name(version, packet.packet_id)
    layout = _BY_KIND[version, "<"].get(type(packet))
    return layout.name if layout is not None else type(packet).__name__


def packet_size(packet: object, version: Version) -> int:
    """Bytes a packet takes on the wire in a version (the header included).

    Raises:
        CigiError: a packet kind the version does not have (cause "packet_kind").
    """
    if isinstance(packet, RawPacket):
        return (4 if version.major >= 4 else 2) + len(packet.body)
    layout = _BY_KIND[version, "<"].get(type(packet))
    if layout is None:
        raise CigiError("packet_kind", f"{type(packet).__name__} does not exist in CIGI {version}")
    return layout.size


# ---- decode -----------------------------------------------------------------------------------

def decode(datagram: bytes, *, sender: str = "host") -> Message:
    """Decode one CIGI datagram (a message).

    Args:
        datagram: the UDP payload.
        sender: "host" (the first packet must be IG Control) or "ig" (Start of Frame).

    Returns:
        The Message: version and byte order from the first packet, the packets in order (known
        kinds as dataclasses, other packets the version defines as RawPacket), and the count of
        packets skipped per id the version does not define.

    Raises:
        CigiError: for any datagram that is not a valid CIGI 3.2/3.3/4.0 message; no other
            exception escapes for any bytes.
    """
    if sender not in _FIRST_NAME:
        raise CigiError("sender", f"sender {sender!r} is neither 'host' nor 'ig'")
    data = bytes(datagram)
    version, order = _header(data, sender)
    by_id = _BY_ID[version, order]
    raw = RAW_PACKETS[version]
    v4 = version.major >= 4
    header = _HEADER_V4[order]
    header_size = 4 if v4 else 2
    n = len(data)
    packets: list[Packet] = []
    skipped: dict[int, int] = {}
    offset = 0
    index = 1
    while offset < n:
        if n - offset < header_size:
            raise CigiError("truncated", f"packet {index} at byte {offset}: {n - offset} byte(s) left, "
                                         f"a packet header needs {header_size}")
        if v4:
            size, pid = header.unpack_from(data, offset)
        else:
            pid, size = data[offset], data[offset + 1]
        where = f"packet {index} (id {pid} {packet_name(version, pid)}) at byte {offset}"
        if size == 0:
            raise CigiError("bad_size", f"{where}: size 0")
        if size < header_size:
            raise CigiError("bad_size", f"{where}: size {size} is smaller than its {header_size}-byte header")
        if offset + size > n:
            raise CigiError("truncated", f"{where}: size {size} runs past the datagram's end at byte {n}")
        layout = by_id.get(pid)
        if layout is not None:
            if size != layout.size:
                raise CigiError("bad_size", f"{where}: size {size} differs from {layout.size}")
            packets.append(layout.decode(data, offset))
        elif pid in raw:
            fixed = raw[pid][1]
            if fixed is not None and size != fixed:
                raise CigiError("bad_size", f"{where}: size {size} differs from {fixed}")
            packets.append(RawPacket(pid, data[offset + header_size:offset + size]))
        else:
            skipped[pid] = skipped.get(pid, 0) + 1
        offset += size
        index += 1
    return Message(version=version, byte_order=order, packets=tuple(packets), skipped=skipped)


def _header(data: bytes, sender: str) -> tuple[Version, str]:
    """Version and byte order from the first packet (CCL CigiIncomingMsg::CheckFirstPacket)."""
    n = len(data)
    if n == 0:
        raise CigiError("empty", "empty datagram")
    if n < 8:
        raise CigiError("truncated", f"datagram of {n} byte(s): the first packet's header needs 8")
    first = _FIRST_NAME[sender]
    if data[2] in (0x00, 0xFF):
        # CIGI 4: [0..1] size, [2..3] id (0x0000 IG Control, 0xFFFF SOF: same bytes in both orders).
        order = ">" if data[0] == 0 else "<"
        _size, pid = _HEADER_V4[order].unpack_from(data, 0)
        if pid != _FIRST_ID[sender, 4]:
            raise CigiError("first_packet", f"first packet: id {pid:#06x} is not {first} ({_FIRST_ID[sender, 4]:#06x})")
        major, minor = data[4], data[7] >> 4
        if major != 4 or minor != 0:
            raise CigiError("version", f"first packet: CIGI version {major}.{minor} (4.x header) is not supported; "
                                       "4.0 is")
        return V4_0, order
    pid = data[0]
    if pid != _FIRST_ID[sender, 3]:
        raise CigiError("first_packet", f"first packet: id {pid} is not {first} ({_FIRST_ID[sender, 3]})")
    major = data[2]
    minor = (data[4] if sender == "host" else data[5]) >> 4
    if major != 3:
        raise CigiError("version", f"first packet: major version {major} is not supported (3.2, 3.3, 4.0 are)")
    if minor not in (2, 3):
        raise CigiError("version", f"first packet: CIGI version 3.{minor} is not supported (3.2, 3.3, 4.0 are; "
                                   "3.0/3.1 use 16-byte IG Control / SOF)")
    magic = data[6:8]
    if magic == b"\x00\x80":
        order = "<"
    elif magic == b"\x80\x00":
        order = ">"
    else:
        raise CigiError("magic", f"first packet: byte-swap magic {magic.hex()} is neither 0x8000 little- nor "
                                 "big-endian")
    return Version(3, minor), order


# ---- encode -----------------------------------------------------------------------------------

def encode(packets: Iterable[Packet], version: Version, byte_order: str) -> bytes:
    """Encode packets as one datagram in a version's layouts and a byte order.

    Args:
        packets: the packets in order (a message should start with IG Control or Start of Frame;
            this is not enforced, so tests can build bad messages).
        version: V3_2, V3_3 or V4_0.
        byte_order: "<" little-endian or ">" big-endian.

    Raises:
        CigiError: a version or byte order that is not supported, a packet kind the version does
            not have ("packet_kind"), or a field value that does not fit its wire field ("value").
    """
    if version not in KINDS:
        raise CigiError("version", f"version {version} is not supported (3.2, 3.3, 4.0 are)")
    if byte_order not in ("<", ">"):
        raise CigiError("byte_order", f"byte order {byte_order!r} is neither '<' nor '>'")
    by_kind = _BY_KIND[version, byte_order]
    v4 = version.major >= 4
    parts: list[bytes] = []
    for packet in packets:
        if isinstance(packet, RawPacket):
            parts.append(_encode_raw(packet, version, byte_order, v4))
            continue
        layout = by_kind.get(type(packet))
        if layout is None:
            raise CigiError("packet_kind", f"{type(packet).__name__} does not exist in CIGI {version}")
        parts.append(layout.encode(packet))
    return b"".join(parts)


def _encode_raw(packet: RawPacket, version: Version, order: str, v4: bool) -> bytes:
    size = (4 if v4 else 2) + len(packet.body)
    limit = 0xFFFF if v4 else 0xFF
    if not 0 <= packet.packet_id <= limit:
        raise CigiError("value", f"RawPacket: packet_id {packet.packet_id} does not fit CIGI {version}'s id field")
    if size > limit:
        raise CigiError("value", f"RawPacket id {packet.packet_id}: size {size} does not fit CIGI {version}'s "
                                 f"size field (max {limit})")
    fixed = RAW_PACKETS[version].get(packet.packet_id, ("", None))[1]
    if fixed is not None and size != fixed:
        raise CigiError("value", f"RawPacket id {packet.packet_id} ({packet_name(version, packet.packet_id)}): "
                                 f"size {size} differs from {fixed}")
    header = _HEADER_V4[order].pack(size, packet.packet_id) if v4 else bytes((packet.packet_id, size))
    return header + bytes(packet.body)


def kinds_of(version: Version) -> Sequence[type]:
    """The dataclass kinds a version has (for tests and tools)."""
    return [kind for kind, _, _ in KINDS[version]]


def layout_fields(version: Version, kind: type) -> list[str]:
    """The fields of `kind` that `version` carries on the wire (others keep their default)."""
    return [name for _, slot in _BY_KIND[version, "<"][kind].spec for name in _slot_names(slot)
            if not name.startswith("_")]


def bench_decode(iterations: int = 1000) -> float:
    """Mean seconds to decode a typical host datagram (IG Control, Entity Control, 10 HAT/HOT
    requests; CIGI 3.3 little-endian)."""
    import time

    packets: list[Packet] = [IGControl(ig_mode=1, host_frame=1), EntityControl(entity_state=1, alt_z=300.0)]
    packets += [HatHotRequest(request_id=i, request_type=1, lat_x=36.3, lon_y=-84.2) for i in range(10)]
    datagram = encode(packets, V3_3, "<")
    start = time.perf_counter()
    for _ in range(iterations):
        decode(datagram)
    return (time.perf_counter() - start) / iterations



