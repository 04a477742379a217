"""The sensors an autopilot's own estimator navigates by: barometer, magnetometer and GNSS.

The paper's vehicle needs none of them (its position and attitude come from motion capture:
:mod:`.sensors`); a real PX4 or ArduPilot flying this plant does (``sitl --firmware``). Each is
the truth at the vehicle plus seeded noise:

- barometer: ISA static pressure at the true altitude, white noise of ``baro_noise_m`` of
  altitude, the air temperature;
- magnetometer: the origin's field turned into body axes, white noise;
- GNSS: position with a first-order Gauss-Markov error (``gnss_pos_noise_m`` standard deviation,
  correlated over ``gnss_error_time_constant_s``: a receiver's error wanders, it does not jump),
  velocity with white noise, delivered ``gnss_delay_s`` late at ``gnss_rate_hz``.

Defaults: a u-blox M8/M9-class receiver in open sky (0.5 m horizontal and 0.8 m vertical wander)
and an MS5611-class barometer (0.1 m).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

from companion.control import quaternion as quat
from companion.control.vector import Vec3

from .dynamics import RigidBodyState
from .geo import GeoOrigin, isa_pressure_pa, isa_temperature_c
from .noise import GaussianStream

__all__ = ["NavSensorParams", "POSITION_SOURCES", "BaroSample", "GnssSample", "NavSensors"]

POSITION_SOURCES = ("mocap", "gnss")
"""what the firmware's estimator positions the vehicle from: motion capture as external vision (the
paper's setup) or GNSS"""


@dataclass(frozen=True)
class NavSensorParams:
    position_source: str = "mocap"
    """``"mocap"``: the tracking system of :mod:`.sensors` as external vision (the paper's
    laboratory); ``"gnss"``: the receiver below (a vehicle outdoors)"""
    baro_noise_m: float = 0.1
    mag_noise_gauss: float = 0.005
    gnss_rate_hz: float = 10.0
    gnss_pos_noise_m: Vec3 = (0.5, 0.5, 0.8)
    """standard deviation of the wandering position error, NED"""
    gnss_error_time_constant_s: float = 20.0
    gnss_vel_noise_m_s: float = 0.05
    gnss_delay_s: float = 0.0

    def __post_init__(self) -> None:
        if self.position_source not in POSITION_SOURCES:
            raise ValueError(f"position_source: expected one of {', '.join(POSITION_SOURCES)}, "
                             f"got {self.position_source!r}")
        if not self.gnss_rate_hz > 0 or not self.gnss_error_time_constant_s > 0:
            raise ValueError("gnss_rate_hz and gnss_error_time_constant_s must be positive")


class BaroSample(NamedTuple):
    pressure_pa: float
    temperature_c: float
    altitude_m: float
    """the pressure altitude the reading stands for (AMSL)"""


class GnssSample(NamedTuple):
    time_s: float
    """when the position was true"""
    lat_deg: float
    lon_deg: float
    alt_m: float
    """AMSL"""
    vel_ned_m_s: Vec3
    eph_m: float
    epv_m: float


class NavSensors:
    """Barometer, magnetometer and GNSS of one vehicle (``seed``: its own noise streams)."""

    def __init__(self, params: NavSensorParams, origin: GeoOrigin, seed: int) -> None:
        self.params = params
        self.origin = origin
        self._baro = GaussianStream(seed, "baro", 1)
        self._mag = GaussianStream(seed, "mag", 3)
        self._gnss = GaussianStream(seed, "gnss", 6)
        s = params.gnss_pos_noise_m
        start = GaussianStream(seed, "gnss_start", 3).initial()
        self._gnss_err: list[float] = [s[0] * start[0], s[1] * start[1], s[2] * start[2]]
        self._period_s = 1.0 / params.gnss_rate_hz
        self._next_gnss_s = 0.0
        self._in_transit: deque[GnssSample] = deque()

    def baro(self, state: RigidBodyState) -> BaroSample:
        alt = self.origin.alt_m - state.pos_ned_m[2] + self.params.baro_noise_m * self._baro.next()[0]
        return BaroSample(isa_pressure_pa(alt), isa_temperature_c(alt), alt)

    def mag(self, state: RigidBodyState) -> Vec3:
        """The field in body axes [gauss]."""
        n = self._mag.next()
        k = self.params.mag_noise_gauss
        b = quat.rotate_inverse(state.q, self.origin.mag_field_ned_gauss)
        return (b[0] + k * n[0], b[1] + k * n[1], b[2] + k * n[2])

    def gnss(self, t_s: float, state: RigidBodyState) -> GnssSample | None:
        """A fix when one is due at ``t_s`` (after its delay), else None."""
        p = self.params
        if t_s + 1e-9 >= self._next_gnss_s:
            self._next_gnss_s += self._period_s
            n = self._gnss.next()
            a = math.exp(-self._period_s / p.gnss_error_time_constant_s)
            b = math.sqrt(1.0 - a * a)
            e, s = self._gnss_err, p.gnss_pos_noise_m
            for i in range(3):
                e[i] = a * e[i] + b * s[i] * n[i]
            r, v, k = state.pos_ned_m, state.vel_ned_m_s, p.gnss_vel_noise_m_s
            lat, lon, alt = self.origin.to_geodetic(r[0] + e[0], r[1] + e[1], r[2] + e[2])
            vel = (v[0] + k * n[3], v[1] + k * n[4], v[2] + k * n[5])
            self._in_transit.append(GnssSample(t_s, lat, lon, alt, vel, math.hypot(s[0], s[1]), s[2]))
        if self._in_transit and self._in_transit[0].time_s + p.gnss_delay_s <= t_s + 1e-9:
            return self._in_transit.popleft()
        return None
