"""Global (latitude, longitude) <-> local NED, about a global origin.

A flat-earth (local tangent plane) projection about the origin, as ArduPilot's
``Location::get_distance_NE`` does: north = dlat * R, east = dlon * R * cos(origin latitude),
with R = 6378137 m (WGS-84 equatorial radius). Over the few hundred metres a rover mission
spans the projection error is far below a millimetre per metre; the conversion is exactly
invertible, so a position converted to global and back lands where it started (to the 1e-7
degree, ~1 cm, resolution of MAVLink's integer coordinates).

Latitudes and longitudes travel as MAVLink integers, degrees * 1e7; local positions are
metres north and east of the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["EARTH_RADIUS_M", "GlobalOrigin"]

EARTH_RADIUS_M = 6_378_137.0
_E7_TO_RAD = math.radians(1e-7)


@dataclass(frozen=True)
class GlobalOrigin:
    """Where local NED (0, 0) is on the earth.

    Attributes:
        lat_e7: latitude, degrees * 1e7 (-900000000 .. 900000000).
        lon_e7: longitude, degrees * 1e7 (-1800000000 .. 1800000000).
        alt_mm: altitude above mean sea level, millimetres (reported, not used for driving).
    """

    lat_e7: int
    lon_e7: int
    alt_mm: int = 0

    def __post_init__(self) -> None:
        if not (-900_000_000 <= self.lat_e7 <= 900_000_000
                and -1_800_000_000 <= self.lon_e7 <= 1_800_000_000):
            raise ValueError(f"origin {self.lat_e7 / 1e7}, {self.lon_e7 / 1e7} is not on earth")

    @classmethod
    def from_degrees(cls, lat_deg: float, lon_deg: float, alt_m: float = 0.0) -> GlobalOrigin:
        """An origin from degrees and metres; raises ValueError if not finite or not on earth."""
        if not all(math.isfinite(v) for v in (lat_deg, lon_deg, alt_m)):
            raise ValueError("origin must be finite")
        return cls(round(lat_deg * 1e7), round(lon_deg * 1e7), round(alt_m * 1000.0))

    @property
    def _east_scale(self) -> float:
        # Never zero: within ~0.6 degrees of a pole the east scale stops shrinking.
        return EARTH_RADIUS_M * max(math.cos(self.lat_e7 * _E7_TO_RAD), 0.01) * _E7_TO_RAD

    def to_local(self, lat_e7: float, lon_e7: float) -> tuple[float, float]:
        """(north m, east m) of a global position (degrees * 1e7) from this origin."""
        dlon = (lon_e7 - self.lon_e7 + 1_800_000_000) % 3_600_000_000 - 1_800_000_000
        return (lat_e7 - self.lat_e7) * EARTH_RADIUS_M * _E7_TO_RAD, dlon * self._east_scale

    def to_global(self, north_m: float, east_m: float) -> tuple[int, int]:
        """(lat_e7, lon_e7) of a local position (metres north and east of this origin)."""
        lat = self.lat_e7 + north_m / (EARTH_RADIUS_M * _E7_TO_RAD)
        lon = self.lon_e7 + east_m / self._east_scale
        lon = (lon + 1_800_000_000) % 3_600_000_000 - 1_800_000_000
        return round(lat), round(lon)
