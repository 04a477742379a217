"""The wire behaviours the companion relies on, asserted alike on the bundled vehicle and on the
real firmware (tests/contract/conftest.py)."""

from __future__ import annotations

import math
import time

import pytest
from pymavlink import mavutil

from companion.mavlink.modes import COPTER_MODES, px4_custom_mode

from .conftest import wait

pytestmark = [pytest.mark.integration, pytest.mark.contract]

ARMED = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED


def heartbeat(m, cond=lambda h: True, timeout: float = 10.0):
    return wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1 and h.autopilot != 8 and cond(h), timeout)


def command(m, target, cmd: int, *params: float, timeout: float = 5.0) -> int:
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(target.sysid, 1, cmd, 0, *p)
    return wait(m, "COMMAND_ACK", lambda a: a.command == cmd, timeout).result


def armable(m, timeout: float = 60.0) -> None:
    wait(m, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & mavutil.mavlink.MAV_SYS_STATUS_PREARM_CHECK,
         timeout)


# --- PX4 -------------------------------------------------------------------------------------


def test_px4_streams_attitude_and_position_before_anything_is_asked(px4):
    m = px4.connect()
    wait(m, "ATTITUDE_QUATERNION", timeout=10)
    wait(m, "LOCAL_POSITION_NED", timeout=10)


def test_px4_after_a_disarm_returns_to_the_users_mode_and_refuses_to_arm_there_without_a_stream(px4):
    """Arm in HOLD, take off, fly OFFBOARD on a stream, LAND: disarmed on the ground it reports
    OFFBOARD again, and arming there is refused with a reason."""
    m = px4.connect()
    heartbeat(m)
    armable(m)
    assert command(m, px4, 176, 1, 4, 3) == 0  # HOLD
    assert command(m, px4, 400, 1) == 0
    command(m, px4, 22, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    wait(m, "LOCAL_POSITION_NED", lambda p: p.z < -1.5, timeout=30)
    end = time.monotonic() + 1.5
    while time.monotonic() < end:  # a stream (> 2 Hz for > 1 s), level attitude, hover-ish thrust
        m.mav.set_attitude_target_send(0, px4.sysid, 1, 3, [1.0, 0, 0, 0], 0, 0, 0, 0.5)
        time.sleep(0.02)
    assert command(m, px4, 176, 1, 6, 0) == 0  # OFFBOARD
    heartbeat(m, lambda h: h.custom_mode == px4_custom_mode("OFFBOARD"))
    assert command(m, px4, 176, 1, 4, 6) == 0  # LAND (by mode)
    heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=60)
    time.sleep(0.5)
    h = heartbeat(m)
    assert h.custom_mode == px4_custom_mode("OFFBOARD"), h
    assert command(m, px4, 400, 1) != 0  # no stream in OFFBOARD: refused


def test_px4_offboard_loss_leaves_offboard_and_descends_without_holding(px4):
    """The stream stops in OFFBOARD: out of OFFBOARD within COM_OF_LOSS_T + 1 s of vehicle time, then
    it descends at once (no 5 s hold: below its altitude by 0.5 m within 2.5 s after leaving) and
    disarms on the ground."""
    m = px4.connect()
    heartbeat(m)
    armable(m)
    m.mav.param_request_read_send(px4.sysid, 1, b"COM_OF_LOSS_T", -1)
    loss_t = wait(m, "PARAM_VALUE", lambda p: p.param_id == "COM_OF_LOSS_T").param_value
    assert command(m, px4, 176, 1, 4, 3) == 0
    assert command(m, px4, 400, 1) == 0
    command(m, px4, 22, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    wait(m, "LOCAL_POSITION_NED", lambda p: p.z < -1.5, timeout=30)
    hover = 0.5
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        m.mav.set_attitude_target_send(0, px4.sysid, 1, 3, [1.0, 0, 0, 0], 0, 0, 0, hover)
        time.sleep(0.02)
    assert command(m, px4, 176, 1, 6, 0) == 0
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        m.mav.set_attitude_target_send(0, px4.sysid, 1, 3, [1.0, 0, 0, 0], 0, 0, 0, hover)
        time.sleep(0.02)
    last = wait(m, "ATTITUDE_QUATERNION").time_boot_ms * 1e-3  # the stream stops here
    heartbeat(m, lambda h: h.custom_mode != px4_custom_mode("OFFBOARD"), timeout=20)
    left = wait(m, "ATTITUDE_QUATERNION").time_boot_ms * 1e-3
    assert left - last < loss_t + 1.0, (left - last, loss_t)
    z_left = wait(m, "LOCAL_POSITION_NED").z
    t_left = left
    p = wait(m, "LOCAL_POSITION_NED", lambda p: p.time_boot_ms * 1e-3 > t_left + 2.5, timeout=20)
    assert p.z - z_left > 0.5, (z_left, p.z)  # descending, not holding
    heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=60)


def test_px4_an_attitude_with_roll_and_pitch_rates_ignored_is_flown(px4):
    """type_mask 3: the attitude (10 deg of roll) is flown; the vehicle reaches 10 +- 4 deg."""
    m = px4.connect()
    heartbeat(m)
    armable(m)
    assert command(m, px4, 176, 1, 4, 3) == 0
    assert command(m, px4, 400, 1) == 0
    command(m, px4, 22, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    wait(m, "LOCAL_POSITION_NED", lambda p: p.z < -1.5, timeout=30)
    level = [1.0, 0.0, 0.0, 0.0]
    roll = [math.cos(math.radians(5)), math.sin(math.radians(5)), 0.0, 0.0]
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        m.mav.set_attitude_target_send(0, px4.sysid, 1, 3, level, 0, 0, 0, 0.5)
        time.sleep(0.02)
    assert command(m, px4, 176, 1, 6, 0) == 0
    end = time.monotonic() + 1.0 / px4.speed * 1.5
    while time.monotonic() < end:
        m.mav.set_attitude_target_send(0, px4.sysid, 1, 3, roll, 0, 0, 0, 0.52)
        time.sleep(0.01)
    att = wait(m, "ATTITUDE")
    assert abs(math.degrees(att.roll) - 10.0) < 4.0, math.degrees(att.roll)


# --- ArduCopter ---------------------------------------------------------------------------------


def test_arducopter_starts_in_stabilize_and_sends_only_heartbeats_until_asked(copter):
    m = copter.connect()
    h = heartbeat(m, timeout=20)
    assert h.custom_mode == COPTER_MODES["STABILIZE"], h
    kinds = set()
    end = time.monotonic() + 2.0
    while time.monotonic() < end:
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is not None and msg.get_srcComponent() == 1:
            kinds.add(msg.get_type())
    assert kinds <= {"HEARTBEAT", "STATUSTEXT", "TIMESYNC", "PARAM_VALUE", "AUTOPILOT_VERSION",
                     "FILE_TRANSFER_PROTOCOL"}, kinds


def test_arducopter_has_a_position_only_once_its_ekf_has_an_origin(copter):
    """LOCAL_POSITION_NED flows only some 40 s (vehicle time) after boot: at least 20 s."""
    m = copter.connect()
    heartbeat(m, timeout=20)
    m.mav.request_data_stream_send(copter.sysid, 1, 0, 10, 1)
    first_att = wait(m, "ATTITUDE", timeout=20).time_boot_ms * 1e-3
    pos = wait(m, "LOCAL_POSITION_NED", timeout=120)
    assert pos.time_boot_ms * 1e-3 > 20.0 and pos.time_boot_ms * 1e-3 > first_att, (first_att, pos.time_boot_ms)
