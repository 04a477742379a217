"""A position mode entered at speed brakes, then holds: the bundled autopilot without sockets.

Each case flies OFFBOARD attitude setpoints (MAVSDK's offboard_attitude example among them) to a fast
climb, descent or sideways flight and then switches to HOLD, as ``offboard.stop()`` does. The braking
reference decelerates at no more than 3 m/s^2 downwards, 4 m/s^2 upwards and 5 m/s^2 horizontally,
its acceleration ramped at 8 m/s^3 (sitl.autopilot.shaping.ShapingLimits, PX4's MPC_ACC_DOWN_MAX,
MPC_ACC_UP_MAX, MPC_ACC_HOR_MAX and MPC_JERK_MAX): the bounds below follow from those figures.
"""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat
from sitl.autopilot.guard import StepGuard
from sitl.autopilot.logic import Autopilot, AutopilotParams, MavResult, Mode
from sitl.autopilot.shaping import ShapingLimits
from sitl.plant.scenario import Scenario
from sitl.plant.vehicle import SimVehicle

LIM = ShapingLimits()
HOVER = 0.63 * 9.81 / (4 * 5.72e-6 * 900.6**2)
"""normalised hover thrust of the bundled airframe (0.333)"""


def _stop_distance(speed: float, accel: float) -> float:
    """Braking from ``speed`` at ``accel`` reached after a jerk-limited ramp: the ramp (accel / jerk)
    travels at most ``speed`` for that long, the rest is v^2 / 2a."""
    return speed * speed / (2.0 * accel) + speed * accel / LIM.jerk_m_s3


def fly_then_hold(profile: list[tuple[float, float, float]], hold_s: float = 14.0):
    """Arm, OFFBOARD after one setpoint, fly ``profile`` (roll [deg], normalised thrust, seconds) at
    20 Hz as MAVSDK does, then HOLD; the vehicle's state at the switch and 100 Hz samples after it."""
    v = SimVehicle(Scenario(name="unit"), "ism_do", 1, (0.0, 0.0, 0.0), 0.0, hovering=False)
    ap = Autopilot(v, AutopilotParams())
    guard = StepGuard(ap)

    def run(seconds: float, samples: list | None = None) -> None:
        for _ in range(int(round(seconds / ap.dt))):
            guard.step()
            if samples is not None and ap._k % 10 == 0:
                s, tilt_sp = v.state, math.degrees(float(quat.tilt_angle(ap.setpoint.q_d)))
                samples.append((ap.t, tilt_sp, s.pos_ned_m, s.vel_ned_m_s))

    run(1.2)
    assert ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)).result == MavResult.ACCEPTED
    assert ap.attitude_target(255, 7, quat.IDENTITY, (0.0, 0.0, 0.0), 0.0) is None
    assert ap.set_mode(Mode.OFFBOARD).result == MavResult.ACCEPTED
    for roll_deg, thrust, seconds in profile:
        q = quat.from_euler(math.radians(roll_deg), 0.0, 0.0)
        for _ in range(int(round(seconds / 0.05))):
            assert ap.attitude_target(255, 7, q, (0.0, 0.0, 0.0), thrust) is None
            run(0.05)
    entry = (v.state.pos_ned_m, v.state.vel_ned_m_s, math.degrees(float(quat.tilt_angle(v.state.q))))
    assert ap.set_mode(Mode.HOLD).result == MavResult.ACCEPTED
    samples: list = []
    run(hold_s, samples)
    return ap, entry, samples


CASES = {
    # MAVSDK-Python's offboard_attitude: 70 % up, +-30 deg roll at 60 %, 60 % level; then offboard.stop()
    "offboard_attitude example (7.8 m/s up)": [(0, 0.7, 2), (30, 0.6, 2), (-30, 0.6, 2), (0, 0.6, 2)],
    "full-thrust climb (13.6 m/s up)": [(0, 1.0, 3.0)],
    "falling (8.7 m/s down)": [(0, 1.0, 3.0), (0, 0.6, 3.0), (0, 0.02, 3.5)],
    "sideways (9.5 m/s)": [(0, 0.7, 1.5), (0, HOVER, 1.0), (50, HOVER / math.cos(math.radians(50)), 3.0)],
    "sideways and up (13.6 m/s)": [(0, 0.7, 1.0), (40, 0.9, 2.5)],
    "sideways and down (5.7 m/s)": [(0, 1.0, 3.0), (0, 0.6, 2.0), (40, 0.15, 2.5)],
}


@pytest.mark.parametrize("profile", CASES.values(), ids=CASES.keys())
def test_hold_entered_at_speed_brakes_within_the_braking_limits_and_holds_where_it_stopped(profile):
    """GIVEN the vehicle flying fast in OFFBOARD WHEN HOLD is entered THEN no loss of control; the
    commanded tilt stays within 45 deg (PX4's MPC_TILTMAX_AIR) or the tilt it already had; it stops
    within the braking distance of its speed (+1 m for the loop's tracking) vertically and horizontally,
    within |v| / a + a / j + 2 s; and it holds the point it stopped at (the last 5 s within 0.1 m)."""
    ap, (pos0, vel0, tilt0), samples = fly_then_hold(profile)
    speed0 = math.sqrt(sum(c * c for c in vel0))
    assert speed0 > 5.0, "the case did not reach speed"
    assert ap.terminated is None and ap.armed and ap.mode == Mode.HOLD, ap.events
    assert max(s[1] for s in samples) <= max(45.0, tilt0 + 1.0)
    v_up, v_h = -vel0[2], math.hypot(vel0[0], vel0[1])
    climb = max(pos0[2] - s[2][2] for s in samples)
    sink = max(s[2][2] - pos0[2] for s in samples)
    assert climb <= (_stop_distance(v_up, LIM.accel_down_m_s2) if v_up > 0 else 0.0) + 1.0, climb
    assert sink <= (_stop_distance(-v_up, LIM.accel_up_m_s2) if v_up < 0 else 0.0) + 1.0, sink
    travel = max(math.hypot(s[2][0] - pos0[0], s[2][1] - pos0[1]) for s in samples)
    assert travel <= _stop_distance(v_h, LIM.brake_accel_xy_m_s2) + 1.0, travel
    t0 = samples[0][0]
    stopped = next(s[0] for s in samples if math.sqrt(sum(c * c for c in s[3])) < 0.2 and s[0] > t0 + 0.5)
    assert stopped - t0 <= speed0 / LIM.accel_down_m_s2 + LIM.accel_up_m_s2 / LIM.jerk_m_s3 + 2.0, stopped - t0
    rest = [s[2] for s in samples if s[0] > samples[-1][0] - 5.0]
    assert max(math.dist(p, rest[0]) for p in rest) < 0.1
    assert not ap.braking


def test_the_offboard_loss_failsafe_entered_in_a_fast_climb_brakes_before_it_descends():
    """The offboard_attitude example's climb, then its stream stops: the failsafe's LAND brakes first
    (no loss of control) and the vehicle is descending 12 s later, far above MPC_LAND_ALT1, at
    MPC_Z_VEL_MAX_DN (1.5 m/s) as PX4 does."""
    v = SimVehicle(Scenario(name="unit"), "ism_do", 1, (0.0, 0.0, 0.0), 0.0, hovering=False)
    ap = Autopilot(v, AutopilotParams())
    guard = StepGuard(ap)
    for _ in range(1200):
        guard.step()
    ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,))
    ap.attitude_target(255, 7, quat.IDENTITY, (0.0, 0.0, 0.0), 0.7)
    assert ap.set_mode(Mode.OFFBOARD).result == MavResult.ACCEPTED
    for _ in range(40):
        ap.attitude_target(255, 7, quat.IDENTITY, (0.0, 0.0, 0.0), 0.7)
        for _ in range(50):
            guard.step()
    assert v.state.vel_ned_m_s[2] < -6.0
    for _ in range(12_000):
        guard.step()
    assert ap.terminated is None and ap.mode == Mode.LAND
    assert v.state.pos_ned_m[2] < -15.0 and v.state.vel_ned_m_s[2] == pytest.approx(1.5, abs=0.1)


def test_land_descends_at_px4s_speeds_for_the_height():
    """LAND from 20 m: 1.5 m/s (MPC_Z_VEL_MAX_DN) above 10 m (MPC_LAND_ALT1), 0.7 m/s (MPC_LAND_SPEED) below
    5 m (MPC_LAND_ALT2), in between interpolated (1.1 m/s at 7.5 m); each within 0.1 m/s, then disarmed."""
    ap, _, _ = fly_then_hold([(0, 0.7, 2.0)], hold_s=6.0)
    guard = StepGuard(ap)
    assert ap.set_mode(Mode.LAND).result == MavResult.ACCEPTED
    seen: dict[float, float] = {}
    for _ in range(60_000):
        guard.step()
        height = -ap.vehicle.state.pos_ned_m[2]
        for mark in (15.0, 7.5, 3.0):
            if mark not in seen and height < mark:
                seen[mark] = ap.vehicle.state.vel_ned_m_s[2]
        if not ap.armed:
            break
    assert seen[15.0] == pytest.approx(1.5, abs=0.1)
    assert seen[7.5] == pytest.approx(1.1, abs=0.1)
    assert seen[3.0] == pytest.approx(0.7, abs=0.1)
    assert not ap.armed and ap.terminated is None
