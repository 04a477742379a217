"""Velocity-limited position and yaw references between waypoints (the filtered reference of E4).

The paper generates velocity and acceleration "by filtering the position between waypoints".
:class:`ReferenceFilter` is a critically damped second-order filter on the target position
whose jerk, acceleration and speed are limited in norm, so a jump to the next waypoint becomes
a smooth reference with ``|v| <= max_speed_m_s``; yaw follows a rate-limited first-order filter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

from .jit import jitable
from .params import TrajectoryParams
from .vector import (
    ZERO3,
    Real,
    Vec3,
    atan2,
    clip,
    clip_norm,
    cos,
    dot,
    maximum,
    norm,
    sin,
    sqrt,
    sub,
)

__all__ = ["PositionReference", "ReferenceFilter", "wrap_angle", "TrajectoryConst", "ReferenceState",
           "reference_filter_step"]


class PositionReference(NamedTuple):
    """Desired position, velocity and acceleration (NED) and yaw about the inertial z axis."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3 = ZERO3
    accel_ned_m_s2: Vec3 = ZERO3
    yaw_rad: Real = 0.0


@jitable
def wrap_angle(angle_rad: Real) -> Real:
    """Angle wrapped to (-pi, pi]."""
    return atan2(sin(angle_rad), cos(angle_rad))


@jitable
def _approach_speed_limit(accel: Vec3, vel: Vec3, max_speed: float, max_jerk: float, dt_s: float) -> Vec3:
    """``accel`` with its component along the velocity no larger than the jerk limit can still
    bring to zero before the speed reaches its limit: ``v + a dt + a^2 / (2 j) <= v_max`` (this
    step, then the ramp down). Without it the speed limit cut the acceleration in one step (E4:
    6 m/s^2 to 0, a 33 deg jump of the attitude reference, 357 deg/s of body rate behind a
    250 deg/s command)."""
    speed = norm(vel)
    if not speed > 1e-9:
        return accel
    along = dot(accel, vel) / speed
    room = maximum(max_speed - speed, 0.0)
    allowed = max_jerk * (sqrt(dt_s * dt_s + 2.0 * room / max_jerk) - dt_s)
    excess = maximum(along - allowed, 0.0) / speed
    return (accel[0] - excess * vel[0], accel[1] - excess * vel[1], accel[2] - excess * vel[2])


class TrajectoryConst(NamedTuple):
    """:class:`~companion.control.params.TrajectoryParams` as a tuple (the same field names), for
    compiled code; :func:`reference_filter_step` takes either."""

    max_speed_m_s: float
    max_accel_m_s2: float
    max_jerk_m_s3: float
    bandwidth_rad_s: float
    max_yaw_rate_rad_s: float

    @staticmethod
    def of(p: TrajectoryParams) -> TrajectoryConst:
        return TrajectoryConst(p.max_speed_m_s, p.max_accel_m_s2, p.max_jerk_m_s3, p.bandwidth_rad_s,
                               p.max_yaw_rate_rad_s)


class ReferenceState(NamedTuple):
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    accel_ned_m_s2: Vec3
    yaw_rad: Real


REFERENCE_SUBSTEP_S = 0.02
"""the longest step the filter integrates at once: a longer ``dt_s`` is split into equal sub-steps.
At 10 Hz with a 5 rad/s bandwidth (w dt = 0.5) the speed limit made the vertical velocity
limit-cycle (+-0.05 m/s) on a horizontal leg and the reference crept up 3 cm in 10 s, out of a
volume whose ceiling the mission flew at (found by tests/fuzz); in 20 ms steps it does not. Loops at
50 Hz and faster take one step, as before. A jerk limit high for the speed limit shortens the
sub-step further (:func:`reference_substep_s`)."""

SUBSTEP_SPEED_FRACTION = 0.5
"""the most of the speed limit one sub-step's jerk may change the velocity by (``j h^2``)"""


@jitable
def reference_substep_s(p: TrajectoryParams | TrajectoryConst) -> float:
    """The longest sub-step [s] the filter takes: :data:`REFERENCE_SUBSTEP_S`, or shorter where the
    jerk limit could swing the velocity by more than half the speed limit in one (``j h^2 <= v_max / 2``).
    A 0.1 m/s limit with a 500 m/s^3 jerk limit in 20 ms steps (10 m/s^2 of acceleration a step,
    0.2 m/s of velocity) made the velocity chatter at its limit on a 10 m horizontal leg and the
    reference climbed 0.37 m while its target was 0.19 m below (found by tests/fuzz); in 10 ms
    steps it does not."""
    return min(REFERENCE_SUBSTEP_S, math.sqrt(SUBSTEP_SPEED_FRACTION * p.max_speed_m_s / p.max_jerk_m_s3))


@jitable
def reference_filter_step(p: TrajectoryParams | TrajectoryConst, st: ReferenceState, target_ned_m: Vec3,
                          target_yaw_rad: Real, dt_s: float) -> ReferenceState:
    """``dt_s`` of the limited, critically damped filter towards ``target_ned_m`` and yaw, in
    equal sub-steps of at most :func:`reference_substep_s`."""
    longest = reference_substep_s(p)
    n = 1
    while dt_s > n * longest * (1.0 + 1e-9):
        n += 1
    h = dt_s / n
    for _ in range(n):
        st = _reference_substep(p, st, target_ned_m, target_yaw_rad, h)
    return st


@jitable
def _reference_substep(p: TrajectoryParams | TrajectoryConst, st: ReferenceState, target_ned_m: Vec3,
                       target_yaw_rad: Real, dt_s: float) -> ReferenceState:
    """One step of the limited, critically damped filter towards ``target_ned_m`` and yaw."""
    w = p.bandwidth_rad_s
    d = sub(target_ned_m, st.pos_ned_m)
    v = st.vel_ned_m_s
    a_cmd = clip_norm(
        (w * w * d[0] - 2.0 * w * v[0], w * w * d[1] - 2.0 * w * v[1], w * w * d[2] - 2.0 * w * v[2]),
        p.max_accel_m_s2,
    )
    a_cmd = _approach_speed_limit(a_cmd, v, p.max_speed_m_s, p.max_jerk_m_s3, dt_s)
    a0 = st.accel_ned_m_s2
    da = clip_norm((a_cmd[0] - a0[0], a_cmd[1] - a0[1], a_cmd[2] - a0[2]), p.max_jerk_m_s3 * dt_s)
    a_cmd = (a0[0] + da[0], a0[1] + da[1], a0[2] + da[2])
    v_new = clip_norm((v[0] + a_cmd[0] * dt_s, v[1] + a_cmd[1] * dt_s, v[2] + a_cmd[2] * dt_s), p.max_speed_m_s)
    accel = ((v_new[0] - v[0]) / dt_s, (v_new[1] - v[1]) / dt_s, (v_new[2] - v[2]) / dt_s)
    r = st.pos_ned_m
    h = 0.5 * dt_s
    pos = (r[0] + h * (v[0] + v_new[0]), r[1] + h * (v[1] + v_new[1]), r[2] + h * (v[2] + v_new[2]))
    yaw_step = clip(w * wrap_angle(target_yaw_rad - st.yaw_rad), -p.max_yaw_rate_rad_s, p.max_yaw_rate_rad_s)
    return ReferenceState(pos, v_new, accel, wrap_angle(st.yaw_rad + yaw_step * dt_s))


@dataclass
class ReferenceFilter:
    """Smooth reference towards a target position and yaw; start it where the vehicle is.

    A wrapper around :func:`reference_filter_step`."""

    params: TrajectoryParams
    pos_ned_m: Vec3
    yaw_rad: Real = 0.0
    vel_ned_m_s: Vec3 = ZERO3
    accel_ned_m_s2: Vec3 = field(default=ZERO3)

    def update(self, target_ned_m: Vec3, target_yaw_rad: Real, dt_s: float) -> PositionReference:
        st = reference_filter_step(self.params,
                                   ReferenceState(self.pos_ned_m, self.vel_ned_m_s, self.accel_ned_m_s2, self.yaw_rad),
                                   target_ned_m, target_yaw_rad, dt_s)
        self.pos_ned_m, self.vel_ned_m_s, self.accel_ned_m_s2, self.yaw_rad = st
        return PositionReference(st.pos_ned_m, st.vel_ned_m_s, st.accel_ned_m_s2, st.yaw_rad)
