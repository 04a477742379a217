"""ArduCopter's GUIDED attitude targets on readings built by hand: the shaping's response to a step,
the thrust a climb rate asks, the level flight after GUID_TIMEOUT."""

from __future__ import annotations

import math

import pytest

from companion.control import quaternion as quat
from companion.control.outer_loop import AttitudeSetpoint
from companion.control.params import VehicleParams
from companion.control.vector import ZERO3
from sitl.autopilot.guided import (CLIMB_RATE_MAX_M_S, ShapedAttitude, angle_boost, climb_rate_m_s, guided_target,
                                   level_keeping_altitude, shape_attitude)
from sitl.autopilot.logic import AutopilotParams
from sitl.autopilot.sensed import Sensed
from sitl.plant.sensors import ImuSample, MocapSample

DT = 1e-3
VEHICLE = VehicleParams()


def reading(q=quat.IDENTITY, v_up: float = 0.0) -> Sensed:
    return Sensed(0.0, MocapSample(0.0, ZERO3, (0.0, 0.0, -v_up), ZERO3, q), q,
                  ImuSample(ZERO3, (0.0, 0.0, -VEHICLE.gravity_m_s2)), 0.0, None)


def test_a_20_degree_step_is_shaped_to_at_most_20_deg_over_e_tc_and_reached_within_a_degree_in_7_tc():
    """Critically damped with time constant tc: the rate peaks at step / (e tc), 49 deg/s at 0.15 s."""
    tc = 0.15
    target = quat.from_euler(math.radians(20.0), 0.0, 0.0)
    s = ShapedAttitude(quat.IDENTITY, ZERO3)
    peak = 0.0
    for _ in range(round(7 * tc / DT)):
        s = shape_attitude(s, target, tc, math.radians(1100.0), DT)
        peak = max(peak, s.omega_rad_s[0])
    assert math.degrees(peak) == pytest.approx(20.0 / (math.e * tc), rel=0.02)
    assert math.degrees(quat.angle_between(s.q, target)) < 1.0


def test_thrust_is_a_climb_rate_held_by_a_vertical_speed_loop_and_divided_by_the_tilts_cosine():
    p = AutopilotParams(flavour="ardupilot", rate_ff_enabled=False)
    weight = VEHICLE.mass_kg * VEHICLE.gravity_m_s2
    assert climb_rate_m_s(0.5) == 0.0 and climb_rate_m_s(1.0) == CLIMB_RATE_MAX_M_S
    tilted = quat.from_euler(math.radians(30.0), 0.0, 0.0)
    sp, shaped = guided_target(AttitudeSetpoint(tilted, ZERO3, 0.0), None, reading(), p, VEHICLE, 0.0, DT)
    assert shaped is None and sp.q_d == tilted
    assert sp.thrust_n == pytest.approx(weight / math.cos(math.radians(30.0)))
    sp, _ = guided_target(AttitudeSetpoint(quat.IDENTITY, ZERO3, 0.0), None, reading(v_up=1.0), p, VEHICLE, 1.0, DT)
    assert sp.thrust_n == pytest.approx(weight)  # climbing as asked: no correction
    sp, _ = guided_target(AttitudeSetpoint(quat.IDENTITY, ZERO3, 0.0), None, reading(), p, VEHICLE, 100.0, DT)
    assert sp.thrust_n == VEHICLE.thrust_max_n


def test_thrust_as_throttle_is_boosted_by_the_vehicles_tilt_unless_angle_boost_is_off():
    tilted = quat.from_euler(math.radians(40.0), 0.0, 0.0)
    throttle = AutopilotParams(flavour="ardupilot", rate_ff_enabled=False, guided_thrust_is_throttle=True)
    level_2_n = AttitudeSetpoint(quat.IDENTITY, ZERO3, 2.0)
    sp, _ = guided_target(level_2_n, None, reading(tilted), throttle, VEHICLE, 0.0, DT)
    assert sp.thrust_n == pytest.approx(2.0 / math.cos(math.radians(40.0)))
    assert sp.thrust_n == pytest.approx(2.0 * angle_boost(tilted))
    plain = AutopilotParams(flavour="ardupilot", rate_ff_enabled=False, guided_thrust_is_throttle=True,
                            angle_boost=False)
    sp, _ = guided_target(level_2_n, None, reading(tilted), plain, VEHICLE, 0.0, DT)
    assert sp.thrust_n == 2.0


def test_after_guid_timeout_it_levels_at_its_yaw_and_holds_its_altitude():
    q = quat.from_euler(math.radians(25.0), 0.0, math.radians(70.0))
    sp = level_keeping_altitude(reading(q, v_up=0.5), VEHICLE)
    roll, pitch, yaw = quat.to_euler(sp.q_d)
    assert abs(roll) < 1e-12 and abs(pitch) < 1e-12 and math.degrees(yaw) == pytest.approx(70.0)
    assert sp.thrust_n == pytest.approx(VEHICLE.mass_kg * (VEHICLE.gravity_m_s2 - 1.0))  # climbing: less thrust
