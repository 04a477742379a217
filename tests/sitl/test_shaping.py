"""The reference shaped from trajectory setpoints and for braking (sitl.autopilot.shaping), alone."""

from __future__ import annotations

import math

import pytest

from companion.control.vector import ZERO3
from sitl.autopilot.shaping import (BRAKE, NAN3, ShapedReference, ShapingLimits, TrajectoryTarget, at_rest,
                                    body_to_ned, shape_step)

LIM = ShapingLimits()
DT = 0.01
NAN = math.nan


def run(target, seconds, ref=None, lim=LIM, braking=False):
    ref = ref or ShapedReference(ZERO3, ZERO3, ZERO3, 0.0)
    out = [ref]
    for _ in range(int(round(seconds / DT))):
        ref = shape_step(lim, ref, target, DT, braking=braking)
        out.append(ref)
    return out


def speeds(refs, axes=(0, 1, 2)):
    return [math.sqrt(sum(r.vel_ned_m_s[i] ** 2 for i in axes)) for r in refs]


def test_a_velocity_step_is_reached_without_overshoot_within_the_acceleration_and_jerk_limits():
    """2 m/s north from rest: at most 3 m/s^2 (MPC_ACC_HOR), the acceleration changing by at most 8 m/s^3
    (MPC_JERK_MAX); 2 m/s reached to 1 % within 2 / 3 + 3 / 8 + 3 time constants of the 2 /s loop, never
    exceeded."""
    refs = run(TrajectoryTarget(vel_ned_m_s=(2.0, 0.0, 0.0)), 4.0)
    acc = [r.accel_ned_m_s2[0] for r in refs]
    assert max(acc) <= LIM.accel_xy_m_s2 + 1e-9
    assert max(abs(b - a) for a, b in zip(acc, acc[1:])) <= LIM.jerk_m_s3 * DT + 1e-9
    v = [r.vel_ned_m_s[0] for r in refs]
    assert max(v) <= 2.0 + 1e-9
    reach = 2.0 / LIM.accel_xy_m_s2 + LIM.accel_xy_m_s2 / LIM.jerk_m_s3 + 3.0 / LIM.vel_gain
    assert v[int(reach / DT)] > 0.99 * 2.0
    assert all(abs(r.vel_ned_m_s[1]) < 1e-12 and abs(r.vel_ned_m_s[2]) < 1e-12 for r in refs)


@pytest.mark.parametrize("target, axes, limit", [
    ((100.0, 0.0, 0.0), (0, 1), LIM.speed_xy_m_s),
    ((0.0, 0.0, -100.0), (2,), LIM.speed_up_m_s),
    ((0.0, 0.0, 100.0), (2,), LIM.speed_down_m_s),
], ids=["north", "up", "down"])
def test_a_far_position_is_approached_at_the_speed_limits(target, axes, limit):
    """100 m away: the reference's speed settles at MPC_XY_VEL_MAX (ours 5 m/s), MPC_Z_VEL_MAX_UP (3) or
    _DN (1.5) and never exceeds it."""
    refs = run(TrajectoryTarget(pos_ned_m=target), 10.0)
    s = speeds(refs, axes)
    assert max(s) <= limit + 1e-9 and s[-1] > 0.99 * limit


def test_position_with_velocity_feed_forward_follows_a_moving_setpoint_without_lag():
    """A setpoint moving north at 1 m/s, sent with its velocity (MAVSDK's set_position_velocity_ned):
    after 6 s the reference is on it within 1 cm. Without the feed-forward it trails by v / MPC_XY_P."""
    def follow(with_velocity: bool) -> float:
        ref = ShapedReference(ZERO3, (1.0, 0.0, 0.0), ZERO3, 0.0)
        for k in range(600):
            t = k * DT
            vel = (1.0, 0.0, 0.0) if with_velocity else NAN3
            ref = shape_step(LIM, ref, TrajectoryTarget(pos_ned_m=(t, 0.0, 0.0), vel_ned_m_s=vel), DT)
        return 6.0 - DT - ref.pos_ned_m[0]

    assert abs(follow(True)) < 0.01
    assert follow(False) == pytest.approx(1.0 / LIM.pos_gain_xy, rel=0.05)


def test_an_acceleration_alone_is_flown_until_the_speed_limit():
    """1 m/s^2 east, nothing else: the speed grows at 1 m/s^2 (after the jerk ramp) and stops at 5 m/s."""
    refs = run(TrajectoryTarget(accel_ned_m_s2=(0.0, 1.0, 0.0)), 8.0)
    v = [r.vel_ned_m_s[1] for r in refs]
    assert v[200] == pytest.approx(2.0 - 0.5 * 1.0 / LIM.jerk_m_s3, abs=0.01)  # 2 s in, less the ramp's lag
    assert max(v) <= LIM.speed_xy_m_s + LIM.accel_xy_m_s2 * DT and v[-1] > 0.99 * LIM.speed_xy_m_s


def test_braking_from_speed_decelerates_within_the_braking_limits_and_comes_to_rest():
    """From 10 m/s north and 8 m/s up: decelerations within 5 m/s^2 horizontally and 3 m/s^2 downwards,
    at rest within 10 / 5 + 8 / 3 s and the ramps (the slower axis sets the pace), then at_rest."""
    start = ShapedReference(ZERO3, (10.0, 0.0, -8.0), ZERO3, 0.3)
    refs = run(BRAKE, 8.0, start, braking=True)
    assert max(math.hypot(r.accel_ned_m_s2[0], r.accel_ned_m_s2[1]) for r in refs) <= LIM.brake_accel_xy_m_s2 + 1e-9
    assert max(r.accel_ned_m_s2[2] for r in refs) <= LIM.accel_down_m_s2 + 1e-9
    rest = next(i for i, r in enumerate(refs) if at_rest(r)) * DT
    assert rest < 8.0 / LIM.accel_down_m_s2 + 2 * LIM.accel_down_m_s2 / LIM.jerk_m_s3 + 3.0 / LIM.vel_gain
    assert all(r.yaw_rad == 0.3 for r in refs)  # the heading is held


def test_a_yaw_rate_turns_the_reference_and_a_yaw_is_approached_at_most_at_the_yaw_rate_limit():
    turned = run(TrajectoryTarget(vel_ned_m_s=ZERO3, yaw_rate_rad_s=math.radians(30.0)), 2.0)[-1]
    assert turned.yaw_rad == pytest.approx(math.radians(60.0), abs=1e-6)
    facing = run(TrajectoryTarget(vel_ned_m_s=ZERO3, yaw_rad=math.radians(170.0)), 1.0)[-1]
    assert facing.yaw_rad == pytest.approx(LIM.yaw_rate_max_rad_s * 1.0, abs=1e-6)


def test_body_velocities_are_rotated_by_the_heading():
    east = body_to_ned((5.0, 0.0, -1.0), math.pi / 2)
    assert east == pytest.approx((0.0, 5.0, -1.0), abs=1e-12)


def test_the_reference_is_held_near_a_vehicle_that_cannot_follow():
    """A vehicle stuck at the origin: the reference of a 5 m/s velocity stays within lead_max_m of it."""
    ref = ShapedReference(ZERO3, ZERO3, ZERO3, 0.0)
    for _ in range(1000):
        ref = shape_step(LIM, ref, TrajectoryTarget(vel_ned_m_s=(5.0, 0.0, 0.0)), DT, vehicle_pos_ned_m=ZERO3)
    assert math.dist(ref.pos_ned_m, ZERO3) == pytest.approx(LIM.lead_max_m)
