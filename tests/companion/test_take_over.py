"""What ``--take-over`` does with an armed or flying vehicle, decided without a vehicle
(supervisor.take_over_refusal): only a vehicle in the air, holding still, in no failsafe or landing
mode is taken; an autopilot's failsafe in progress is never fought."""

from __future__ import annotations

import dataclasses

import pytest

from companion.flight.supervisor import STABLE_CLIMB_M_S, STABLE_SPEED_M_S, TakeOverView, take_over_refusal

HOLDING = TakeOverView(armed=True, in_air=True, on_ground=False, landed_known=True, mode="HOLD", autopilot="px4",
                       failsafe=False, has_navigation=True, vel_ned_m_s=(0.05, -0.03, 0.02))


def test_a_vehicle_holding_in_the_air_is_taken_over():
    assert take_over_refusal(HOLDING) is None
    assert take_over_refusal(dataclasses.replace(HOLDING, autopilot="ardupilot", mode="GUIDED")) is None


def test_px4s_offboard_loss_descent_is_left_to_finish():
    """PX4 v1.16 without RC (and the bundled vehicle): the heartbeat says POSCTL and MAV_STATE_CRITICAL,
    EXTENDED_SYS_STATE says LANDING, the vehicle descends at MPC_LAND_SPEED."""
    descending = dataclasses.replace(HOLDING, mode="POSCTL", failsafe=True, in_air=False, vel_ned_m_s=(0, 0, 0.7))
    assert "failsafe in progress" in take_over_refusal(descending)
    # each sign alone is enough
    assert "POSCTL" in take_over_refusal(dataclasses.replace(HOLDING, mode="POSCTL"))
    assert "taking off or landing" in take_over_refusal(dataclasses.replace(HOLDING, in_air=False))
    assert "not holding still" in take_over_refusal(dataclasses.replace(HOLDING, vel_ned_m_s=(0, 0, 0.2)))


@pytest.mark.parametrize("mode", ["LAND", "RTL", "SMART_RTL", "PRECLAND", "BRAKE"])
def test_landing_and_failsafe_modes_are_not_taken(mode):
    assert mode in take_over_refusal(dataclasses.replace(HOLDING, mode=mode, autopilot="ardupilot"))


def test_a_vehicle_armed_on_the_ground_is_not_taken_over():
    """Its take-off steps would be skipped and the controller would hold it on the ground."""
    ground = dataclasses.replace(HOLDING, in_air=False, on_ground=True, vel_ned_m_s=(0, 0, 0))
    assert "armed on the ground" in take_over_refusal(ground)


def test_a_taking_off_or_moving_vehicle_is_not_taken_over():
    assert "taking off" in take_over_refusal(dataclasses.replace(HOLDING, mode="TAKEOFF"))
    fast = dataclasses.replace(HOLDING, vel_ned_m_s=(STABLE_SPEED_M_S + 0.01, 0.0, 0.0))
    assert "not holding still" in take_over_refusal(fast)
    climbing = dataclasses.replace(HOLDING, vel_ned_m_s=(0.0, 0.0, -(STABLE_CLIMB_M_S + 0.01)))
    assert "not holding still" in take_over_refusal(climbing)


def test_without_a_position_or_a_landed_state_it_is_judged_on_what_there_is():
    assert "no position" in take_over_refusal(dataclasses.replace(HOLDING, has_navigation=False))
    unknown = dataclasses.replace(HOLDING, in_air=False, landed_known=False)  # no EXTENDED_SYS_STATE
    assert take_over_refusal(unknown) is None


def test_the_descent_bound_is_below_the_slowest_landing():
    """The bundled vehicle's MPC_LAND_SPEED floor is 0.2 m/s, PX4's MPC_LAND_CRWL default 0.3 m/s."""
    assert STABLE_CLIMB_M_S < 0.2
