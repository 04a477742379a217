"""The reference the bundled autopilot's position loop tracks when a setpoint is a motion, not a point:
PX4's trajectory setpoints in OFFBOARD, and the braking that begins every position mode entered at speed.

PX4 v1.16 hands an offboard trajectory setpoint (SET_POSITION_TARGET_LOCAL_NED: position, velocity and
acceleration, each axis given or not) to its cascaded position controller: a velocity setpoint of the
velocity feed-forward plus ``MPC_XY_P`` / ``MPC_Z_P`` times the position error, within
``MPC_XY_VEL_MAX`` and ``MPC_Z_VEL_MAX_UP`` / ``_DN``, then an acceleration of the acceleration
feed-forward plus a gain times the velocity error. The bundled vehicle's position loop is the paper's
(ISM+DO, PD+DO, PID or AIBC from ``companion.control``), which tracks a reference -- position,
velocity, acceleration and yaw. :func:`shape_step` runs the same cascade on that reference itself,
as a kinematic model with limited speed, acceleration and jerk, so that a velocity step, a position
50 m away or a vehicle entering HOLD at 8 m/s becomes a reference the airframe can follow.

**Braking.** A position mode (HOLD, LAND, RTL, ...) entered from OFFBOARD starts with :data:`BRAKE`: the
reference starts at the vehicle's position and velocity and is brought to rest at no more than
``brake_accel_*`` (PX4's ``MPC_ACC_DOWN_MAX``, ``MPC_ACC_UP_MAX``, ``MPC_ACC_HOR_MAX``), the mode then
holding, landing or returning from where it stopped. Started at rest instead (the reference filter of
``companion.control.trajectory`` jumps to its 2 m/s limit from any faster start), a HOLD entered in an
8 m/s climb asked for 700 m/s^2 downwards for one step: the force limits turned that into 70 deg of tilt
at a tenth of the hover thrust, and the loss-of-control failsafe stopped the motors 56 m up
(docs/faults.md).

Floats only (one vehicle): no I/O, no clock, ``dt`` passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from companion.control.trajectory import wrap_angle
from companion.control.vector import ZERO3, Vec3

__all__ = ["NAN3", "TrajectoryTarget", "BRAKE", "ShapingLimits", "ShapedReference", "shape_step", "at_rest",
           "body_to_ned"]

NAN3: Vec3 = (math.nan, math.nan, math.nan)
"""an axis not given (PX4: NaN in trajectory_setpoint)"""


@dataclass(frozen=True)
class TrajectoryTarget:
    """One trajectory setpoint, NED, as PX4's ``trajectory_setpoint`` holds it: a NaN component is an axis
    the setpoint leaves free; a NaN yaw holds the heading (or turns at ``yaw_rate_rad_s`` if given)."""

    pos_ned_m: Vec3 = NAN3
    vel_ned_m_s: Vec3 = NAN3
    accel_ned_m_s2: Vec3 = NAN3
    yaw_rad: float = math.nan
    yaw_rate_rad_s: float = math.nan


BRAKE = TrajectoryTarget(vel_ned_m_s=ZERO3)
"""come to rest, wherever that is"""


@dataclass(frozen=True)
class ShapingLimits:
    """Speeds, accelerations and gains of the reference, named after PX4 v1.16's parameters (defaults in
    brackets where ours differ: this airframe is a 0.63 kg indoor quadrotor with 3x thrust and much drag)."""

    speed_xy_m_s: float = 5.0
    """MPC_XY_VEL_MAX [12]: at 5 m/s this airframe's drag (3.3 N) already takes 28 deg of tilt; at 12 m/s, 63"""
    speed_up_m_s: float = 3.0
    """MPC_Z_VEL_MAX_UP"""
    speed_down_m_s: float = 1.5
    """MPC_Z_VEL_MAX_DN"""
    accel_xy_m_s2: float = 3.0
    """MPC_ACC_HOR"""
    accel_up_m_s2: float = 4.0
    """MPC_ACC_UP_MAX"""
    accel_down_m_s2: float = 3.0
    """MPC_ACC_DOWN_MAX: braking a climb needs the thrust to fall to m (g - this), 0.69 of the hover"""
    brake_accel_xy_m_s2: float = 5.0
    """MPC_ACC_HOR_MAX: braking is allowed more than a commanded manoeuvre; this airframe's drag alone
    decelerates it by 8 m/s^2 at 7 m/s"""
    jerk_m_s3: float = 8.0
    """MPC_JERK_MAX"""
    pos_gain_xy: float = 0.95
    """MPC_XY_P [1/s]: velocity per metre of position error"""
    pos_gain_z: float = 1.0
    """MPC_Z_P [1/s]"""
    vel_gain: float = 2.0
    """acceleration per m/s of velocity error [1/s]; with ``jerk_m_s3`` at least this times the largest
    acceleration the reference approaches a new velocity without overshoot"""
    yaw_gain: float = 2.0
    """heading approach [1/s]"""
    yaw_rate_max_rad_s: float = math.radians(90.0)
    lead_max_m: float = 2.0
    """the reference never runs further than this ahead of the vehicle (an unreachable velocity or a
    saturated airframe would otherwise leave the position loop an ever growing error)"""


class ShapedReference(NamedTuple):
    """The reference the position loop tracks (NED)."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    accel_ned_m_s2: Vec3
    yaw_rad: float


def body_to_ned(vec_frd: Vec3, yaw_rad: float) -> Vec3:
    """A MAV_FRAME_BODY_NED vector in NED: rotated by the heading only, as PX4 v1.16 does (forward and
    right stay horizontal whatever the tilt; down stays down)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    x, y, z = vec_frd
    return (c * x - s * y, s * x + c * y, z)


def _limit_xy_z(v: Vec3, xy_max: float, up_max: float, down_max: float) -> Vec3:
    """Horizontal norm at most ``xy_max`` (direction kept), vertical within [-up_max, down_max] (NED)."""
    h = math.hypot(v[0], v[1])
    k = xy_max / h if h > xy_max else 1.0
    return (k * v[0], k * v[1], min(max(v[2], -up_max), down_max))


def _commanded_accel(lim: ShapingLimits, ref: ShapedReference, target: TrajectoryTarget,
                     accel_xy_max_m_s2: float, dt: float) -> Vec3:
    """PX4's cascade on the reference: velocity setpoint from the feed-forward and the position error,
    limited, then acceleration from the velocity error plus the acceleration feed-forward, limited;
    an axis given only an acceleration takes it as it is (kept from pushing past the speed limits)."""
    gains = (lim.pos_gain_xy, lim.pos_gain_xy, lim.pos_gain_z)
    steered = [False, False, False]
    v_cmd = [0.0, 0.0, 0.0]
    a_ff = [0.0, 0.0, 0.0]
    for i in range(3):
        p, v, a = target.pos_ned_m[i], target.vel_ned_m_s[i], target.accel_ned_m_s2[i]
        a_ff[i] = a if math.isfinite(a) else 0.0
        free = not math.isfinite(p) and not math.isfinite(v) and math.isfinite(a)
        steered[i] = not free  # an axis given nothing at all holds its speed at zero
        v_cmd[i] = (v if math.isfinite(v) else 0.0) + (gains[i] * (p - ref.pos_ned_m[i]) if math.isfinite(p) else 0.0)
    v_lim = _limit_xy_z((v_cmd[0], v_cmd[1], v_cmd[2]), lim.speed_xy_m_s, lim.speed_up_m_s, lim.speed_down_m_s)
    accel = [a_ff[i] + (lim.vel_gain * (v_lim[i] - ref.vel_ned_m_s[i]) if steered[i] else 0.0) for i in range(3)]
    a_out = _limit_xy_z((accel[0], accel[1], accel[2]), accel_xy_max_m_s2, lim.accel_up_m_s2, lim.accel_down_m_s2)
    return _no_faster(lim, ref.vel_ned_m_s, a_out, steered, dt)


def _no_faster(lim: ShapingLimits, vel: Vec3, accel: Vec3, steered: list[bool], dt: float) -> Vec3:
    """An acceleration given alone may not take the reference past the speed limits: its component
    along the motion is cut to what the jerk limit can still bring to zero before the limit
    (``v + a dt + a^2 / 2j <= v_max``, as companion.control.trajectory's reference does)."""
    a = list(accel)

    def allowed(room: float) -> float:
        j = lim.jerk_m_s3
        return j * (math.sqrt(dt * dt + 2.0 * max(room, 0.0) / j) - dt)

    free_xy = [i for i in (0, 1) if not steered[i]]
    h = math.hypot(vel[0], vel[1])
    if free_xy and h > 0.0:
        along = sum(a[i] * vel[i] for i in free_xy) / h
        excess = along - allowed(lim.speed_xy_m_s - h)
        if excess > 0.0:
            for i in free_xy:
                a[i] -= excess * vel[i] / h
    if not steered[2]:
        a[2] = min(max(a[2], -allowed(lim.speed_up_m_s + vel[2])), allowed(lim.speed_down_m_s - vel[2]))
    return (a[0], a[1], a[2])


def _yaw_step(lim: ShapingLimits, yaw: float, target: TrajectoryTarget, dt: float) -> float:
    if math.isfinite(target.yaw_rad):
        rate = lim.yaw_gain * wrap_angle(target.yaw_rad - yaw)
    elif math.isfinite(target.yaw_rate_rad_s):
        rate = target.yaw_rate_rad_s
    else:
        return yaw
    rate = min(max(rate, -lim.yaw_rate_max_rad_s), lim.yaw_rate_max_rad_s)
    return float(wrap_angle(yaw + rate * dt))


def shape_step(lim: ShapingLimits, ref: ShapedReference, target: TrajectoryTarget, dt: float,
               vehicle_pos_ned_m: Vec3 | None = None, braking: bool = False) -> ShapedReference:
    """``dt`` of the reference towards ``target``: the acceleration moves towards the cascade's command
    at no more than the jerk limit, velocity and position integrate it; with ``vehicle_pos_ned_m`` the
    reference is held within ``lead_max_m`` of it. ``braking`` (with :data:`BRAKE`) allows the
    horizontal braking limit instead of the manoeuvring one."""
    a_cmd = _commanded_accel(lim, ref, target, lim.brake_accel_xy_m_s2 if braking else lim.accel_xy_m_s2, dt)
    a0 = ref.accel_ned_m_s2
    da = (a_cmd[0] - a0[0], a_cmd[1] - a0[1], a_cmd[2] - a0[2])
    n = math.sqrt(da[0] ** 2 + da[1] ** 2 + da[2] ** 2)
    k = min(1.0, lim.jerk_m_s3 * dt / n) if n > 0.0 else 1.0
    a = (a0[0] + k * da[0], a0[1] + k * da[1], a0[2] + k * da[2])
    v0 = ref.vel_ned_m_s
    v = (v0[0] + a[0] * dt, v0[1] + a[1] * dt, v0[2] + a[2] * dt)
    p0 = ref.pos_ned_m
    p = (p0[0] + 0.5 * (v0[0] + v[0]) * dt, p0[1] + 0.5 * (v0[1] + v[1]) * dt, p0[2] + 0.5 * (v0[2] + v[2]) * dt)
    if vehicle_pos_ned_m is not None:
        p = _within(p, vehicle_pos_ned_m, lim.lead_max_m)
    return ShapedReference(p, v, a, _yaw_step(lim, ref.yaw_rad, target, dt))


def _within(p: Vec3, centre: Vec3, radius: float) -> Vec3:
    d = (p[0] - centre[0], p[1] - centre[1], p[2] - centre[2])
    n = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    if n <= radius:
        return p
    k = radius / n
    return (centre[0] + k * d[0], centre[1] + k * d[1], centre[2] + k * d[2])


def at_rest(ref: ShapedReference, speed_m_s: float = 0.05, accel_m_s2: float = 0.2) -> bool:
    """Braking is over: the reference is (almost) still."""
    v, a = ref.vel_ned_m_s, ref.accel_ned_m_s2
    return (v[0] ** 2 + v[1] ** 2 + v[2] ** 2 <= speed_m_s ** 2
            and a[0] ** 2 + a[1] ** 2 + a[2] ** 2 <= accel_m_s2 ** 2)
