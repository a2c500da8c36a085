"""The documented CSV flight log (docs/replay-formats.md).

A header row names the columns, in any order; `#` starts a comment line:

    time_s, lat_deg, lon_deg, alt_m [, heading_deg, pitch_deg, roll_deg]     geodetic (WGS-84)
    time_s, x_m, y_m, z_m [, heading_deg, pitch_deg, roll_deg]                world frame

Other columns are ignored. A row with a missing, non-numeric or non-finite value, or a latitude
or longitude out of range, is counted as corrupt and skipped.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from .track import RawLog

GEODETIC = ("lat_deg", "lon_deg", "alt_m")
WORLD = ("x_m", "y_m", "z_m")
ATTITUDE = ("heading_deg", "pitch_deg", "roll_deg")


def read(path: Path) -> RawLog:
    """The records of a CSV log.

    Raises:
        ValueError: no header, or a header without time_s and a full position triple, or
            with only part of the attitude triple (the message names the columns).
    """
    raw = RawLog()
    with open(path, newline="", encoding="utf-8", errors="replace") as f:
        # Comment lines become empty rows, so that line_num stays the file's line number.
        rows = csv.reader("\n" if line.lstrip().startswith("#") else line for line in f)
        header = next((row for row in rows if row), None)
        if header is None:
            raise ValueError(f"{path.name}: empty CSV log (expected a header row)")
        columns = {name.strip(): i for i, name in enumerate(header)}
        if all(c in columns for c in GEODETIC):
            position = GEODETIC
        elif all(c in columns for c in WORLD):
            position, raw.geodetic = WORLD, False
        else:
            raise ValueError(f"{path.name}: header {', '.join(columns)} has neither {', '.join(GEODETIC)} "
                             f"nor {', '.join(WORLD)}")
        if "time_s" not in columns:
            raise ValueError(f"{path.name}: header {', '.join(columns)} has no time_s")
        present = [c in columns for c in ATTITUDE]
        if any(present) and not all(present):
            raise ValueError(f"{path.name}: header has only part of {', '.join(ATTITUDE)}")
        wanted = ["time_s", *position, *(ATTITUDE if all(present) else ())]
        raw.hpr = [] if all(present) else None
        for row in rows:
            line = rows.line_num
            if not any(cell.strip() for cell in row):
                continue
            try:
                values = [float(row[columns[c]]) for c in wanted]
            except (IndexError, ValueError):
                raw.problem("corrupt", f"line {line}: {','.join(row)[:60]!r}")
                continue
            bad = [c for c, v in zip(wanted, values, strict=True) if not math.isfinite(v)]
            if raw.geodetic and not bad:
                bad = [c for c, v, lim in zip(GEODETIC, values[1:4], (90.0, 180.0, None), strict=True)
                       if lim is not None and abs(v) > lim]
            if bad:
                raw.problem("corrupt", f"line {line}: {bad[0]} = {values[wanted.index(bad[0])]}")
                continue
            raw.times.append(values[0])
            raw.coords.append((values[1], values[2], values[3]))
            if raw.hpr is not None:
                raw.hpr.append((values[4], values[5], values[6]))
    return raw
