"""X-Plane flight data recorder text files (.fdr), as X-Plane's "Creating FDR Files" describes.

The file starts with `A` or `I` (line endings) and a version line; then keyword lines
(ACFT, TAIL, DATE, PRES, COMM, ...) that are skipped, and one DATA line per sample:

    DATA, time s, temp degC, lon deg, lat deg, h msl ft, radio alt ft, ailn, elev, rudd,
          pitch deg, roll deg, heading deg true, ... (further columns ignored)

Longitude comes before latitude. Heights are feet above mean sea level (converted to metres).
A DATA line with fewer than 12 values, a value that is not a finite number, or a latitude or
longitude out of range is counted as corrupt and skipped.
"""

from __future__ import annotations

import math
from pathlib import Path

from .track import RawLog

FT_M = 0.3048
#: Columns read from a DATA line (after the keyword): time, lon, lat, h msl, pitch, roll, heading.
TIME, LON, LAT, MSL, PITCH, ROLL, HEADING = 0, 2, 3, 4, 9, 10, 11


def read(path: Path) -> RawLog:
    """The samples of an FDR file."""
    hpr: list[tuple[float, float, float]] = []
    raw = RawLog(hpr=hpr)
    with open(path, encoding="utf-8", errors="replace") as f:
        for line_no, line in enumerate(f, start=1):
            fields = [c.strip() for c in line.split(",")]
            if fields[0].upper() != "DATA":
                continue
            values = [c for c in fields[1:] if c != ""]
            try:
                cols = [float(values[i]) for i in (TIME, LON, LAT, MSL, PITCH, ROLL, HEADING)]
            except (IndexError, ValueError):
                raw.problem("corrupt", f"line {line_no}: {line.strip()[:60]!r}")
                continue
            t, lon, lat, msl, pitch, roll, heading = cols
            if not all(math.isfinite(v) for v in cols) or abs(lat) > 90.0 or abs(lon) > 180.0:
                raw.problem("corrupt", f"line {line_no}: impossible value in {line.strip()[:60]!r}")
                continue
            raw.times.append(t)
            raw.coords.append((lat, lon, msl * FT_M))
            hpr.append((heading, pitch, roll))
    return raw
