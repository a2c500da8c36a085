"""Flight-log replay: read a log, clean it into a track, sample it at frame times.

    csv   documented CSV (geodetic or world coordinates, optional attitude)   csv_log.py
    igc   IGC glider logger files                                             igc.py
    fdr   X-Plane flight data recorder text files                             fdr.py
    ulog  PX4 ULog files, through pyulog                                      ulog.py

docs/replay-formats.md describes each format, the geodetic conversion, the sampling and the
attitude estimate for logs without attitude.
"""

from __future__ import annotations

import importlib
import logging
from pathlib import Path

from .player import Replay, ReplayStatus
from .track import PROBLEMS, Track, build_track

__all__ = ["FORMATS", "PROBLEMS", "Replay", "ReplayStatus", "Track", "detect_format", "load_track"]

log = logging.getLogger("ig.host.replay")

#: Format name -> (reader module, file suffixes).
FORMATS = {
    "csv": ("host_sim.replay.csv_log", (".csv",)),
    "igc": ("host_sim.replay.igc", (".igc",)),
    "fdr": ("host_sim.replay.fdr", (".fdr",)),
    "ulog": ("host_sim.replay.ulog", (".ulg", ".ulog")),
}


def detect_format(path: Path) -> str:
    """The format of a log from its suffix (or the ULog magic bytes).

    Raises:
        ValueError: the suffix is none of FORMATS' and the file is not a ULog.
    """
    suffix = path.suffix.lower()
    for name, (_, suffixes) in FORMATS.items():
        if suffix in suffixes:
            return name
    with open(path, "rb") as f:
        if f.read(7) == b"ULog\x01\x12\x35":
            return "ulog"
    known = ", ".join(s for _, suffixes in FORMATS.values() for s in suffixes)
    raise ValueError(f"{path.name}: cannot tell the log format from {suffix or 'no suffix'!r} ({known}); "
                     f"name it with --replay-format {'|'.join(FORMATS)}")


def load_track(path: str | Path, *, format: str = "auto",
               origin: tuple[float, float, float] | None = None) -> tuple[Track, str]:
    """Read and clean a flight log; returns the track and the format read.

    Args:
        path: the log file.
        format: "auto" (by suffix) or a name of FORMATS.
        origin: geodetic reference (lat deg, lon deg, h m) of the world frame; default the
            log's first fix.

    Raises:
        ValueError: unknown format, unreadable file or fewer than two usable records; the
            message names the file and the problem.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    if format == "auto":
        format = detect_format(path)
    if format not in FORMATS:
        raise ValueError(f"format {format!r} is not one of auto, {', '.join(FORMATS)}")
    reader = importlib.import_module(FORMATS[format][0])
    try:
        raw = reader.read(path)
    except (OSError, UnicodeError) as exc:
        raise ValueError(f"{path.name}: cannot read: {exc}") from exc
    track = build_track(raw, origin=origin, name=path.name)
    found = {k: v for k, v in track.problems.items() if v}
    log.info("%s (%s): %d records over %.1f s%s%s", path.name, format, len(track.t_s), track.duration_s,
             ", attitude estimated from the track" if track.attitude_estimated else "",
             f"; problems {found}" if found else "")
    for note in track.notes:
        log.warning("%s: %s", path.name, note)
    return track, format
