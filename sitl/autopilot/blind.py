"""Flying without position: the accelerometer's vertical bias, learnt while the vehicle is tracked,
and the level descent on the accelerometer alone once tracking is lost.

Nothing tells touch-down without position (the ground stops the vehicle, the IMU still reads 1 g),
so the descent counts itself down once the integrated descent exceeds the height it had when
position was lost by 30 % + 0.5 m; resting on the ground meanwhile costs nothing (the commanded
thrust is below the weight).
"""

from __future__ import annotations

from typing import NamedTuple

from companion.control import quaternion as quat

from .sensed import Sensed

__all__ = ["BLIND_DESCENT_M_S", "BlindDescent", "learn_bias", "blind_start", "blind_step", "counted_down",
           "blind_thrust_n"]

BLIND_DESCENT_M_S = 0.7
"""the descent speed flown blind [m/s]"""
BIAS_TIME_CONSTANT_S = 2.0
"""the bias is learnt through a first-order filter of this time constant"""


class BlindDescent(NamedTuple):
    vz_m_s: float
    """vertical speed integrated from the accelerometer (NED, + down)"""
    height_m: float
    """height above the ground when position was lost"""
    descended_m: float
    """descent integrated since"""


def learn_bias(bias_m_s2: float, sensed: Sensed, gravity_m_s2: float, dt_s: float) -> float:
    """One step of the vertical accelerometer bias (NED) against the tracking system's acceleration:
    ``b' = (R(q) f)_z + g - a_z - b`` over ``BIAS_TIME_CONSTANT_S``."""
    w, x, y, z = sensed.q_est
    f = sensed.imu.specific_force_body_m_s2
    sf_ned_z = (2.0 * (x * z - w * y) * f[0] + 2.0 * (y * z + w * x) * f[1]
                + (w * w - x * x - y * y + z * z) * f[2])  # third row of R(q) times f
    return bias_m_s2 + dt_s / BIAS_TIME_CONSTANT_S * (sf_ned_z + gravity_m_s2 - sensed.tracked.accel_ned_m_s2[2]
                                                      - bias_m_s2)


def blind_start(sensed: Sensed, ground_z_m: float) -> BlindDescent:
    """The descent from the newest tracked state: its vertical speed and its height."""
    tracked = sensed.tracked
    return BlindDescent(float(tracked.vel_ned_m_s[2]), max(0.0, ground_z_m - float(tracked.pos_ned_m[2])), 0.0)


def blind_step(d: BlindDescent, sensed: Sensed, bias_m_s2: float, gravity_m_s2: float, dt_s: float) -> BlindDescent:
    """The vertical speed and the descent after one step of the bias-corrected accelerometer."""
    sf_ned = quat.rotate(sensed.q_est, sensed.imu.specific_force_body_m_s2)
    vz = d.vz_m_s + (sf_ned[2] + gravity_m_s2 - bias_m_s2) * dt_s
    return BlindDescent(vz, d.height_m, d.descended_m + max(vz, 0.0) * dt_s)


def counted_down(d: BlindDescent) -> bool:
    """Descended 30 % + 0.5 m more than the height it started from: on the ground."""
    return d.descended_m > 1.3 * d.height_m + 0.5


def blind_thrust_n(d: BlindDescent, mass_kg: float, gravity_m_s2: float, weight_n: float,
                   thrust_max_n: float) -> float:
    """Thrust that holds ``BLIND_DESCENT_M_S`` (a proportional loop on the integrated speed, 2 /s),
    never below 30 % of the weight nor above the maximum."""
    thrust = mass_kg * (gravity_m_s2 - 2.0 * (BLIND_DESCENT_M_S - d.vz_m_s))
    return min(max(thrust, 0.3 * weight_n), thrust_max_n)
