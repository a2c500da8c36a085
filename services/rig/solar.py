"""Where the sun is: a unit vector in the local east-north-up frame from a UTC date and time and
a place, by the low-precision solar position of the NOAA solar calculator (J. Meeus,
Astronomical Algorithms, 2nd ed., 1998, chapters 25 and 28; docs/references.md).

The host computes it from CIGI's Celestial Sphere Control (date MMDDYYYY, hour and minute) and
the database origin's latitude and longitude, and sends it in the Frame's environment. Accuracy:
about 0.01 deg in declination and 0.1 minute in the equation of time for 1950-2050, far below
anything lighting can show. The direction is geometric: atmospheric refraction, which lifts the
sun by about 0.5 deg at the horizon, is left out (it moves the light source, not the scene).
"""

from __future__ import annotations

import datetime
import math

#: Julian day of 2000 January 1.5 (J2000.0), days.
_J2000 = 2451545.0
#: Julian day of 1970 January 1.0 (the UNIX epoch), days.
_UNIX_EPOCH_JD = 2440587.5


def sun_direction(*, year: int, month: int, day: int, hour: int, minute: int,
                  lat_deg: float, lon_deg: float) -> tuple[float, float, float]:
    """Unit vector towards the sun in the local east-north-up frame of a place.

    Args:
        year, month, day: the UTC date (Gregorian calendar).
        hour, minute: the UTC time of day (hour 0..23, minute 0..59).
        lat_deg: geodetic latitude, degrees north (-90..90).
        lon_deg: longitude, degrees east (-180..180; any finite value is taken modulo 360).

    Returns:
        (east, north, up), a unit vector; up = sin(solar elevation).

    Raises:
        ValueError: an impossible date or time, or a latitude or longitude out of range; the
            message names the field and value.
    """
    try:
        when = datetime.datetime(year, month, day, hour, minute, tzinfo=datetime.UTC)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"date {year:04}-{month:02}-{day:02} {hour:02}:{minute:02} UTC: {exc}") from exc
    if not (math.isfinite(lat_deg) and -90.0 <= lat_deg <= 90.0):
        raise ValueError(f"lat_deg: {lat_deg} is outside [-90, 90]")
    if not math.isfinite(lon_deg):
        raise ValueError(f"lon_deg: {lon_deg} is not finite")
    jd = _UNIX_EPOCH_JD + when.timestamp() / 86400.0
    t = (jd - _J2000) / 36525.0  # Julian centuries since J2000.0 (UT for TT: 1 min is 0.0007 deg)

    # Meeus ch. 25, low accuracy: the sun's geometric mean longitude and anomaly (degrees), the
    # eccentricity of the Earth's orbit and the equation of the centre.
    l0 = (280.46646 + t * (36000.76983 + t * 0.0003032)) % 360.0
    m = math.radians(357.52911 + t * (35999.05029 - 0.0001537 * t))
    e = 0.016708634 - t * (0.000042037 + 0.0000001267 * t)
    c = (math.sin(m) * (1.914602 - t * (0.004817 + 0.000014 * t))
         + math.sin(2 * m) * (0.019993 - 0.000101 * t) + math.sin(3 * m) * 0.000289)
    # Apparent longitude (nutation and aberration) and the true obliquity of the ecliptic.
    omega = math.radians(125.04 - 1934.136 * t)
    lam = math.radians(l0 + c - 0.00569 - 0.00478 * math.sin(omega))
    eps0 = 23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0
    eps = math.radians(eps0 + 0.00256 * math.cos(omega))
    decl = math.asin(math.sin(eps) * math.sin(lam))

    # Equation of time (Meeus 28.3, after Smart), radians of hour angle: apparent minus mean sun.
    y = math.tan(eps / 2) ** 2
    l0r = math.radians(l0)
    eot = (y * math.sin(2 * l0r) - 2 * e * math.sin(m) + 4 * e * y * math.sin(m) * math.cos(2 * l0r)
           - 0.5 * y * y * math.sin(4 * l0r) - 1.25 * e * e * math.sin(2 * m))

    # Hour angle: the mean sun's (UTC minutes since midnight, 0.25 deg a minute, noon at 0) moved
    # by the longitude, plus the equation of time.
    ha = math.radians((hour * 60 + minute) * 0.25 - 180.0 + lon_deg) + eot
    lat = math.radians(lat_deg)
    # The sun's direction in the equatorial frame of the place (hour angle west positive),
    # rotated by the latitude into east-north-up: a rotation, so the vector stays unit.
    east = -math.cos(decl) * math.sin(ha)
    north = math.cos(lat) * math.sin(decl) - math.sin(lat) * math.cos(decl) * math.cos(ha)
    up = math.sin(lat) * math.sin(decl) + math.cos(lat) * math.cos(decl) * math.cos(ha)
    return (east, north, up)
