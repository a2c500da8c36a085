"""Small flight logs written by the tests, in every replay format, from one known flight."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

#: The reference point of the flight and its records: a level left turn at 120 m above it.
ORIGIN = (46.5, 7.0, 600.0)
SPEED_MPS, TURN_DPS = 30.0, -3.0


def flight(n: int = 20, dt: float = 1.0):
    """(t, lat, lon, h, heading, pitch, roll) of a steady left turn starting north, one a second."""
    w = math.radians(TURN_DPS)
    radius = SPEED_MPS / abs(w)
    rows = []
    for k in range(n):
        t = k * dt
        east = -radius * (1 - math.cos(w * t))  # turning left from heading north
        north = radius * math.sin(abs(w) * t)
        lat = ORIGIN[0] + north / 111_200.0
        lon = ORIGIN[1] + east / (111_320.0 * math.cos(math.radians(ORIGIN[0])))
        heading = (TURN_DPS * t) % 360.0
        rows.append((t, lat, lon, ORIGIN[2] + 120.0, heading, 2.0, -17.0))
    return rows


def write_csv(path: Path, rows, *, attitude: bool = True, extra_lines=()) -> Path:
    head = "time_s,lat_deg,lon_deg,alt_m" + (",heading_deg,pitch_deg,roll_deg" if attitude else "")
    lines = ["# a test flight", head]
    for r in rows:
        lines.append(",".join(f"{v:.9f}" for v in (r if attitude else r[:4])))
    for at, text in extra_lines:
        lines.insert(at, text)
    path.write_text("\n".join(lines) + "\n")
    return path


def igc_b(t: float, lat: float, lon: float, h: float, valid: str = "A") -> str:
    t = int(round(t))
    hh, mm, ss = (t // 3600) % 24, (t // 60) % 60, t % 60

    def dm(v, width):
        d = int(abs(v))
        return f"{d:0{width}d}{round((abs(v) - d) * 60000):05d}"
    return (f"B{hh:02d}{mm:02d}{ss:02d}{dm(lat, 2)}{'N' if lat >= 0 else 'S'}{dm(lon, 3)}{'E' if lon >= 0 else 'W'}"
            f"{valid}{int(round(h)) - 30:05d}{int(round(h)):05d}")


def write_igc(path: Path, rows, *, start_s: int = 12 * 3600, extra=()) -> Path:
    lines = ["AXXX001 test logger", "HFDTE010725", "HFPLTPILOTINCHARGE:Test", "I013638FXA"]
    for t, lat, lon, h, *_ in rows:
        lines.append(igc_b(start_s + t, lat, lon, h) + "000")
    for at, text in extra:
        lines.insert(at, text)
    lines.append("GABCDEF")
    path.write_text("\r\n".join(lines) + "\r\n")
    return path


def write_fdr(path: Path, rows, *, extra=()) -> Path:
    lines = ["A", "4", "", "ACFT,Aircraft/Laminar Research/Cessna 172SP/Cessna_172SP.acf,", "TAIL,N12345,",
             "TIME,12:00:00,", "DATE,01/07/25,", "PRES,29.92,", "TEMP,65,", "WIND,230,10,", ""]
    for t, lat, lon, h, hd, p, r in rows:
        values = [t, 15, lon, lat, h / 0.3048, 400, 0, 0, 0, p, r, hd, 58, 0] + [0] * 60
        lines.append("DATA," + ",".join(f"{v:.9f}" if isinstance(v, float) else str(v) for v in values) + ",")
    for at, text in extra:
        lines.insert(at, text)
    path.write_text("\n".join(lines) + "\n")
    return path


def _msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def write_ulog(path: Path, rows, *, attitude: bool = True, damage: bool = False) -> Path:
    """A minimal ULog v1: vehicle_global_position (and vehicle_attitude) topics."""
    out = bytearray(b"ULog\x01\x12\x35" + b"\x01" + struct.pack("<Q", 0))
    out += _msg("B", bytes(8) + bytes(8) + bytes(24))  # flag bits: nothing incompatible
    out += _msg("F", b"vehicle_global_position:uint64_t timestamp;double lat;double lon;float alt;")
    out += _msg("F", b"vehicle_attitude:uint64_t timestamp;float[4] q;")
    out += _msg("A", struct.pack("<BH", 0, 1) + b"vehicle_global_position")
    if attitude:
        out += _msg("A", struct.pack("<BH", 0, 2) + b"vehicle_attitude")
    for k, (t, lat, lon, h, hd, p, r) in enumerate(rows):
        us = int(round((100.0 + t) * 1e6))
        out += _msg("D", struct.pack("<HQddf", 1, us, lat, lon, h))
        if attitude:
            # PX4: FRD body to NED, q = qz(yaw) qy(pitch) qx(roll), w first
            y, pt, rl = (math.radians(a) / 2 for a in (hd, p, r))
            qz = np.array([math.cos(y), 0, 0, math.sin(y)])
            qy = np.array([math.cos(pt), 0, math.sin(pt), 0])
            qx = np.array([math.cos(rl), math.sin(rl), 0, 0])
            from host_sim.replay.attitude import multiply
            q = multiply(multiply(qz, qy), qx)
            out += _msg("D", struct.pack("<HQ4f", 2, us + 5000, *q))
        if damage and k == len(rows) // 2:
            out += _msg("D", struct.pack("<H", 1) + b"\x01\x02")  # a data message cut short
    path.write_bytes(bytes(out))
    return path


def straight(n: int = 300, speed_mps: float = 60.0):
    """(t, lat, lon, h, heading, pitch, roll) of a level flight due east, one record a second:
    long and fast enough for a misdated record to land kilometres away."""
    return [(float(k), ORIGIN[0], ORIGIN[1] + speed_mps * k / (111_320.0 * math.cos(math.radians(ORIGIN[0]))),
             ORIGIN[2] + 300.0, 90.0, 1.0, 0.0) for k in range(n)]


def csv_cells(rows, blanks=()):
    """CSV data lines of rows (t, lat, lon, h, heading, pitch, roll), with the cells of the
    (row index, column index) pairs in blanks left empty."""
    out = []
    for i, r in enumerate(rows):
        out.append(",".join("" if (i, j) in blanks else f"{v:.9f}" for j, v in enumerate(r)))
    return out
