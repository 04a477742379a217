"""Where the simulated world is on Earth: the local NED origin, its geodetic position, and the
atmosphere and magnetic field there (what a GNSS receiver, a barometer and a compass measure).

A flat-earth projection around the origin (the vehicle flies within metres of it), the ISA
troposphere for pressure, and a constant magnetic field (the World Magnetic Model's value at the
default origin, Zurich: declination 3.2 deg, inclination 63.6 deg, 48.2 uT; set another for
another place, as PX4 and ArduPilot compare it with their own model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.control.vector import Vec3
from companion.mission.plan import EARTH_RADIUS_M

__all__ = ["GeoOrigin", "EARTH_RADIUS_M", "isa_pressure_pa", "isa_temperature_c"]

SEA_LEVEL_PA = 101325.0
SEA_LEVEL_K = 288.15
LAPSE_K_M = 0.0065
GAS_EXPONENT = 5.25588
"""g M / (R L) of the ISA troposphere"""


@dataclass(frozen=True)
class GeoOrigin:
    """Where the local NED origin is on Earth (default: PX4 SITL's Zurich field)."""

    lat_deg: float = 47.397742
    lon_deg: float = 8.545594
    alt_m: float = 488.0
    """altitude above mean sea level [m]"""
    mag_field_ned_gauss: Vec3 = (0.2140, 0.0120, 0.4317)
    """Earth's magnetic field at the origin, NED [gauss]"""

    def to_global(self, north_m: float, east_m: float, down_m: float) -> tuple[int, int, int]:
        """``(lat 1e7 deg, lon 1e7 deg, alt mm AMSL)`` by a flat-earth projection."""
        lat, lon, alt = self.to_geodetic(north_m, east_m, down_m)
        return int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000))

    def to_geodetic(self, north_m: float, east_m: float, down_m: float) -> tuple[float, float, float]:
        """``(lat deg, lon deg, alt m AMSL)`` of a local NED position."""
        lat = self.lat_deg + math.degrees(north_m / EARTH_RADIUS_M)
        lon = self.lon_deg + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(self.lat_deg))))
        return lat, lon, self.alt_m - down_m


def isa_temperature_c(alt_m: float) -> float:
    """Air temperature of the ISA troposphere at ``alt_m`` above mean sea level [deg C]."""
    return SEA_LEVEL_K - LAPSE_K_M * alt_m - 273.15


def isa_pressure_pa(alt_m: float) -> float:
    """Static pressure of the ISA troposphere at ``alt_m`` above mean sea level [Pa]."""
    return SEA_LEVEL_PA * (1.0 - LAPSE_K_M * alt_m / SEA_LEVEL_K) ** GAS_EXPONENT
