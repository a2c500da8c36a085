"""IGC files, the flight logs of glider loggers (FAI IGC specification, appendix A).

Only B records (fixes) are read; everything else (headers, tasks, security G records) is
skipped. A B record is `B HHMMSS DDMMmmm{N|S} DDDMMmmm{E|W} {A|V} PPPPP GGGGG ...`: UTC time,
latitude and longitude in degrees, minutes and thousandths of minutes, fix validity (A: 3D
fix, V: no valid fix), pressure altitude and GNSS altitude (metres above the WGS-84
ellipsoid). Extensions declared by an I record follow and are ignored.

Heights are the GNSS altitude when any valid fix has one, else the pressure altitude (some
loggers write 00000 for GNSS). V records are counted (`no_fix`) and skipped. A time that goes
back by more than 12 hours is the flight crossing midnight UTC when the next fix goes back as
well; a single fix half a day off is a misdated one and moves no other fix (track.py judges
it). IGC has no attitude: it is
estimated from the track (attitude.estimate). A fix whose latitude, longitude or chosen height
is outside physics (track.RANGES: latitude 90 degrees 30 minutes, a height of 99999 m) is
counted as out_of_range and skipped.
"""

from __future__ import annotations

import re
from pathlib import Path

from .text import head, refuse_binary
from .track import RawLog, out_of_range

B_RECORD = re.compile(r"B(\d{2})(\d{2})(\d{2})(\d{2})(\d{5})([NS])(\d{3})(\d{5})([EW])([AV])([-\d]\d{4})([-\d]\d{4})")


def read(path: Path) -> RawLog:
    """The fixes of an IGC file.

    Raises:
        ValueError: a binary file, or a text file without any B record (naming it).
    """
    refuse_binary(path, head(path), "IGC log")
    raw = RawLog()
    fixes = []  # (line, time of day, lat, lon, pressure alt, gnss alt)
    line_no = 0
    with open(path, encoding="ascii", errors="replace") as f:
        for line_no, line in enumerate(f, start=1):
            if not line.startswith("B"):
                continue
            raw.records_read += 1
            m = B_RECORD.match(line)
            if m is None:
                raw.problem("corrupt", f"line {line_no}: {line.strip()[:40]!r}")
                continue
            hh, mm, ss, lat_d, lat_m, ns, lon_d, lon_m, ew, valid, p_alt, g_alt = m.groups()
            bad = next(((name, text, limit) for name, text, limit in (
                ("hours", hh, 23), ("minutes", mm, 59), ("seconds", ss, 59),
                ("latitude degrees", lat_d, 90), ("latitude thousandths of minutes", lat_m, 59999),
                ("longitude degrees", lon_d, 180), ("longitude thousandths of minutes", lon_m, 59999))
                if int(text) > limit), None)
            if bad is not None:
                name, text, limit = bad
                raw.problem("out_of_range", f"line {line_no}: {name} = {text} outside 0 .. {limit}")
                continue
            if valid == "V":
                raw.problem("no_fix", f"line {line_no}: fix marked V (no valid position)")
                continue
            t = float(int(hh) * 3600 + int(mm) * 60 + int(ss))
            lat = (int(lat_d) + int(lat_m) / 60000.0) * (1 if ns == "N" else -1)
            lon = (int(lon_d) + int(lon_m) / 60000.0) * (1 if ew == "E" else -1)
            why = out_of_range("lat_deg", lat) or out_of_range("lon_deg", lon)
            if why is not None:
                raw.problem("out_of_range", f"line {line_no}: {why}")
                continue
            fixes.append((line_no, t, lat, lon, float(p_alt), float(g_alt)))
    if raw.records_read == 0:
        # Without this the log would end in "0 usable record(s)", as if its fixes were bad.
        raise ValueError(f"{path.name}: no B record (fix) in its {line_no} line(s): not an IGC flight log")
    use_gnss = any(g != 0.0 for *_, g in fixes)
    days = _days([f[1] for f in fixes])
    for (line_no, t, lat, lon, p_alt, g_alt), day in zip(fixes, days, strict=True):
        t += day
        h = g_alt if use_gnss else p_alt
        why = out_of_range("alt_m", h)
        if why is not None:
            raw.problem("out_of_range", f"line {line_no}: {why}")
            continue
        raw.times.append(t)
        raw.lines.append(line_no)
        raw.coords.append((lat, lon, h))
    return raw


#: Longest time without fixes across midnight UTC that still counts as a midnight crossing,
#: seconds: a logger records every few seconds while it flies.
MIDNIGHT_GAP_S = 2 * 3600.0


def _days(sod: list[float]) -> list[float]:
    """Seconds to add to each fix's time of day: a day more after each midnight UTC.

    A fix more than 12 hours before (after) the last accepted one crosses midnight (is a
    fix of the same day) only if the next fix agrees, and (crossing) lands within
    MIDNIGHT_GAP_S after it; otherwise it is misdated and keeps its time without moving the day
    of the fixes after it.
    """
    half = 12 * 3600.0
    out, day, last = [], 0.0, None
    for k, s in enumerate(sod):
        t = s + day
        nxt = sod[k + 1] + day if k + 1 < len(sod) else None
        if last is not None and t < last - half:
            # Past midnight only if the day's last fix was late enough for this one to follow
            # it within MIDNIGHT_GAP_S (two garbage fixes at 00:00:00 after a fix at noon agree
            # with each other, but no flight's record jumps twelve hours).
            if nxt is None or not nxt < last - half or t + 86400.0 - last > MIDNIGHT_GAP_S:
                out.append(day)  # misdated
                continue
            day += 86400.0  # past midnight UTC
            t += 86400.0
        elif last is not None and t > last + half and (nxt is None or not nxt > last + half):
            out.append(day)
            continue
        last = t
        out.append(day)
    return out
