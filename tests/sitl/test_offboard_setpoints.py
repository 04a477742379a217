"""OFFBOARD as PX4 v1.16 has it, in-process: entered on one fresh setpoint, and flying what
SET_POSITION_TARGET_LOCAL_NED carries (position, velocity, acceleration, in LOCAL_NED or BODY_NED), the
message read as PX4's mavlink_receiver.cpp reads it (sitl.autopilot.server.trajectory_target)."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat
from sitl.autopilot.logic import MavResult, Mode
from sitl.autopilot.server import trajectory_target
from sitl.autopilot.shaping import NAN3, TrajectoryTarget
from tests.sitl.test_autopilot import airborne, make, run

IGNORE_POS = 0b111
IGNORE_VEL = 0b111000
IGNORE_ACC = 0b111000000
IGNORE_YAW = mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
IGNORE_YAW_RATE = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE


def message(frame: int, mask: int, pos=(0.0, 0.0, 0.0), vel=(0.0, 0.0, 0.0), acc=(0.0, 0.0, 0.0), yaw=0.0,
            yaw_rate=0.0):
    mav = mavlink.MAVLink(None, srcSystem=245, srcComponent=190)
    msg = mav.set_position_target_local_ned_encode(0, 1, 1, frame, mask, *pos, *vel, *acc, yaw, yaw_rate)
    return mav.decode(bytearray(msg.pack(mav)))


# --- entering OFFBOARD ------------------------------------------------------------------------


def test_offboard_is_entered_on_a_single_fresh_setpoint_and_refused_on_a_stale_one():
    """PX4 v1.16's offboard check wants one offboard_control_mode younger than COM_OF_LOSS_T (1 s), no
    rate: one SET_ATTITUDE_TARGET then DO_SET_MODE is accepted (as PX4 v1.16 SIH accepts it); after
    1.1 s without one it is refused with PX4's reason and answer (TEMPORARILY_REJECTED, as its commander
    answers a mode whose requirements fail)."""
    ap = make()
    airborne(ap)
    assert ap.attitude_target(245, 7, quat.IDENTITY, (0.0, 0.0, 0.0), 0.33) is None
    assert ap.set_mode(Mode.OFFBOARD, sender=245).result == MavResult.ACCEPTED
    assert ap.set_mode(Mode.HOLD, sender=245).result == MavResult.ACCEPTED
    run(ap, 1.1)
    result = ap.set_mode(Mode.OFFBOARD, sender=245)
    assert result.result == MavResult.TEMPORARILY_REJECTED and result.reason == "Offboard denied: No offboard signal"
    assert ap.position_target(245, TrajectoryTarget(vel_ned_m_s=(0.0, 0.0, 0.0))) is None  # a velocity counts too
    assert ap.set_mode(Mode.OFFBOARD, sender=245).result == MavResult.ACCEPTED


def test_a_fresh_setpoint_of_another_system_does_not_let_a_third_take_offboard():
    ap = make()
    airborne(ap)
    ap.attitude_target(77, 7, quat.IDENTITY, (0.0, 0.0, 0.0), 0.33)
    assert ap.set_mode(Mode.OFFBOARD, sender=245).result != MavResult.ACCEPTED


# --- reading the message ----------------------------------------------------------------------


def test_local_ned_components_are_given_unless_their_bit_says_ignore():
    t = trajectory_target(message(mavlink.MAV_FRAME_LOCAL_NED, IGNORE_POS | IGNORE_ACC | IGNORE_YAW_RATE,
                                  vel=(1.0, 2.0, -0.5), yaw=0.7), quat.IDENTITY)
    assert isinstance(t, TrajectoryTarget)
    assert all(math.isnan(c) for c in (*t.pos_ned_m, *t.accel_ned_m_s2, t.yaw_rate_rad_s))
    assert t.vel_ned_m_s == (1.0, 2.0, -0.5) and t.yaw_rad == pytest.approx(0.7)


def test_body_ned_velocity_turns_with_the_heading_and_its_position_is_ignored():
    """MAVSDK's set_velocity_body: BODY_NED, position, acceleration and yaw ignored. Facing east, 5 m/s
    forward is 5 m/s east; the yaw rate is kept."""
    q = quat.from_yaw(math.pi / 2)
    t = trajectory_target(message(mavlink.MAV_FRAME_BODY_NED, IGNORE_POS | IGNORE_ACC | IGNORE_YAW,
                                  pos=(9.0, 9.0, 9.0), vel=(5.0, 0.0, -1.0), yaw_rate=0.5), q)
    assert isinstance(t, TrajectoryTarget)
    assert t.pos_ned_m == NAN3 or all(math.isnan(c) for c in t.pos_ned_m)
    assert t.vel_ned_m_s == pytest.approx((0.0, 5.0, -1.0), abs=1e-12)
    assert math.isnan(t.yaw_rad) and t.yaw_rate_rad_s == pytest.approx(0.5)


@pytest.mark.parametrize("frame, mask, why", [
    (mavlink.MAV_FRAME_LOCAL_OFFSET_NED, IGNORE_VEL | IGNORE_ACC, "frame 7 unsupported"),
    (mavlink.MAV_FRAME_BODY_OFFSET_NED, IGNORE_VEL | IGNORE_ACC, "frame 9 unsupported"),
    (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, IGNORE_VEL | IGNORE_ACC, "frame 3 unsupported"),
    (mavlink.MAV_FRAME_LOCAL_NED, IGNORE_POS | IGNORE_VEL | mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET,
     "force not supported"),
])
def test_what_px4_refuses_is_refused_with_its_reason(frame, mask, why):
    reason = trajectory_target(message(frame, mask), quat.IDENTITY)
    assert isinstance(reason, str) and reason.startswith(why)


def test_a_setpoint_with_nothing_in_it_or_an_absurd_value_is_rejected():
    ap = make()
    assert ap.position_target(245, TrajectoryTarget()) == "no pos, vel or accel"
    assert ap.position_target(245, TrajectoryTarget(pos_ned_m=(math.inf, 0.0, 0.0))) == "out of range"
    assert ap.position_target(245, TrajectoryTarget(vel_ned_m_s=(0.0, 1e9, 0.0))) == "out of range"


# --- flying it --------------------------------------------------------------------------------


def offboard_with(ap, target: TrajectoryTarget) -> None:
    assert ap.position_target(245, target) is None
    assert ap.set_mode(Mode.OFFBOARD, sender=245).result == MavResult.ACCEPTED


def keep_sending(ap, target: TrajectoryTarget, seconds: float) -> None:
    for _ in range(int(round(seconds / 0.05))):  # 20 Hz, as MAVSDK's offboard plugin resends
        assert ap.position_target(245, target) is None
        run(ap, 0.05)


def test_a_velocity_setpoint_is_flown_at_that_velocity():
    """2 m/s north in OFFBOARD (MAVSDK's set_velocity_ned): after 3 s the vehicle flies 2 +- 0.1 m/s north
    and holds its height within 0.15 m."""
    ap = make()
    airborne(ap)
    z0 = ap.vehicle.state.pos_ned_m[2]
    target = TrajectoryTarget(vel_ned_m_s=(2.0, 0.0, 0.0), yaw_rad=0.0)
    offboard_with(ap, target)
    keep_sending(ap, target, 3.0)
    vel = ap.vehicle.state.vel_ned_m_s
    assert vel[0] == pytest.approx(2.0, abs=0.1) and abs(vel[1]) < 0.1
    assert abs(ap.vehicle.state.pos_ned_m[2] - z0) < 0.15


def test_a_climb_velocity_is_flown_and_a_zero_velocity_stops_it():
    ap = make()
    airborne(ap)
    target = TrajectoryTarget(vel_ned_m_s=(0.0, 0.0, -1.0))
    offboard_with(ap, target)
    keep_sending(ap, target, 3.0)
    assert ap.vehicle.state.vel_ned_m_s[2] == pytest.approx(-1.0, abs=0.1)
    keep_sending(ap, TrajectoryTarget(vel_ned_m_s=(0.0, 0.0, 0.0)), 3.0)
    assert max(abs(c) for c in ap.vehicle.state.vel_ned_m_s) < 0.1


def test_position_with_velocity_feed_forward_is_flown_as_px4_adds_it():
    """MAVSDK's set_position_velocity_ned towards a point 20 m north with 4 m/s feed-forward: the vehicle
    reaches 3.5 m/s on the way (the position-only reference of the bundled HOLD is capped at 2 m/s) and,
    as on PX4 (velocity = feed-forward + MPC_XY_P x error), settles where the two cancel: 4 / 0.95 m past
    the point, within 0.2 m."""
    ap = make()
    airborne(ap)
    start = ap.vehicle.state.pos_ned_m
    goal = (start[0] + 20.0, start[1], start[2])
    target = TrajectoryTarget(pos_ned_m=goal, vel_ned_m_s=(4.0, 0.0, 0.0), yaw_rad=0.0)
    offboard_with(ap, target)
    fastest = 0.0
    for _ in range(12):
        keep_sending(ap, target, 1.0)
        fastest = max(fastest, ap.vehicle.state.vel_ned_m_s[0])
    assert fastest > 3.5
    past = (goal[0] + 4.0 / 0.95, goal[1], goal[2])
    assert math.dist(ap.vehicle.state.pos_ned_m, past) < 0.2


def test_an_acceleration_setpoint_accelerates_the_vehicle():
    """1 m/s^2 east for 2 s from a hover: 2 m/s east (less the jerk ramp's 0.06 m/s), within 0.15 m/s."""
    ap = make()
    airborne(ap)
    target = TrajectoryTarget(accel_ned_m_s2=(0.0, 1.0, 0.0), vel_ned_m_s=(math.nan, math.nan, 0.0))
    offboard_with(ap, target)
    keep_sending(ap, target, 2.0)
    assert ap.vehicle.state.vel_ned_m_s[1] == pytest.approx(2.0 - 1.0 / 16.0, abs=0.15)


def test_leaving_offboard_at_speed_brakes_and_holds():
    """Flying 3 m/s north on a velocity setpoint, then HOLD: it stops within 3^2 / (2 x 5) + 3 x 5 / 8 m
    (+1 m) and holds."""
    ap = make()
    airborne(ap)
    target = TrajectoryTarget(vel_ned_m_s=(3.0, 0.0, 0.0))
    offboard_with(ap, target)
    keep_sending(ap, target, 4.0)
    x0 = ap.vehicle.state.pos_ned_m[0]
    assert ap.set_mode(Mode.HOLD, sender=245).result == MavResult.ACCEPTED
    run(ap, 6.0)
    assert not ap.braking and ap.mode == Mode.HOLD
    assert ap.vehicle.state.pos_ned_m[0] - x0 < 9.0 / 10.0 + 15.0 / 8.0 + 1.0
    assert abs(ap.vehicle.state.vel_ned_m_s[0]) < 0.05


def test_back_to_offboard_while_braking_goes_on_from_the_braking_reference():
    """Flying 3 m/s north, HOLD for 0.3 s (braking), then OFFBOARD again with the same velocity: the
    reference goes on from where the braking left it (no jump), and the vehicle is back at 3 m/s."""
    ap = make()
    airborne(ap)
    target = TrajectoryTarget(vel_ned_m_s=(3.0, 0.0, 0.0))
    offboard_with(ap, target)
    keep_sending(ap, target, 4.0)
    ap.set_mode(Mode.HOLD, sender=245)
    keep_sending(ap, target, 0.3)
    assert ap.braking
    before = ap.shaped
    assert ap.set_mode(Mode.OFFBOARD, sender=245).result == MavResult.ACCEPTED
    assert ap.shaped == before
    run(ap, 0.01)
    assert math.dist(ap.shaped.pos_ned_m, before.pos_ned_m) < 0.05
    keep_sending(ap, target, 3.0)
    assert ap.vehicle.state.vel_ned_m_s[0] == pytest.approx(3.0, abs=0.1)
