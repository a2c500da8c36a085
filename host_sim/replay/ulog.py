"""PX4 ULog files (.ulg), read with pyulog.

Positions come from `vehicle_global_position` (lat, lon degrees; alt metres AMSL), or, when a
log has none, from the GNSS receiver (`sensor_gps` or the older `vehicle_gps_position`, with
degrees or 1e-7 degrees and metres or millimetres as the log's version has them). The attitude
comes from `vehicle_attitude` (quaternion q, FRD body to NED), interpolated (slerp) to the
position times; without it the attitude is estimated from the track. Times are the logger's
microsecond timestamps.

pyulog skips damaged messages itself and flags the file; a flagged file counts one `corrupt`.
A position with a time or value outside physics (track.RANGES) is counted as out_of_range
and skipped, naming the field and the position's number in its topic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import attitude
from .track import RANGES, RawLog, out_of_range

TOPICS = ["vehicle_global_position", "sensor_gps", "vehicle_gps_position", "vehicle_attitude"]


def read(path: Path) -> RawLog:
    """The positions (and attitudes) of a ULog file.

    Raises:
        ValueError: pyulog cannot read the file, or it has no position topic.
    """
    from pyulog import ULog  # optional dependency (the `devices` extra)

    try:
        with open(path, "rb") as f:  # pyulog leaves a file it opened itself open when it fails
            ulog = ULog(f, TOPICS)
    except Exception as exc:  # pyulog raises many kinds on a bad file
        raise ValueError(f"{path.name}: not a readable ULog file: {type(exc).__name__}: {exc}") from exc
    data = {d.name: d.data for d in ulog.data_list if d.multi_id == 0}
    raw = RawLog()
    if ulog.file_corruption:
        raw.problem("corrupt", "pyulog found damaged messages and skipped them")
    try:
        t, lat, lon, alt = _positions(data, path)
    except KeyError as exc:  # a damaged format definition names other fields
        raise ValueError(f"{path.name}: the position topic has no field {exc}") from exc
    raw.records_read = len(t)
    keep = np.ones(len(t), bool)
    for name, v in (("time_s", t), ("lat_deg", lat), ("lon_deg", lon), ("alt_m", alt)):
        lo, hi = RANGES[name]
        for i in np.flatnonzero(keep & ~((v >= lo) & (v <= hi))):  # NaN fails too
            raw.problem("out_of_range", f"position {i + 1}: {out_of_range(name, float(v[i]))}")
            keep[i] = False
    raw.lines, raw.numbered = [int(i) + 1 for i in np.flatnonzero(keep)], "position"
    t, lat, lon, alt = t[keep], lat[keep], lon[keep], alt[keep]
    raw.times = [float(v) for v in t]
    raw.coords = [(float(a), float(b), float(c)) for a, b, c in zip(lat, lon, alt, strict=True)]
    att = data.get("vehicle_attitude")
    if att is not None and all(k in att for k in ("timestamp", "q[0]", "q[1]", "q[2]", "q[3]")) \
            and len(att["timestamp"]) >= 1:
        # A damaged format definition can give the fields other types, whose values become
        # NaN or overflow on the way to float64 (numpy warns "invalid value encountered in
        # cast"): those samples are dropped by `good` below, so the warnings say nothing more.
        with np.errstate(invalid="ignore", over="ignore"):
            at = att["timestamp"].astype(np.float64) * 1e-6
            q = np.stack([att[f"q[{k}]"] for k in range(4)], axis=-1).astype(np.float64)
            good = np.isfinite(q).all(axis=1) & np.isfinite(at) & (np.linalg.norm(q, axis=1) > 0.5)
        at, q = at[good], q[good]
        order = np.argsort(at, kind="stable")
        at, q = at[order], q[order]
        if len(at):
            raw.hpr = [_attitude_at(at, q, ti) for ti in t]
    return raw


def _positions(data: dict, path: Path) -> tuple[np.ndarray, ...]:
    if "vehicle_global_position" in data:
        d = data["vehicle_global_position"]
        return (d["timestamp"] * 1e-6, d["lat"].astype(np.float64), d["lon"].astype(np.float64),
                d["alt"].astype(np.float64))
    for topic in ("sensor_gps", "vehicle_gps_position"):
        if topic in data:
            d = data[topic]
            if "latitude_deg" in d:
                lat, lon = d["latitude_deg"], d["longitude_deg"]
                alt = d["altitude_msl_m"] if "altitude_msl_m" in d else d["altitude_ellipsoid_m"]
            else:
                lat, lon, alt = d["lat"] * 1e-7, d["lon"] * 1e-7, d["alt"] * 1e-3
            return (d["timestamp"] * 1e-6, np.asarray(lat, np.float64), np.asarray(lon, np.float64),
                    np.asarray(alt, np.float64))
    raise ValueError(f"{path.name}: no position topic ({', '.join(TOPICS[:3])})")


def _attitude_at(at: np.ndarray, q_ned: np.ndarray, t: float) -> tuple[float, float, float]:
    """heading, pitch, roll at t from attitude samples, slerped (held past either end)."""
    i = int(np.searchsorted(at, t, side="right")) - 1
    if i < 0:
        q = q_ned[0]
    elif i >= len(at) - 1:
        q = q_ned[-1]
    else:
        f = (t - at[i]) / (at[i + 1] - at[i]) if at[i + 1] > at[i] else 0.0
        q = attitude.slerp(q_ned[i] / np.linalg.norm(q_ned[i]), q_ned[i + 1] / np.linalg.norm(q_ned[i + 1]), f)
    h, p, r = attitude.from_ned_quaternion(q / np.linalg.norm(q))
    return float(h), float(p), float(r)
