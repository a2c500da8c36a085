"""The sun's direction against Meeus's worked examples and an independent ephemeris."""

import math

import pytest

from services.rig.solar import sun_direction


def elevation_azimuth(v):
    """(elevation, azimuth clockwise from north), degrees, of an east-north-up vector."""
    east, north, up = v
    return math.degrees(math.asin(up)), math.degrees(math.atan2(east, north)) % 360.0


def test_meeus_examples_25a_and_28a():
    # J. Meeus, Astronomical Algorithms (1998), 1992 October 13.0: declination -7.78507 deg
    # (example 25.a), equation of time 13 min 42.7 s = 3.42775 deg (example 28.a). At the
    # equator, north = sin(declination); at longitude 180 and 0 h UTC the hour angle is the
    # equation of time.
    east, north, up = sun_direction(year=1992, month=10, day=13, hour=0, minute=0, lat_deg=0.0, lon_deg=180.0)
    assert math.degrees(math.asin(north)) == pytest.approx(-7.78507, abs=0.002)
    assert math.degrees(math.atan2(-east, up)) == pytest.approx(3.42775, abs=0.005)


def test_noon_on_the_equinox_at_the_equator_is_overhead():
    # 2024-03-20 03:06 UTC is the equinox; solar noon at longitude 0 is about 12:07 UTC.
    elevation, _ = elevation_azimuth(sun_direction(year=2024, month=3, day=20, hour=12, minute=7,
                                                   lat_deg=0.0, lon_deg=0.0))
    assert elevation == pytest.approx(90.0, abs=0.5)


def test_sunrise_on_the_equinox_is_due_east_and_sunset_due_west():
    # 2000-03-20 07:35 UTC is the equinox: the sun is on the celestial equator, so it bears due
    # east all morning at the equator; 12 h later, at the antimeridian's opposite, due west.
    _, azimuth = elevation_azimuth(sun_direction(year=2000, month=3, day=20, hour=6, minute=0,
                                                 lat_deg=0.0, lon_deg=0.0))
    assert azimuth == pytest.approx(90.0, abs=0.5)
    _, azimuth = elevation_azimuth(sun_direction(year=2000, month=3, day=20, hour=18, minute=0,
                                                 lat_deg=0.0, lon_deg=0.0))
    assert azimuth == pytest.approx(270.0, abs=0.5)


def test_solstice_sunrise_azimuth_at_greenwich():
    # Where the sun crosses the horizon, cos(azimuth) = sin(declination) / cos(latitude): about
    # 49.6 deg at Greenwich on the June solstice (declination 23.44 deg), geometric sunrise
    # (no refraction) about 03:49 UTC.
    lat = 51.4769
    times = [(3, m) for m in range(30, 60)] + [(4, m) for m in range(10)]
    vs = [sun_direction(year=2024, month=6, day=20, hour=h, minute=m, lat_deg=lat, lon_deg=0.0) for h, m in times]
    i = min(range(len(vs)), key=lambda k: abs(vs[k][2]))
    elevation, azimuth = elevation_azimuth(vs[i])
    assert abs(elevation) < 0.15  # within a minute of the crossing
    expected = math.degrees(math.acos(math.sin(math.radians(23.44)) / math.cos(math.radians(lat))))
    assert azimuth == pytest.approx(expected, abs=0.5)


# Geometric (no refraction) elevation and azimuth from PyEphem 4.2.1 (an independent, more
# precise ephemeris: VSOP87), UTC.
EPHEM = [
    ((2024, 6, 21, 4, 43, 51.4769, -0.0005), 6.7985, 60.4394),
    ((2024, 12, 21, 12, 0, -33.87, 151.21), -26.6605, 209.1896),
    ((2010, 1, 1, 0, 0, 64.15, -21.94), -46.2249, 329.0190),
    ((2031, 9, 15, 17, 30, 40.7128, -74.006), 51.1880, 195.5704),
]


@pytest.mark.parametrize(("when", "elevation", "azimuth"), EPHEM)
def test_against_an_ephemeris(when, elevation, azimuth):
    year, month, day, hour, minute, lat, lon = when
    v = sun_direction(year=year, month=month, day=day, hour=hour, minute=minute, lat_deg=lat, lon_deg=lon)
    assert math.fsum(c * c for c in v) == pytest.approx(1.0, abs=1e-12)
    got_elevation, got_azimuth = elevation_azimuth(v)
    assert got_elevation == pytest.approx(elevation, abs=0.05)
    assert got_azimuth == pytest.approx(azimuth, abs=0.05)


@pytest.mark.parametrize(("field", "kwargs"), [
    ("2024-02-30", {"month": 2, "day": 30}),
    ("24:00", {"hour": 24}),
    ("lat_deg: 91", {"lat_deg": 91.0}),
    ("lon_deg: nan", {"lon_deg": float("nan")}),
])
def test_bad_values_are_named(field, kwargs):
    args = dict(year=2024, month=6, day=1, hour=12, minute=0, lat_deg=0.0, lon_deg=0.0) | kwargs
    with pytest.raises(ValueError, match=field):
        sun_direction(**args)
