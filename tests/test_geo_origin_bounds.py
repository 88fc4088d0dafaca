"""A global origin (:class:`~mecanum_mav.mecanum.geo.GlobalOrigin`) as its docstring states it:
MAVLink's integer coordinates (degrees * 1e7, altitude in millimetres), latitudes from pole to
pole and longitudes from -180 to 180 degrees, both ends included, and nothing off the earth or
non-finite."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.mecanum.geo import GlobalOrigin


@pytest.mark.parametrize("lat_e7, lon_e7", [
    (900_000_000, 0), (-900_000_000, 0),  # the poles
    (0, 1_800_000_000), (0, -1_800_000_000),  # the antimeridian, from either side
    (900_000_000, -1_800_000_000), (-900_000_000, 1_800_000_000),
])
def test_an_origin_may_sit_on_a_pole_or_on_the_antimeridian(lat_e7, lon_e7):
    origin = GlobalOrigin(lat_e7, lon_e7)
    assert (origin.lat_e7, origin.lon_e7, origin.alt_mm) == (lat_e7, lon_e7, 0)


@pytest.mark.parametrize("lat_e7, lon_e7", [
    (900_000_001, 0), (-900_000_001, 0),  # a 1e-7 degree past a pole
    (0, 1_800_000_001), (0, -1_800_000_001),  # past the antimeridian
    (900_000_001, 1_800_000_001),
])
def test_an_origin_a_hair_off_the_earth_is_refused(lat_e7, lon_e7):
    with pytest.raises(ValueError, match="is not on earth"):
        GlobalOrigin(lat_e7, lon_e7)


def test_an_origin_from_degrees_is_in_mavlink_units_degrees_1e7_and_millimetres():
    origin = GlobalOrigin.from_degrees(47.3977419, -8.5455938, 488.123)
    assert origin == GlobalOrigin(473_977_419, -85_455_938, 488_123)
    assert GlobalOrigin.from_degrees(-33.8688197, 151.2092955).alt_mm == 0  # (no altitude)
    assert GlobalOrigin.from_degrees(0.0, 0.0, -12.5) == GlobalOrigin(0, 0, -12_500)


@pytest.mark.parametrize("lat_deg, lon_deg, alt_m", [
    (math.nan, 8.5, 0.0), (47.4, math.inf, 0.0), (47.4, 8.5, -math.inf), (47.4, 8.5, math.nan),
])
def test_an_origin_from_non_finite_degrees_or_metres_is_refused(lat_deg, lon_deg, alt_m):
    with pytest.raises(ValueError, match=r"^origin must be finite$"):
        GlobalOrigin.from_degrees(lat_deg, lon_deg, alt_m)


def test_an_origin_from_degrees_off_the_earth_is_refused():
    with pytest.raises(ValueError, match="is not on earth"):
        GlobalOrigin.from_degrees(90.0000001, 0.0)
    assert GlobalOrigin.from_degrees(-90.0, 180.0) == GlobalOrigin(-900_000_000, 1_800_000_000)


def test_an_origin_off_the_earth_is_refused_naming_it_in_degrees():
    with pytest.raises(ValueError, match=r"^origin 90\.0000001, -12\.5 is not on earth$"):
        GlobalOrigin(900_000_001, -125_000_000)
    with pytest.raises(ValueError, match=r"^origin -45\.0, 180\.0000001 is not on earth$"):
        GlobalOrigin(-450_000_000, 1_800_000_001)
