"""The pieces of ``sitl --firmware`` without a firmware: the lockstep gate, the relay's reading of
MAVLink headers, the plant's MAVLink component, and what PX4's simulator link and ArduPilot's JSON
interface carry. The firmware itself flies in tests/autopilots/test_firmware_plant.py."""

from __future__ import annotations

import json
import math
import re
import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.modes import px4_custom_mode
from companion.mavlink.setpoints import ROLL_PITCH_RATES_IGNORED
from companion.control.params import VehicleParams
from companion.mavlink.params import PLANT_COMPID
from sitl.firmware.ardupilot import MAGIC_16, servo_packet, state_line
from sitl.firmware.lockstep import CompanionGate
from sitl.firmware.plant_component import PlantComponent
from sitl.firmware.px4_wire import ACCEL, BARO, GYRO, MAG, Px4Wire
from sitl.firmware.frames import CLOCKS_MS, CLOCKS_US, SETPOINTS, frames, stamps
from sitl.firmware.world import FirmwareWorld
from sitl.plant.dynamics import Plant
from sitl.plant.geo import GeoOrigin
from sitl.plant.scenario import Scenario

MAV = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
GCS = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)


# --- the lockstep gate ---------------------------------------------------------------------

def test_the_world_waits_for_a_setpoint_once_the_firmware_is_a_lead_past_its_stamp() -> None:
    gate = CompanionGate(lead_s=0.025)
    assert gate.may_advance(0.0)  # no companion yet: free
    gate.setpoint(10.000)
    gate.telemetry(10.020)
    assert gate.may_advance(0.001)
    gate.telemetry(10.025)
    assert not gate.may_advance(0.002)
    gate.setpoint(10.010)  # the companion's next tick
    assert gate.may_advance(0.003)
    assert gate.waits == 1


def test_an_older_or_unstamped_setpoint_does_not_move_the_gate() -> None:
    gate = CompanionGate(lead_s=0.025)
    gate.setpoint(5.0)
    gate.setpoint(4.0)
    gate.setpoint(0.0)
    assert gate.setpoint_stamp_s == 5.0


def test_a_stream_silent_for_its_wait_awake_is_gone_and_time_runs_on_to_the_failsafe() -> None:
    gate = CompanionGate(lead_s=0.025, give_up_wall_s=1.0)
    gate.setpoint(1.0)
    gate.telemetry(1.03)
    wall = 0.0
    while not gate.may_advance(wall):
        wall += 0.01
        assert wall < 2.0
    assert wall == pytest.approx(1.0, abs=0.03) and gate.gave_up == 1
    gate.telemetry(5.0)
    assert gate.may_advance(wall + 0.01)  # given up on that stamp: runs on
    gate.setpoint(5.0)  # a new companion
    gate.telemetry(5.1)
    assert not gate.may_advance(wall + 0.02)


def test_a_stalled_host_does_not_count_as_the_stream_going() -> None:
    """Awake time only: one check after a 5 s stall of the whole machine adds at most 20 ms."""
    gate = CompanionGate(lead_s=0.025, give_up_wall_s=1.0)
    gate.setpoint(1.0)
    gate.telemetry(1.03)
    assert not gate.may_advance(0.0)
    assert not gate.may_advance(5.0)
    assert gate.gave_up == 0


def test_no_lead_is_no_lockstep() -> None:
    gate = CompanionGate(lead_s=0.0)
    gate.setpoint(1.0)
    gate.telemetry(100.0)
    assert gate.may_advance(0.0)


# --- the relay reads headers only ------------------------------------------------------------

def test_setpoint_and_telemetry_stamps_are_read_from_the_headers() -> None:
    sp = GCS.set_attitude_target_encode(123456, 1, 1, ROLL_PITCH_RATES_IGNORED, [1, 0, 0, 0], 0, 0, 0, 0.5).pack(GCS)
    att = MAV.attitude_encode(777000, 0, 0, 0, 0, 0, 0).pack(MAV)
    imu = MAV.highres_imu_encode(778500000, *([0.0] * 13), 0x7).pack(MAV)
    hb = MAV.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                              mavlink.MAV_STATE_ACTIVE).pack(MAV)
    msgs, used = frames(hb + att + sp + imu)
    assert used == len(hb + att + sp + imu) and [m.msgid for m in msgs] == [0, 30, 82, 105]
    assert [m.compid for m in msgs] == [1, 1, 190, 1]
    assert stamps(msgs, SETPOINTS) == pytest.approx(123.456)
    assert stamps(msgs, CLOCKS_MS, CLOCKS_US) == pytest.approx(778.5)


def test_a_frame_cut_by_the_stream_waits_for_its_end_and_garbage_is_skipped() -> None:
    att = MAV.attitude_encode(1000, 0, 0, 0, 0, 0, 0).pack(MAV)
    msgs, used = frames(b"\x00junk" + att[:7])
    assert msgs == [] and used == 5
    msgs, used = frames(att[:7] + att[7:])
    assert [m.msgid for m in msgs] == [30] and used == len(att)


def test_a_stamp_of_zero_trimmed_from_a_mavlink2_payload_reads_as_zero() -> None:
    sp = GCS.set_attitude_target_encode(0, 0, 0, 0, [0, 0, 0, 0], 0, 0, 0, 0).pack(GCS)
    assert stamps(frames(sp)[0], SETPOINTS) == 0.0


# --- the plant's own component -----------------------------------------------------------------

def _component() -> tuple[PlantComponent, FirmwareWorld]:
    world = FirmwareWorld(Scenario(name="t"), 1, GeoOrigin())
    return PlantComponent(world.vehicle, GeoOrigin()), world


def _decode(datagrams: list[bytes]) -> list:  # type: ignore[type-arg]
    parser = mavlink.MAVLink(None)
    return [m for d in datagrams for m in parser.parse_buffer(d) or []]


def _boot(c: PlantComponent, firmware_has: tuple[str, ...] = ()) -> None:
    """The firmware's heartbeat, then three rounds of the probe, answered for ``firmware_has``."""
    c.receive(MAV.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                   mavlink.MAV_STATE_ACTIVE).pack(MAV))
    t = 0.0
    while c.params is None:
        asked = [m.param_id for m in _decode(c.tick(t)) if m.get_type() == "PARAM_REQUEST_READ"]
        for name in asked:
            if name in firmware_has:
                c.receive(MAV.param_value_encode(name.encode(), 1.0, mavlink.MAV_PARAM_TYPE_REAL32, 900, 5).pack(MAV))
        t += 0.5
        assert t < 5


def test_the_plant_serves_its_parameters_and_a_set_reaches_the_vehicle() -> None:
    c, world = _component()
    _boot(c)
    listed = _decode(c.receive(GCS.param_request_list_encode(1, PLANT_COMPID).pack(GCS)))
    assert {m.param_id for m in listed} >= {"SIM_FORCE_X", "SIM_WIND_N", "SIM_MOT1_EFF", "SIM_IMU_NAN"}
    assert all(m.get_srcComponent() == PLANT_COMPID and m.param_count == len(listed) for m in listed)
    echo = _decode(c.receive(GCS.param_set_encode(1, PLANT_COMPID, b"SIM_FORCE_X", 6.0,
                                                  mavlink.MAV_PARAM_TYPE_REAL32).pack(GCS)))
    assert [(m.param_id, m.param_value) for m in echo] == [("SIM_FORCE_X", 6.0)]
    assert world.vehicle.extra_force_ned_n == (6.0, 0.0, 0.0)


def test_a_value_out_of_range_is_refused_with_the_old_value_echoed_and_a_reason() -> None:
    c, world = _component()
    _boot(c)
    out = _decode(c.receive(GCS.param_set_encode(1, PLANT_COMPID, b"SIM_FORCE_X", 60.0,
                                                 mavlink.MAV_PARAM_TYPE_REAL32).pack(GCS)))
    texts = [m.text for m in out if m.get_type() == "STATUSTEXT"]
    values = [m.param_value for m in out if m.get_type() == "PARAM_VALUE"]
    assert values == [0.0] and "outside" in texts[0] and world.vehicle.extra_force_ned_n == (0.0, 0.0, 0.0)


def test_a_name_the_firmware_has_is_never_shadowed() -> None:
    c, _ = _component()
    _boot(c, firmware_has=("SIM_WIND_N",))
    assert c.shadowed == {"SIM_WIND_N"}
    assert c.params is not None and c.params.get("SIM_WIND_N") is None
    read = GCS.param_request_read_encode(1, 0, b"SIM_WIND_N", -1).pack(GCS)
    assert c.receive(read) == []  # the firmware answers for its own


def test_a_parameter_for_another_component_or_system_is_not_the_plants() -> None:
    c, world = _component()
    _boot(c)
    for target in ((1, 1), (2, PLANT_COMPID)):
        assert c.receive(GCS.param_set_encode(*target, b"SIM_FORCE_X", 2.0, 9).pack(GCS)) == []
    assert world.vehicle.extra_force_ned_n == (0.0, 0.0, 0.0)


def test_the_origin_is_sent_until_the_firmware_reports_one() -> None:
    c, _ = _component()
    _boot(c)
    sent = [m for t in (5.0, 7.0) for m in _decode(c.tick(t)) if m.get_type() == "SET_GPS_GLOBAL_ORIGIN"]
    assert len(sent) == 2 and sent[0].latitude == round(GeoOrigin().lat_deg * 1e7)
    c.receive(MAV.gps_global_origin_encode(473977420, 85455940, 488000).pack(MAV))
    assert not [m for m in _decode(c.tick(9.0)) if m.get_type() == "SET_GPS_GLOBAL_ORIGIN"]


def test_nothing_is_served_before_the_firmware_is_heard() -> None:
    c, _ = _component()
    assert c.tick(10.0) == [] and c.receive(GCS.param_request_list_encode(1, 0).pack(GCS)) == []


# --- the firmware's simulator links ---------------------------------------------------------------

def test_a_frame_reaches_px4_as_hil_sensor_with_every_field_flagged() -> None:
    world = FirmwareWorld(Scenario(name="t", vehicle=VehicleParams(layout="x")), 1, GeoOrigin())
    frame = world.step((0.0,) * 4, False, 4)
    msgs = _decode(Px4Wire().frame(frame, vision=True))
    sensor = msgs[0]
    assert sensor.get_type() == "HIL_SENSOR" and sensor.time_usec == 4000 and sensor.id == 0
    assert sensor.fields_updated == ACCEL | GYRO | MAG | BARO
    assert sensor.zacc == pytest.approx(-9.81, abs=0.3)  # resting on the ground
    assert sensor.abs_pressure == pytest.approx(955.98, abs=0.1)  # ISA at 488 m, hPa
    assert math.hypot(sensor.xmag, sensor.ymag, sensor.zmag) == pytest.approx(0.482, abs=0.02)


def test_px4s_motor_outputs_are_read_with_its_armed_flag() -> None:
    wire = Px4Wire()
    armed = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    data = MAV.hil_actuator_controls_encode(8000, [0.5, 0.6, 0.7, 0.8] + [0.0] * 12, armed,
                                            mavlink.HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP).pack(MAV)
    out = wire.parse(data[:10]) + wire.parse(data[10:])
    assert len(out) == 1 and out[0].armed and out[0].controls[:4] == pytest.approx((0.5, 0.6, 0.7, 0.8))


def test_an_ardupilot_servo_packet_and_the_state_line_it_reads() -> None:
    pwm = [1500, 1600, 1000, 2000] + [0] * 12
    assert servo_packet(struct.pack("<HHI16H", MAGIC_16, 1000, 42, *pwm)) == (1000, 42, tuple(pwm))
    assert servo_packet(b"\x00" * 40) is None
    world = FirmwareWorld(Scenario(name="t"), 1, GeoOrigin())
    line = state_line(world.step((0.0,) * 4, True, 1)).decode()
    assert line.startswith("\n") and line.endswith("\n")
    doc = json.loads(line)
    assert set(doc) == {"timestamp", "imu", "position", "quaternion", "velocity"}
    # ArduPilot finds each key and reads "[%f, %f, %f]" right after the key and '":'
    for key in ("gyro", "accel_body", "position", "velocity"):
        assert re.search(rf'"{key}":\[[-0-9.e]+,[-0-9.e]+,[-0-9.e]+\]', line), key


def test_hover_outputs_hold_the_plant_up() -> None:
    """The normalised output for hover, from the thrust the plant needs: the body neither climbs
    nor sinks by more than the 8-bit motor grid allows."""
    v = VehicleParams(layout="x")
    world = FirmwareWorld(Scenario(name="t", vehicle=v), 1, GeoOrigin())
    u = math.sqrt(v.weight_n / v.thrust_max_n)  # thrust is u^2 of full thrust
    world.vehicle.plant.state = Plant.at_rest(v, world.scenario.airframe, (0.0, 0.0, -2.0), hovering=True).state
    for _ in range(250):
        frame = world.step((u,) * 4, True, 4)  # 1 s
    # the grid's step near hover: 3.1 rad/s of 520, 1.2 % of the thrust: at most 0.06 m/s^2 either way
    assert abs(frame.state.vel_ned_m_s[2]) < 0.07 and abs(frame.state.pos_ned_m[2] + 2.0) < 0.04
    assert frame.accel_m_s2[2] == pytest.approx(-v.gravity_m_s2, abs=0.25)
    # 10 % more output: 10 % more speed, 21 % more thrust, 2.1 m/s^2 up; after 0.25 s less the
    # rotors' 20 ms lag, 0.48 m/s
    moving = world.step((u * 1.1,) * 4, True, 250)
    assert -0.55 < moving.state.vel_ned_m_s[2] < -0.42


def test_the_relay_hands_what_is_addressed_to_the_plant_to_it_and_passes_the_rest() -> None:
    from sitl.firmware.frames import for_component

    to_plant = GCS.param_set_encode(1, PLANT_COMPID, b"SIM_FORCE_X", 2.0, mavlink.MAV_PARAM_TYPE_REAL32).pack(GCS)
    read_plant = GCS.param_request_read_encode(1, PLANT_COMPID, b"SIM_WIND_N", -1).pack(GCS)
    to_autopilot = GCS.param_set_encode(1, 1, b"MPC_XY_P", 1.0, mavlink.MAV_PARAM_TYPE_REAL32).pack(GCS)
    broadcast = GCS.param_request_list_encode(1, 0).pack(GCS)
    sp = GCS.set_attitude_target_encode(1, 1, 25, ROLL_PITCH_RATES_IGNORED, [1, 0, 0, 0], 0, 0, 0, 0.5).pack(GCS)
    # to component 25, but a setpoint
    mine, rest = for_component(to_autopilot + to_plant + sp + read_plant + broadcast, PLANT_COMPID)
    assert mine == to_plant + read_plant and rest == to_autopilot + sp + broadcast
    assert for_component(to_plant[:9], PLANT_COMPID) == (b"", to_plant[:9])  # cut: passed on as it came


def test_the_world_waits_only_while_the_vehicle_is_armed() -> None:
    """PX4 returns to OFFBOARD after a disarm; a disarmed vehicle is never flown by a stream."""
    from sitl.firmware.frames import armed

    gate = CompanionGate(lead_s=0.025)
    gate.setpoint(10.0)
    gate.telemetry(10.03)
    assert not gate.may_advance(0.0)
    offboard = px4_custom_mode("OFFBOARD")
    flying = MAV.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                  mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED,
                                  offboard, mavlink.MAV_STATE_ACTIVE).pack(MAV)
    parked = MAV.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                  mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, offboard,
                                  mavlink.MAV_STATE_ACTIVE).pack(MAV)
    plant = mavlink.MAVLink(None, srcSystem=1, srcComponent=PLANT_COMPID)
    other = plant.heartbeat_encode(mavlink.MAV_TYPE_GENERIC, mavlink.MAV_AUTOPILOT_INVALID,
                                   mavlink.MAV_MODE_FLAG_SAFETY_ARMED, 0, mavlink.MAV_STATE_ACTIVE).pack(plant)
    assert armed(frames(flying)[0]) is True and armed(frames(parked)[0]) is False
    assert armed(frames(other)[0]) is None  # not the autopilot's
    gate.heartbeat(False)
    assert gate.may_advance(0.01)
    gate.heartbeat(True)
    assert not gate.may_advance(0.02)


def test_after_a_command_the_next_heartbeat_tells_a_handed_back_vehicle_from_a_stream_going_on() -> None:
    """Landing: the command, one more setpoint, then silence: by the heartbeat the stream has
    ended and the world runs on. Taking OFFBOARD: the command, and the stream goes on: lockstep."""
    gate = CompanionGate(lead_s=0.025)
    gate.setpoint(10.0)
    gate.telemetry(10.02)
    gate.command()
    gate.setpoint(10.01)
    gate.telemetry(10.5)
    assert gate.may_advance(0.0)  # the firmware runs to its heartbeat
    gate.heartbeat(True)
    assert gate.may_advance(0.01) and gate.gave_up == 0  # handed back: runs on
    gate.setpoint(20.0)  # a new stream
    gate.telemetry(20.03)
    assert not gate.may_advance(0.02)
    gate.command()  # DO_SET_MODE OFFBOARD
    gate.setpoint(20.02)
    gate.telemetry(20.06)
    assert gate.may_advance(0.03)
    gate.setpoint(20.12)
    gate.telemetry(20.15)
    gate.heartbeat(True)  # the stream is fresh: lockstep goes on
    assert not gate.may_advance(0.04)


def test_a_heartbeat_that_answers_the_command_at_once_does_not_decide_for_the_stream() -> None:
    """ArduCopter answers a mode change with a heartbeat in the same millisecond, before the
    companion's stream could have been seen to end: had that heartbeat decided, the landing's
    world froze 25 ms on (the companion's last setpoint + the lead) until the companion's own 3 s
    watchdog declared the link lost (1 of 3 ArduCopter hover45 flights on a busy host)."""
    gate = CompanionGate(lead_s=0.025)
    gate.setpoint(69.384)
    gate.telemetry(69.39)
    gate.command()  # DO_SET_MODE LAND
    gate.setpoint(69.394)  # the tick already under way
    gate.telemetry(69.394)
    gate.heartbeat(True)  # LAND, at once
    gate.telemetry(69.424)
    assert gate.may_advance(0.0)  # still the command's: runs on
    gate.telemetry(69.6)
    gate.heartbeat(True)  # the stream has ended by now
    gate.telemetry(70.0)
    assert gate.may_advance(0.01) and gate.gave_up == 0


# --- signing at the companion's side of the relay --------------------------------------------

KEY = bytes(range(32))


def _pump(relay, rounds: int = 20) -> None:  # type: ignore[no-untyped-def]
    import select

    for _ in range(rounds):
        ready = select.select(relay.sockets(), [], [], 0.02)[0]
        for sock in ready:
            relay.readable(sock)


def _received(sock) -> bytes:  # type: ignore[no-untyped-def]
    import socket

    out = b""
    sock.settimeout(0.2)
    try:
        while True:
            out += sock.recv(65535)
            sock.settimeout(0.05)
    except (socket.timeout, BlockingIOError):
        return out


def test_under_signing_the_udp_relay_signs_what_leaves_and_passes_only_signed_frames_in() -> None:
    import socket

    from companion.mavlink.signing import enable_signing
    from sitl.firmware.relay import UdpRelay
    from sitl.firmware.signed_link import SignedLink

    companion = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    companion.bind(("127.0.0.1", 0))
    firmware = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    firmware.bind(("127.0.0.1", 0))
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    fw_side = probe.getsockname()
    probe.close()
    relay = UdpRelay(fw_side, companion.getsockname(), lambda t: None, lambda t: None)
    relay.signing = SignedLink(KEY)
    try:
        px4 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        firmware.sendto(px4.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                             mavlink.MAV_STATE_ACTIVE).pack(px4)
                        + px4.attitude_encode(1000, 0.1, 0, 0, 0, 0, 0).pack(px4), fw_side)
        _pump(relay)
        rx = mavlink.MAVLink(None)
        rx.signing.secret_key = KEY  # pymavlink checks each signature against this key
        got = rx.parse_buffer(_received(companion)) or []
        assert [m.get_type() for m in got] == ["HEARTBEAT", "ATTITUDE"] and all(m.get_signed() for m in got)

        plain = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        signed = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        enable_signing(signed, KEY)
        wrong = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        enable_signing(wrong, bytes(32 * [7]))
        ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
        arm_plain = plain.command_long_encode(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(plain)
        arm_wrong = wrong.command_long_encode(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(wrong)
        arm_signed = signed.command_long_encode(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(signed)
        gcs_heartbeat = plain.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                               mavlink.MAV_STATE_ACTIVE).pack(plain)
        for datagram in (arm_plain, arm_wrong, arm_signed, gcs_heartbeat):
            companion.sendto(datagram, relay.co_sock.getsockname())
        _pump(relay)
        assert _received(firmware) == arm_signed + gcs_heartbeat  # unchanged, the refused ones dropped
        assert relay.signing.refused == {"unsigned COMMAND_LONG": 1, "wrong key COMMAND_LONG": 1}
        companion.sendto(arm_signed, relay.co_sock.getsockname())  # the same frame again: a replay
        _pump(relay)
        assert _received(firmware) == b"" and relay.signing.refused["replayed COMMAND_LONG"] == 1
    finally:
        relay.close()
        companion.close()
        firmware.close()


def test_under_signing_the_tcp_relay_signs_the_firmwares_stream_and_the_plants_replies() -> None:
    import socket

    from companion.mavlink.signing import enable_signing
    from sitl.firmware.relay import TcpRelay
    from sitl.firmware.signed_link import SignedLink

    firmware_server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    firmware_server.bind(("127.0.0.1", 0))
    firmware_server.listen(1)
    probe = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    probe.bind(("127.0.0.1", 0))
    listen = probe.getsockname()
    probe.close()
    plant = mavlink.MAVLink(None, srcSystem=1, srcComponent=PLANT_COMPID)
    answer = plant.param_value_encode(b"SIM_FORCE_X", 2.0, mavlink.MAV_PARAM_TYPE_REAL32, 1, 0).pack(plant)
    relay = TcpRelay(listen, firmware_server.getsockname(), lambda t: None, lambda t: None,
                     (PLANT_COMPID, lambda data: [answer]))
    relay.signing = SignedLink(KEY)
    client = socket.create_connection(listen)
    try:
        _pump(relay, 5)
        fw, _ = firmware_server.accept()
        signed = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        enable_signing(signed, KEY)
        plain = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        client.sendall(signed.param_set_encode(1, PLANT_COMPID, b"SIM_FORCE_X", 2.0,
                                               mavlink.MAV_PARAM_TYPE_REAL32).pack(signed)
                       + plain.param_set_encode(1, 1, b"ARMING_CHECK", 0, mavlink.MAV_PARAM_TYPE_REAL32).pack(plain)
                       + signed.param_set_encode(1, 1, b"GUID_TIMEOUT", 0.5,
                                                 mavlink.MAV_PARAM_TYPE_REAL32).pack(signed))
        _pump(relay)
        up = mavlink.MAVLink(None).parse_buffer(_received(fw)) or []
        assert [m.param_id for m in up] == ["GUID_TIMEOUT"]  # the plant's own answered here; the unsigned dropped
        ardu = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        fw.sendall(ardu.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                         mavlink.MAV_STATE_ACTIVE).pack(ardu))
        _pump(relay)
        rx = mavlink.MAVLink(None)
        rx.signing.secret_key = KEY
        got = rx.parse_buffer(_received(client)) or []
        assert sorted(m.get_type() for m in got) == ["HEARTBEAT", "PARAM_VALUE"] and all(m.get_signed() for m in got)
        assert relay.signing.refused == {"unsigned PARAM_SET": 1}
    finally:
        client.close()
        relay.close()
        firmware_server.close()
