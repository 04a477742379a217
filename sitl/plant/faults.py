"""Sensor faults injected into the simulated vehicle, and the firmware checks that catch them.

Injected (by parameter, for a given number of seconds from now): a tracking-system dropout (no
position or attitude samples), a frozen IMU (the same reading, bit for bit), and an IMU that
reads NaN; and a reset of the position estimate (the reported position moves by a given vector
at once, as an EKF's does after a GPS glitch — announced by the reset counter or not). The
firmware checks every IMU sample: a non-finite or out-of-range one is replaced by
the last good one; a reading repeated bit for bit is stuck (a real IMU's noise never repeats);
bad or stuck for ``fault_after_s`` → the IMU is declared failed (latched until disarmed) and the
attitude estimate falls back to the tracking system alone. Position is valid while tracking
samples arrive; ``position_timeout_s`` without one → position lost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.control import quaternion as quat
from companion.control.quaternion import Quat
from companion.control.vector import Vec3

from .sensors import ImuSample

__all__ = ["SensorFaults", "ImuMonitor", "MocapRates"]


@dataclass
class SensorFaults:
    """Windows [start, end) of simulated time in which each fault is active."""

    mocap_dropout: tuple[float, float] = (math.inf, math.inf)
    imu_frozen: tuple[float, float] = (math.inf, math.inf)
    imu_nan: tuple[float, float] = (math.inf, math.inf)
    position_offset_ned_m: Vec3 = (0.0, 0.0, 0.0)
    """what the reported position estimate adds to the tracked position [m, NED]: the sum of the
    estimator resets injected (the vehicle itself does not move)"""
    position_resets: int = 0
    """estimator resets announced (ODOMETRY's reset_counter); an unannounced jump is not counted"""

    def reset_position(self, shift_ned_m: Vec3, announced: bool) -> None:
        """The position estimate jumps by ``shift_ned_m`` now; ``announced``: the reset counter counts it."""
        o = self.position_offset_ned_m
        self.position_offset_ned_m = (o[0] + shift_ned_m[0], o[1] + shift_ned_m[1], o[2] + shift_ned_m[2])
        if announced:
            self.position_resets += 1

    @staticmethod
    def active(window: tuple[float, float], t: float) -> bool:
        return window[0] <= t < window[1]


@dataclass
class ImuMonitor:
    max_gyro_rad_s: float = 35.0
    """2000 deg/s, a MEMS gyro's range"""
    max_accel_m_s2: float = 160.0
    """16 g"""
    fault_after_s: float = 0.05
    last_good: ImuSample | None = None
    bad_since: float = math.nan
    failed: str | None = None
    """why the IMU was declared failed (None: healthy)"""
    rejected: int = 0
    _previous: ImuSample | None = None

    def check(self, sample: ImuSample, t: float) -> ImuSample:
        """The sample the firmware uses: this one if plausible, else the last good one."""
        (g0, g1, g2), (a0, a1, a2) = sample
        mg, ma = self.max_gyro_rad_s, self.max_accel_m_s2
        # chained comparisons: False for NaN too (this runs at 1 kHz, so no generators)
        plausible = (-mg <= g0 <= mg and -mg <= g1 <= mg and -mg <= g2 <= mg
                     and -ma <= a0 <= ma and -ma <= a1 <= ma and -ma <= a2 <= ma)
        stuck = plausible and sample == self._previous
        self._previous = sample
        if plausible and not stuck:
            self.bad_since = math.nan
            self.last_good = sample
            return sample
        self.rejected += 1
        if math.isnan(self.bad_since):
            self.bad_since = t
        elif self.failed is None and t - self.bad_since >= self.fault_after_s:
            self.failed = "non-finite or out-of-range readings" if not plausible else "frozen (readings repeat exactly)"
        if not plausible and self.last_good is not None:
            return self.last_good
        return sample


@dataclass
class MocapRates:
    """Body rates from consecutive tracking attitudes (the fallback when the gyro has failed),
    low-passed: at 60 Hz the attitude noise (0.1 deg) differenced is ~6 deg/s."""

    cutoff_rad_s: float = 60.0
    omega_rad_s: Vec3 = (0.0, 0.0, 0.0)
    _last: tuple[float, Quat] | None = None

    def update(self, t: float, q: Quat) -> Vec3:
        if self._last is not None and t > self._last[0]:
            dt = t - self._last[0]
            raw = quat.log(quat.relative(self._last[1], q))
            rate = (raw[0] / dt, raw[1] / dt, raw[2] / dt)
            k = 1.0 - math.exp(-self.cutoff_rad_s * dt)
            w = self.omega_rad_s
            self.omega_rad_s = (w[0] + k * (rate[0] - w[0]), w[1] + k * (rate[1] - w[1]), w[2] + k * (rate[2] - w[2]))
        self._last = (t, q)
        return self.omega_rad_s
