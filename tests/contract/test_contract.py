"""The wire behaviours the companion relies on, asserted alike on the bundled vehicle and on the
real firmware (tests/contract/conftest.py)."""

from __future__ import annotations

import math
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.commands import FORCE_ARM_DISARM
from companion.mavlink.setpoints import RATES_IGNORED, ROLL_PITCH_RATES_IGNORED
from companion.mavlink.modes import COPTER_MODES, PX4_MODES, px4_custom_mode

from .conftest import SPEED, latest, stream, stream_until, wait

pytestmark = [pytest.mark.integration, pytest.mark.contract]

ARMED = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED


def heartbeat(m, cond=lambda h: True, timeout: float = 10.0):
    return wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1 and h.autopilot != 8 and cond(h), timeout)


def command(m, target, cmd: int, *params: float, attempts: int = 4, timeout: float = 1.5) -> int:
    """COMMAND_LONG as MAVLink's command protocol sends it: again, with the confirmation counted up,
    when no ACK came within ``timeout`` (a Python reader on a busy host can fall behind the telemetry
    and the kernel drops what comes after, an ACK among it)."""
    p = list(params) + [0.0] * (7 - len(params))
    for confirmation in range(attempts):
        m.mav.command_long_send(target.sysid, 1, cmd, confirmation, *p)
        try:
            return wait(m, "COMMAND_ACK", lambda a: a.command == cmd, timeout).result
        except AssertionError:
            continue
    raise AssertionError(f"no COMMAND_ACK for command {cmd} after {attempts} attempts of {timeout} s")


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
    # a stream (> 2 Hz for > 1 s), level attitude, hover-ish thrust, kept up while switching: a
    # busy host can delay the switch past the stream's timeout if the stream stops first
    stream(m, px4.sysid, 1.5, (1.0, 0, 0, 0), 0.5)
    m.mav.command_long_send(px4.sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                            *PX4_MODES["OFFBOARD"], 0, 0, 0, 0)  # OFFBOARD
    _stream_until_mode(m, px4, "OFFBOARD")
    m.mav.command_long_send(px4.sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                            *PX4_MODES["LAND"], 0, 0, 0, 0)  # LAND (by mode), still streaming:
    _stream_until_mode(m, px4, "LAND")  # an offboard-loss failsafe first would be another test
    heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=60)
    time.sleep(0.5)
    h = heartbeat(m)
    assert h.custom_mode == px4_custom_mode("OFFBOARD"), h
    assert command(m, px4, 400, 1) != 0  # no stream in OFFBOARD: refused


def _stream_until_mode(m, px4, mode: str, timeout: float = 10.0) -> None:
    """Level setpoints at 50 Hz of wall time, reading between them, until a heartbeat says ``mode``."""
    def in_mode(msg) -> bool:
        return (msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 1
                and msg.custom_mode == px4_custom_mode(mode))

    assert stream_until(m, px4.sysid, (1.0, 0, 0, 0), 0.5, in_mode, timeout), f"not in {mode} within {timeout} s"


def _airborne_in_offboard(m, px4, hover: float | None = None) -> None:
    """Taken off, then in OFFBOARD on a level attitude at the vehicle's own hover thrust (MPC_THR_HOVER:
    SIH's 0.5 is a 4.9 m/s^2 climb on the bundled vehicle, whose hover is 0.33)."""
    heartbeat(m)
    if hover is None:
        m.mav.param_request_read_send(px4.sysid, 1, b"MPC_THR_HOVER", -1)
        hover = wait(m, "PARAM_VALUE", lambda p: p.param_id == "MPC_THR_HOVER").param_value
    armable(m)
    assert command(m, px4, 176, 1, 4, 3) == 0
    assert command(m, px4, 400, 1) == 0
    command(m, px4, 22, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    wait(m, "LOCAL_POSITION_NED", lambda p: p.z < -1.5, timeout=30)
    stream(m, px4.sysid, 1.5, (1.0, 0, 0, 0), hover)
    m.mav.command_long_send(px4.sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                            *PX4_MODES["OFFBOARD"], 0, 0, 0, 0)
    stream(m, px4.sysid, 0.5, (1.0, 0, 0, 0), hover)
    assert latest(m, "HEARTBEAT").custom_mode == px4_custom_mode("OFFBOARD") or heartbeat(
        m, lambda h: h.custom_mode == px4_custom_mode("OFFBOARD"))


def test_px4_offboard_loss_leaves_offboard_and_descends_without_holding(px4):
    """The stream stops in OFFBOARD: out of OFFBOARD within COM_OF_LOSS_T + 1.5 s of vehicle time (a
    1 Hz heartbeat), then it descends at once (no 5 s hold: 0.5 m below within 3 s after leaving)
    and disarms on the ground."""
    m = px4.connect()
    heartbeat(m)
    m.mav.param_request_read_send(px4.sysid, 1, b"COM_OF_LOSS_T", -1)
    loss_t = wait(m, "PARAM_VALUE", lambda p: p.param_id == "COM_OF_LOSS_T").param_value
    _airborne_in_offboard(m, px4)
    last = latest(m, "ATTITUDE_QUATERNION").time_boot_ms * 1e-3  # the stream stops here
    heartbeat(m, lambda h: h.custom_mode != px4_custom_mode("OFFBOARD"), timeout=20)
    left = latest(m, "ATTITUDE_QUATERNION").time_boot_ms * 1e-3
    assert left - last < loss_t + 1.5, (left - last, loss_t)
    z_left = latest(m, "LOCAL_POSITION_NED").z
    p = wait(m, "LOCAL_POSITION_NED", lambda p: p.time_boot_ms * 1e-3 > left + 3.0, timeout=20)
    assert p.z - z_left > 0.5, (z_left, p.z)  # descending, not holding
    heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=60)


def test_px4_an_attitude_with_roll_and_pitch_rates_ignored_is_flown(px4):
    """type_mask 3: the attitude (10 deg of roll) is flown; after 1 s of vehicle time the vehicle is at
    10 +- 4 deg (PX4's attitude loop: ~0.2 s to settle)."""
    m = px4.connect()
    _airborne_in_offboard(m, px4)
    roll = (math.cos(math.radians(5)), math.sin(math.radians(5)), 0.0, 0.0)
    stream(m, px4.sysid, 1.0 / px4.speed, roll, 0.52)
    m.mav.set_attitude_target_send(0, px4.sysid, 1, ROLL_PITCH_RATES_IGNORED, list(roll), 0, 0, 0, 0.52)
    att = latest(m, "ATTITUDE")
    assert abs(math.degrees(att.roll) - 10.0) < 4.0, math.degrees(att.roll)


def _vehicle_seconds_pass(m, seconds: float) -> None:
    """Read until the autopilot's own stamps have advanced by ``seconds`` (a busy host slows the vehicle)."""
    t0 = latest(m, "ATTITUDE").time_boot_ms
    wait(m, "ATTITUDE", lambda a: a.time_boot_ms > t0 + seconds * 1e3, timeout=seconds / SPEED + 20.0)


def _mode_command_once(m, target, mode: str, timeout: float = 5.0) -> int:
    """One DO_SET_MODE, the worst of its ACKs' results; not retried (a retry would come after the
    setpoint went stale). PX4 v1.16 answers DO_SET_MODE twice, and a refused OFFBOARD comes as
    ACCEPTED then TEMPORARILY_REJECTED (measured on SIH): every ACK within 0.5 s of the first counts."""
    main, sub = px4_custom_mode(mode) >> 16 & 0xFF, px4_custom_mode(mode) >> 24
    m.mav.command_long_send(target.sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0,
                            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub, 0, 0, 0, 0)
    results = [wait(m, "COMMAND_ACK", lambda a: a.command == mavlink.MAV_CMD_DO_SET_MODE, timeout).result]
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
        if ack is not None and ack.command == mavlink.MAV_CMD_DO_SET_MODE:
            results.append(ack.result)
    return max(results)


def test_px4_takes_offboard_on_one_fresh_setpoint_and_rejects_it_on_a_stale_one(px4):
    """PX4 v1.16's offboard check (commander offboardCheck.cpp) wants one offboard_control_mode younger
    than COM_OF_LOSS_T and no rate. Armed in HOLD on the ground: one SET_ATTITUDE_TARGET, COM_OF_LOSS_T +
    0.5 s of vehicle time with nothing more, DO_SET_MODE offboard -> TEMPORARILY_REJECTED (its answer to a
    mode whose requirement fails); then one SET_ATTITUDE_TARGET and at once DO_SET_MODE offboard ->
    ACCEPTED (what MAVSDK's offboard.start() does after a single set_attitude)."""
    m = px4.connect()
    heartbeat(m)
    m.mav.param_request_read_send(px4.sysid, 1, b"COM_OF_LOSS_T", -1)
    loss_t = wait(m, "PARAM_VALUE", lambda p: p.param_id == "COM_OF_LOSS_T").param_value
    armable(m)
    assert command(m, px4, 176, 1, 4, 3) == 0  # HOLD
    assert command(m, px4, 400, 1) == 0
    level = [1.0, 0.0, 0.0, 0.0]
    m.mav.set_attitude_target_send(0, px4.sysid, 1, RATES_IGNORED, level, 0, 0, 0, 0.0)
    # the vehicle answers in order, so once it answers this it has read the setpoint: the clock starts
    # there, not when it was sent (on a busy host the bundled vehicle at 4x read one 0.5 s of its time
    # late, and the setpoint was still fresh when it should have been stale)
    m.mav.param_request_read_send(px4.sysid, 1, b"COM_OF_LOSS_T", -1)
    wait(m, "PARAM_VALUE", lambda p: p.param_id == "COM_OF_LOSS_T")
    _vehicle_seconds_pass(m, loss_t + 0.5)
    assert _mode_command_once(m, px4, "OFFBOARD") == mavutil.mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    m.mav.set_attitude_target_send(0, px4.sysid, 1, RATES_IGNORED, level, 0, 0, 0, 0.0)
    assert _mode_command_once(m, px4, "OFFBOARD") == mavutil.mavlink.MAV_RESULT_ACCEPTED
    m.mav.command_long_send(px4.sysid, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                            0, FORCE_ARM_DISARM, 0, 0, 0, 0, 0)  # disarm on the ground


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
    m.mav.request_data_stream_send(copter.sysid, 1, mavlink.MAV_DATA_STREAM_ALL, 10, 1)
    first_att = wait(m, "ATTITUDE", timeout=20).time_boot_ms * 1e-3
    pos = wait(m, "LOCAL_POSITION_NED", timeout=120)
    assert pos.time_boot_ms * 1e-3 > 20.0 and pos.time_boot_ms * 1e-3 > first_att, (first_att, pos.time_boot_ms)


def _guided_airborne(m, copter) -> None:
    """GUIDED, armed, 2 m up, thrust as throttle (GUID_OPTIONS bit 3), streams on."""
    heartbeat(m, timeout=20)
    m.mav.request_data_stream_send(copter.sysid, 1, mavlink.MAV_DATA_STREAM_ALL, 20, 1)
    wait(m, "LOCAL_POSITION_NED", timeout=120)
    armable(m, timeout=60)
    m.mav.param_set_send(copter.sysid, 1, b"GUID_OPTIONS", 8, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
    wait(m, "PARAM_VALUE", lambda p: p.param_id == "GUID_OPTIONS")
    assert command(m, copter, 176, 1, COPTER_MODES["GUIDED"]) == 0
    end = time.monotonic() + 20
    while command(m, copter, 400, 1) != 0:  # its pre-arm checks may settle a little later
        assert time.monotonic() < end, "never armed"
        time.sleep(0.5)
    assert command(m, copter, 22, 0, 0, 0, 0, 0, 0, 2.0) == 0
    wait(m, "LOCAL_POSITION_NED", lambda p: p.z < -1.8, timeout=60)


def _hover_throttle(m, copter) -> float:
    m.mav.param_request_read_send(copter.sysid, 1, b"MOT_THST_HOVER", -1)
    return wait(m, "PARAM_VALUE", lambda p: p.param_id == "MOT_THST_HOVER").param_value


def test_arducopter_learns_its_hover_throttle_in_flight_from_a_stale_value(copter):
    """MOT_THST_HOVER at boot is ArduCopter SITL's saved 0.35, about 5 % below the throttle that
    hovers; MOT_HOVER_LEARN 2 learns it in level flight with a 10 s time constant. After 30 s of
    vehicle time hovering in GUIDED (2 time constants and more since take-off) it has come up by at
    least 3 % of its boot value and by no more than 15 % (ArduCopter 4.8 SITL: 0.350 to 0.367)."""
    m = copter.connect()
    heartbeat(m, timeout=20)
    at_boot = _hover_throttle(m, copter)
    _guided_airborne(m, copter)
    t0 = latest(m, "LOCAL_POSITION_NED").time_boot_ms * 1e-3
    wait(m, "LOCAL_POSITION_NED", lambda p: p.time_boot_ms * 1e-3 > t0 + 30.0, timeout=30.0 / copter.speed + 20)
    learnt = _hover_throttle(m, copter)
    assert 1.03 * at_boot < learnt < 1.15 * at_boot, (at_boot, learnt)


def test_arducopter_guided_flies_an_attitude_target_beyond_its_angle_limit(copter):
    """A 40 deg roll target in GUIDED (the angle limit is 30 deg): flown past 35 deg, not clipped."""
    m = copter.connect()
    _guided_airborne(m, copter)
    hover = _hover_throttle(m, copter)
    q = (math.cos(math.radians(20)), math.sin(math.radians(20)), 0.0, 0.0)
    stream(m, copter.sysid, 1.5 / copter.speed, q, min(hover / math.cos(math.radians(40)), 0.9),
           type_mask=RATES_IGNORED)
    m.mav.set_attitude_target_send(0, copter.sysid, 1, RATES_IGNORED, list(q), 0, 0, 0, hover)
    att = latest(m, "ATTITUDE")
    assert math.degrees(att.roll) > 35.0, math.degrees(att.roll)


def test_arducopter_levels_after_guid_timeout_and_stays_in_guided(copter):
    """The targets (15 deg of roll) stop: after GUID_TIMEOUT (3 s) and 1 s more of vehicle time it is
    level (< 3 deg), armed, in GUIDED."""
    m = copter.connect()
    _guided_airborne(m, copter)
    hover = _hover_throttle(m, copter)
    q = (math.cos(math.radians(7.5)), math.sin(math.radians(7.5)), 0.0, 0.0)
    stream(m, copter.sysid, 1.0 / copter.speed, q, hover, type_mask=RATES_IGNORED)
    t0 = latest(m, "ATTITUDE").time_boot_ms * 1e-3
    att = wait(m, "ATTITUDE", lambda a: a.time_boot_ms * 1e-3 > t0 + 4.0, timeout=30)
    assert abs(math.degrees(att.roll)) < 3.0, math.degrees(att.roll)
    h = latest(m, "HEARTBEAT")
    assert h.custom_mode == COPTER_MODES["GUIDED"] and h.base_mode & ARMED


def _set_param(m, copter, name: str, value: float) -> None:
    m.mav.param_set_send(copter.sysid, 1, name.encode(), value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
    wait(m, "PARAM_VALUE", lambda p: p.param_id == name and abs(p.param_value - value) < 1e-6)


def _fly_and_record(m, copter, vehicle_s: float, q, thrust: float) -> list:
    """SET_ATTITUDE_TARGET (attitude and throttle, rates ignored) at 50 Hz of wall time until the
    vehicle's own stamps have advanced by ``vehicle_s`` (a busy host slows the vehicle: a window in
    wall time would hold less flight); every ATTITUDE and LOCAL_POSITION_NED of the autopilot meanwhile."""
    seen: list = []

    def record(msg) -> bool:
        if msg.get_srcComponent() == 1 and msg.get_type() in ("ATTITUDE", "LOCAL_POSITION_NED"):
            seen.append(msg)
        return bool(seen) and seen[-1].time_boot_ms - seen[0].time_boot_ms >= vehicle_s * 1e3

    flown = stream_until(m, copter.sysid, q, thrust, record, 5.0 * vehicle_s / copter.speed + 10.0,
                         type_mask=RATES_IGNORED)
    assert flown, f"the vehicle did not fly {vehicle_s} s within the wall time allowed"
    return seen


def _lean_with(m, copter, param: str, value: float, level_s: float, roll_deg: float, lean_s: float, hover: float,
               kind: str) -> list:
    """``param`` set to ``value``, level for ``level_s``, then a ``roll_deg`` lean with the throttle that
    holds altitude there for ``lean_s`` (vehicle seconds): the autopilot's ``kind`` messages of the lean."""
    _set_param(m, copter, param, value)
    _fly_and_record(m, copter, level_s, _roll(0.0), hover)
    lean = _fly_and_record(m, copter, lean_s, _roll(roll_deg), hover / math.cos(math.radians(roll_deg)))
    return [msg for msg in lean if msg.get_type() == kind]


def _fast_streams(m, copter) -> None:
    for msg_id in (mavutil.mavlink.MAVLINK_MSG_ID_ATTITUDE, mavutil.mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED):
        m.mav.command_long_send(copter.sysid, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                msg_id, 20000, 0, 0, 0, 0, 0)  # 50 Hz


def _roll(deg: float) -> tuple[float, float, float, float]:
    return (math.cos(math.radians(deg / 2)), math.sin(math.radians(deg / 2)), 0.0, 0.0)


def test_arducopter_shapes_attitude_targets_with_rate_ff_enab(copter):
    """A 20 deg roll step, once with ATC_RATE_FF_ENAB 0 and once with 1 (ArduPilot's default), in one
    boot. Shaped (ATC_INPUT_TC 0.15 s) the step is a critically damped second order whose fastest
    turn is 20 deg / (e x 0.15 s) = 49 deg/s; unshaped the vehicle turns as fast as its attitude loop
    lets it. Asserted: the shaped peak roll rate within 35-70 deg/s and at most 80 % of the
    unshaped one (ArduCopter 4.8 SITL: about 50 against 75 deg/s)."""
    m = copter.connect()
    _guided_airborne(m, copter)
    hover = _hover_throttle(m, copter)
    _fast_streams(m, copter)
    peak = {}
    for ff in (0.0, 1.0):
        seen = _lean_with(m, copter, "ATC_RATE_FF_ENAB", ff, 1.5, 20.0, 1.0, hover, "ATTITUDE")
        peak[ff] = max(math.degrees(a.rollspeed) for a in seen)
    assert 35.0 < peak[1.0] < 70.0 and peak[1.0] < 0.8 * peak[0.0], peak


def test_arducopter_boosts_throttle_by_the_tilt_with_angle_boost(copter):
    """At a 30 deg lean with the throttle that holds altitude there (hover / cos 30 deg), for 1.5 s of
    vehicle time: with ATC_ANGLE_BOOST 1 ArduPilot divides it by cos 30 deg once more (15 % more
    thrust, about 1.5 m/s^2 up once leaning) and the vehicle climbs at least 0.3 m more than with 0
    (ArduCopter 4.8 SITL: 0.8 m more; the bundled flavour 0.9 m)."""
    m = copter.connect()
    _guided_airborne(m, copter)
    _set_param(m, copter, "ATC_RATE_FF_ENAB", 0.0)
    hover = _hover_throttle(m, copter)
    _fast_streams(m, copter)
    climb = {}
    for boost in (0.0, 1.0):
        seen = _lean_with(m, copter, "ATC_ANGLE_BOOST", boost, 2.0, 30.0, 1.5, hover, "LOCAL_POSITION_NED")
        climb[boost] = seen[0].z - seen[-1].z
    assert climb[1.0] - climb[0.0] > 0.3, climb
