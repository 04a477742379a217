"""ArduCopter's GUIDED attitude targets as its firmware flies them: the target shaped
(ATC_RATE_FF_ENAB), throttle boosted by the tilt (ATC_ANGLE_BOOST), thrust as a climb rate unless
GUID_OPTIONS bit 3 makes it throttle, and level flight once GUID_TIMEOUT has passed.

Pure functions of the target, what the vehicle sensed and the parameters; the autopilot
(:mod:`sitl.autopilot.logic`) keeps the shaped attitude between steps. The tilt is *not* limited
to ANGLE_MAX (ArduCopter 4.7/4.8 flew 37.6 deg with 30 deg set: tests/autopilots).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Protocol

from companion.control import quaternion as quat
from companion.control.outer_loop import AttitudeSetpoint
from companion.control.params import VehicleParams
from companion.control.vector import ZERO3, Vec3

from .sensed import Sensed

__all__ = ["CLIMB_RATE_MAX_M_S", "GuidedParams", "ShapedAttitude", "angle_boost", "climb_rate_m_s", "shape_attitude",
           "guided_target", "level_keeping_altitude"]

CLIMB_RATE_MAX_M_S = 2.5
"""thrust as a climb rate: 0 descends at this rate, 0.5 holds, 1 climbs at it [m/s]"""


class GuidedParams(Protocol):
    """The autopilot's parameters GUIDED reads (:class:`~sitl.autopilot.logic.AutopilotParams`)."""

    rate_ff_enabled: bool
    input_tc_s: float
    input_accel_max_rad_s2: float
    guided_thrust_is_throttle: bool
    angle_boost: bool


class ShapedAttitude(NamedTuple):
    """The shaped target ATC_RATE_FF_ENAB flies: an attitude and its body rates [rad/s]."""

    q: quat.Quat
    omega_rad_s: Vec3


def angle_boost(q: quat.Quat) -> float:
    """ArduPilot's throttle boost at the vehicle's tilt: 1 / cos(tilt), the cosine floored at 0.1,
    fading to 0 past 84 deg (get_throttle_boosted)."""
    c = math.cos(float(quat.tilt_angle(q)))
    return min(max(10.0 * c, 0.0), 1.0) / min(max(c, 0.1), 1.0)


def climb_rate_m_s(thrust: float) -> float:
    """The climb rate a normalised thrust asks when thrust is a climb rate: 0.5 holds the altitude."""
    return (thrust - 0.5) * 2.0 * CLIMB_RATE_MAX_M_S


def shape_attitude(prev: ShapedAttitude, q_target: quat.Quat, tc_s: float, accel_max_rad_s2: float,
                   dt_s: float) -> ShapedAttitude:
    """One step of ArduPilot's input shaping, modelled as a critically damped second order of
    natural frequency 1 / ATC_INPUT_TC (the shaped attitude's acceleration is error / tc^2 -
    2 rate / tc, limited by ATC_ACCEL_*_MAX): a 20 deg roll step turns at most 20 deg / (e tc) =
    49 deg/s at tc = 0.15 s. Fitted to the firmware, not copied from it: ArduCopter 4.8 SITL turns
    at 49 deg/s shaped, 85 deg/s unshaped (tests/contract)."""
    q, rates = prev
    err = quat.log(quat.relative(q, q_target))
    tc = max(tc_s, dt_s)
    step = accel_max_rad_s2 * dt_s
    omega: Vec3 = tuple(w + min(max((float(e) / tc - 2.0 * w) / tc * dt_s, -step), step)  # type: ignore[assignment]
                        for e, w in zip(err, rates))
    return ShapedAttitude(quat.integrate(q, omega, dt_s), omega)


def guided_target(sp: AttitudeSetpoint, shaped: ShapedAttitude | None, sensed: Sensed, p: GuidedParams,
                  vehicle: VehicleParams, climb_rate: float,
                  dt_s: float) -> tuple[AttitudeSetpoint, ShapedAttitude | None]:
    """The setpoint an attitude target is flown as, and the shaped attitude to keep (None: not
    shaping). Shaping starts from the vehicle's own attitude and rates."""
    q_d, omega_d = sp.q_d, sp.omega_d_rad_s
    if p.rate_ff_enabled:
        start = shaped or ShapedAttitude(sensed.q_est, sensed.imu.gyro_rad_s)
        shaped = shape_attitude(start, q_d, p.input_tc_s, p.input_accel_max_rad_s2, dt_s)
        q_d, omega_d = shaped
    else:
        shaped = None
    thrust_n = sp.thrust_n
    if p.guided_thrust_is_throttle and p.angle_boost:
        thrust_n = min(thrust_n * angle_boost(sensed.q_est), vehicle.thrust_max_n)
    if not p.guided_thrust_is_throttle:
        v_up = -sensed.tracked.vel_ned_m_s[2]
        cos_tilt = max(math.cos(float(quat.tilt_angle(q_d))), 0.3)
        thrust_n = vehicle.mass_kg * (vehicle.gravity_m_s2 + 2.0 * (climb_rate - v_up)) / cos_tilt
        thrust_n = min(max(thrust_n, 0.0), vehicle.thrust_max_n)
    return AttitudeSetpoint(q_d, omega_d, thrust_n), shaped


def level_keeping_altitude(sensed: Sensed, vehicle: VehicleParams) -> AttitudeSetpoint:
    """GUIDED after GUID_TIMEOUT: level at the current yaw, climb rate zero, drifting freely."""
    v_up = -sensed.tracked.vel_ned_m_s[2]
    thrust_n = min(max(vehicle.mass_kg * (vehicle.gravity_m_s2 - 2.0 * v_up), 0.0), vehicle.thrust_max_n)
    yaw = float(quat.to_euler(sensed.q_est)[2])
    return AttitudeSetpoint(quat.from_yaw(yaw), ZERO3, thrust_n)
