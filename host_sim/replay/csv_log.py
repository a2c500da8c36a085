"""The documented CSV flight log (docs/replay-formats.md).

A header row names the columns, in any order; `#` starts a comment line:

    time_s, lat_deg, lon_deg, alt_m [, heading_deg] [, pitch_deg] [, roll_deg]     geodetic (WGS-84)
    time_s, x_m, y_m, z_m [, heading_deg] [, pitch_deg] [, roll_deg]                world frame

Other columns are ignored. Each attitude column is optional on its own (an ADS-B-derived log
has heading and roll but no pitch): a column the header lacks is a column without values,
estimated from the track by build_track while the others keep their logged values.
Each column is its own time series: recorders leave a cell empty
when they did not sample that value, so an empty cell (or `nan`, as numpy writes one) is a
missing value, filled later by interpolating that column alone (track.build_track). A row
needs a time: without a readable one it is skipped. A cell that is not a number is counted
as corrupt, and one outside physics (track.RANGES) as out_of_range; either is refused on its
own and the rest of its row is kept.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Iterator
from pathlib import Path

from .text import head, refuse_binary
from .track import ATTITUDE, RawLog, out_of_range

GEODETIC = ("lat_deg", "lon_deg", "alt_m")
WORLD = ("x_m", "y_m", "z_m")


def _rows(f: Iterable[str]) -> Iterator[tuple[int, list[str]]]:
    """(line number, cells) of every line of f, comment lines as no cells. Each line is parsed
    on its own: a stray quote (a damaged cell) would otherwise open a quoted field that
    swallows every line after it (a flight log has no field that spans lines)."""
    for number, line in enumerate(f, start=1):
        if line.lstrip().startswith("#"):
            yield number, []
        else:
            yield number, next(csv.reader([line]), [])


def _encoding(path: Path) -> str:
    """The text encoding of a CSV log from its first bytes: UTF-8 with or without the byte
    order mark spreadsheets write ("CSV UTF-8"), or UTF-16 with its mark.

    Raises:
        ValueError: more control bytes than a damaged text log has (a binary file).
    """
    first = head(path)
    if first.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "utf-16"  # before the binary test: every other byte of UTF-16 text is NUL
    refuse_binary(path, first, "CSV log")
    return "utf-8-sig"


def _shown(names: Iterable[str]) -> str:
    """Header names for a message: non-printable characters escaped, at most 120 characters."""
    text = ", ".join(names)
    text = "".join(c if c.isprintable() else ascii(c)[1:-1] for c in text)
    return text if len(text) <= 120 else text[:117] + "..."


def read(path: Path) -> RawLog:
    """The records of a CSV log.

    Raises:
        ValueError: a binary file, no header, or a header without time_s and a full position triple, or
            or a position column without any value (the message names the columns).
    """
    raw = RawLog()
    with open(path, newline="", encoding=_encoding(path), errors="replace") as f:
        rows = _rows(f)
        header = next((row for _, row in rows if row), None)
        if header is None:
            raise ValueError(f"{path.name}: empty CSV log (expected a header row)")
        columns = {name.strip(): i for i, name in enumerate(header)}
        if all(c in columns for c in GEODETIC):
            position = GEODETIC
        elif all(c in columns for c in WORLD):
            position, raw.geodetic = WORLD, False
        else:
            raise ValueError(f"{path.name}: header {_shown(columns)} has neither {', '.join(GEODETIC)} "
                             f"nor {', '.join(WORLD)}")
        if "time_s" not in columns:
            raise ValueError(f"{path.name}: header {_shown(columns)} has no time_s")
        present = tuple(c for c in ATTITUDE if c in columns)
        values = [*position, *present]
        raw.hpr = [] if present else None
        raw.columns = ("position", *present)
        for line, row in rows:
            if not any(cell.strip() for cell in row):
                continue
            raw.records_read += 1
            t = _cell(raw, row, columns["time_s"], "time_s", line)
            if math.isnan(t):  # refused and counted by _cell, unless missing
                text = _cell_text(row, columns["time_s"])
                if text.lower() in ("", "nan"):
                    raw.problem("corrupt", f"line {line}: time_s = {text!r} (a row needs a time)")
                continue
            cells = dict(zip(values, (_cell(raw, row, columns[c], c, line) for c in values), strict=True))
            raw.times.append(t)
            raw.lines.append(line)
            raw.coords.append((cells[position[0]], cells[position[1]], cells[position[2]]))
            if raw.hpr is not None:
                # A column the header lacks is NaN in every record: no value, estimated.
                h, p, r = (cells.get(c, math.nan) for c in ATTITUDE)
                raw.hpr.append((h % 360.0 if math.isfinite(h) else h, p, r))
    for j, c in enumerate(position):
        if raw.times and not any(math.isfinite(p[j]) for p in raw.coords):
            raise ValueError(f"{path.name}: column {c} has no value in any row")
    return raw


def _cell_text(row: list[str], i: int) -> str:
    return row[i].strip() if i < len(row) else ""  # a short row: its last cells are empty


def _cell(raw: RawLog, row: list[str], i: int, name: str, line: int) -> float:
    """The value of a cell, or NaN when it is empty or refused (counted, with its line)."""
    text = _cell_text(row, i)
    if text == "" or text.lower() == "nan":
        return math.nan
    try:
        v = float(text)
    except ValueError:
        raw.problem("corrupt", f"line {line}: {name} = {text[:30]!r} is not a number")
        return math.nan
    why = out_of_range(name, v)
    if why is not None:
        raw.problem("out_of_range", f"line {line}: {why}")
        return math.nan
    return v
