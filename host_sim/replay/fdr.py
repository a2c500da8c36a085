"""X-Plane flight data recorder text files (.fdr), as X-Plane's "Creating FDR Files" describes.

The file starts with `A` or `I` (line endings) and a version line; then keyword lines
(ACFT, TAIL, DATE, PRES, COMM, ...) that are skipped, and one DATA line per sample:

    DATA, time s, temp degC, lon deg, lat deg, h msl ft, radio alt ft, ailn, elev, rudd,
          pitch deg, roll deg, heading deg true, ... (further columns ignored)

Longitude comes before latitude. Heights are feet above mean sea level (converted to metres).
A DATA line with fewer than 12 values or a value that is not a number is counted as corrupt
and skipped; one with a value outside physics (track.RANGES: a time beyond 1e10 s, a pitch of
95 degrees, a latitude beyond 90) as out_of_range, naming the field. FDR samples are whole
records written at once, so one impossible value condemns the line.
"""

from __future__ import annotations

from pathlib import Path

from .text import head, refuse_binary
from .track import RawLog, out_of_range

FT_M = 0.3048
#: Columns read from a DATA line (after the keyword): time, lon, lat, h msl, pitch, roll, heading.
TIME, LON, LAT, MSL, PITCH, ROLL, HEADING = 0, 2, 3, 4, 9, 10, 11
#: The fields of those columns, as track.RANGES names them (heights checked in metres).
_FIELDS = ("time_s", "lon_deg", "lat_deg", "alt_m", "pitch_deg", "roll_deg", "heading_deg")


def read(path: Path) -> RawLog:
    """The samples of an FDR file.

    Raises:
        ValueError: a binary file, or a text file without any DATA line (naming it).
    """
    refuse_binary(path, head(path), "X-Plane FDR log")
    hpr: list[tuple[float, float, float]] = []
    raw = RawLog(hpr=hpr)
    line_no = 0
    with open(path, encoding="utf-8", errors="replace") as f:
        for line_no, line in enumerate(f, start=1):
            fields = [c.strip() for c in line.split(",")]
            if fields[0].upper() != "DATA":
                continue
            raw.records_read += 1
            values = [c for c in fields[1:] if c != ""]
            try:
                cols = [float(values[i]) for i in (TIME, LON, LAT, MSL, PITCH, ROLL, HEADING)]
            except (IndexError, ValueError):
                raw.problem("corrupt", f"line {line_no}: {line.strip()[:60]!r}")
                continue
            t, lon, lat, msl, pitch, roll, heading = cols
            cols[3] = msl = msl * FT_M
            why = next((w for w in map(out_of_range, _FIELDS, cols) if w is not None), None)
            if why is not None:
                raw.problem("out_of_range", f"line {line_no}: {why}")
                continue
            raw.times.append(t)
            raw.lines.append(line_no)
            raw.coords.append((lat, lon, msl))
            hpr.append((heading % 360.0, pitch, roll))
    if raw.records_read == 0:
        # Without this the log would end in "0 usable record(s)", as if its samples were bad.
        raise ValueError(f"{path.name}: no DATA line in its {line_no} line(s): not an X-Plane FDR log")
    return raw
