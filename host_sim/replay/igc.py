"""IGC files, the flight logs of glider loggers (FAI IGC specification, appendix A).

Only B records (fixes) are read; everything else (headers, tasks, security G records) is
skipped. A B record is `B HHMMSS DDMMmmm{N|S} DDDMMmmm{E|W} {A|V} PPPPP GGGGG ...`: UTC time,
latitude and longitude in degrees, minutes and thousandths of minutes, fix validity (A: 3D
fix, V: no valid fix), pressure altitude and GNSS altitude (metres above the WGS-84
ellipsoid). Extensions declared by an I record follow and are ignored.

Heights are the GNSS altitude when any valid fix has one, else the pressure altitude (some
loggers write 00000 for GNSS). V records are counted (`no_fix`) and skipped. A time that goes
back by more than 12 hours is the flight crossing midnight UTC. IGC has no attitude: it is
estimated from the track (attitude.estimate).
"""

from __future__ import annotations

import re
from pathlib import Path

from .track import RawLog

B_RECORD = re.compile(r"B(\d{2})(\d{2})(\d{2})(\d{2})(\d{5})([NS])(\d{3})(\d{5})([EW])([AV])([-\d]\d{4})([-\d]\d{4})")


def read(path: Path) -> RawLog:
    """The fixes of an IGC file."""
    raw = RawLog()
    fixes = []  # (line, time, lat, lon, pressure alt, gnss alt)
    day = 0.0
    last = None
    with open(path, encoding="ascii", errors="replace") as f:
        for line_no, line in enumerate(f, start=1):
            if not line.startswith("B"):
                continue
            m = B_RECORD.match(line)
            if m is None:
                raw.problem("corrupt", f"line {line_no}: {line.strip()[:40]!r}")
                continue
            hh, mm, ss, lat_d, lat_m, ns, lon_d, lon_m, ew, valid, p_alt, g_alt = m.groups()
            if int(hh) > 23 or int(mm) > 59 or int(ss) > 59 or int(lat_d) > 90 or int(lon_d) > 180 \
                    or int(lat_m) >= 60000 or int(lon_m) >= 60000:
                raw.problem("corrupt", f"line {line_no}: field out of range in {line.strip()[:40]!r}")
                continue
            if valid == "V":
                raw.problem("no_fix", f"line {line_no}: fix marked V (no valid position)")
                continue
            t = int(hh) * 3600 + int(mm) * 60 + int(ss) + day
            if last is not None and t < last - 12 * 3600:
                day += 86400.0  # past midnight UTC
                t += 86400.0
            last = t
            lat = (int(lat_d) + int(lat_m) / 60000.0) * (1 if ns == "N" else -1)
            lon = (int(lon_d) + int(lon_m) / 60000.0) * (1 if ew == "E" else -1)
            fixes.append((t, lat, lon, float(p_alt), float(g_alt)))
    use_gnss = any(g != 0.0 for *_, g in fixes)
    for t, lat, lon, p_alt, g_alt in fixes:
        raw.times.append(t)
        raw.coords.append((lat, lon, g_alt if use_gnss else p_alt))
    return raw
