"""The real MAVSDK core (mavsdk 4.x, in-process C++) flies the simulated vehicle over UDP.

MAVSDK's Offboard plugin cannot send a quaternion with body rates, so the setpoint goes out as a
raw SET_ATTITUDE_TARGET through MavlinkDirect, and the mode change as DO_SET_MODE through
MavlinkDirect's command sender (which retries until acknowledged).
"""

from __future__ import annotations

import asyncio
import json
import math

import pytest
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.mavlink_direct import MavlinkMessage

from companion.control import quaternion as quat

from helpers.processes import quat_angle_deg

pytestmark = pytest.mark.integration


def attitude_message(q, thrust: float) -> MavlinkMessage:
    fields = {"time_boot_ms": 0, "target_system": 1, "target_component": 1, "type_mask": 0, "q": list(q),
              "body_roll_rate": 0.0, "body_pitch_rate": 0.0, "body_yaw_rate": 0.0, "thrust": thrust}
    return MavlinkMessage(message_name="SET_ATTITUDE_TARGET", system_id=245, component_id=190,
                          target_system_id=1, target_component_id=1, fields_json=json.dumps(fields))


def command_message(command: int, *params: float) -> MavlinkMessage:
    p = list(params) + [0.0] * (7 - len(params))
    fields = {"target_system": 1, "target_component": 1, "command": command, "confirmation": 0,
              **{f"param{i + 1}": v for i, v in enumerate(p)}}
    return MavlinkMessage(message_name="COMMAND_LONG", system_id=245, component_id=190, target_system_id=1,
                          target_component_id=1, fields_json=json.dumps(fields))


async def first(gen, cond=lambda x: True, timeout: float = 20.0):
    async def scan():
        async for item in gen:
            if cond(item):
                return item
    return await asyncio.wait_for(scan(), timeout)


async def fly(url: str) -> dict:
    out: dict = {}
    cfg = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(cfg) as sdk:
        await sdk.add_any_connection(f"udpout://{url}")
        system = await sdk.first_autopilot(timeout_s=10.0)
        assert system is not None
        tel, act, direct = TelemetryAsync(system), ActionAsync(system), MavlinkDirectAsync(system)
        out["health"] = await first(tel.subscribe_health(), lambda h: h.is_armable)
        await act.arm()
        out["armed"] = await first(tel.subscribe_armed(), lambda a: a)
        await act.takeoff()
        out["position"] = await first(tel.subscribe_position_velocity_ned(), lambda p: p.position.down_m < -2.3)
        out["global_position"] = await first(tel.subscribe_position())
        out["imu"] = await first(tel.subscribe_imu())
        q0 = await first(tel.subscribe_attitude_quaternion())
        yaw = quat.to_euler((q0.w, q0.x, q0.y, q0.z))[2]
        hover = 0.63 * 9.81 / (4 * 5.72e-6 * 900.6**2)

        setpoint = {"msg": attitude_message(quat.from_yaw(yaw), hover)}

        async def stream():
            while True:
                await direct.send_message(setpoint["msg"])
                await asyncio.sleep(0.02)

        streamer = asyncio.create_task(stream())
        try:
            await asyncio.sleep(1.5)  # streaming before switching, as a companion does (PX4 needs one fresh setpoint)
            ack = await direct.send_command(command_message(176, 1, 6, 0))
            out["offboard_ack"] = json.loads(ack.fields_json)["result"]
            out["mode"] = await first(tel.subscribe_flight_mode(), lambda m: m.name == "OFFBOARD")

            roll = math.radians(20.0)
            step = quat.from_euler(roll, 0.0, yaw)
            setpoint["msg"] = attitude_message(step, hover / math.cos(roll))
            await asyncio.sleep(0.25)  # wall; at 2x that is 0.5 s simulated
            samples = []
            async for q in tel.subscribe_attitude_quaternion():
                samples.append(quat_angle_deg((q.w, q.x, q.y, q.z), step))
                if len(samples) >= 30:
                    break
            out["roll_errors"] = samples
            setpoint["msg"] = attitude_message(quat.from_yaw(yaw), hover)
            await asyncio.sleep(0.5)
        finally:
            streamer.cancel()
        await act.land()
        out["landed"] = await first(tel.subscribe_armed(), lambda a: not a, timeout=40)
    return out


def test_mavsdk_arms_takes_off_flies_offboard_attitude_and_lands(sitl):
    """GIVEN MAVSDK connected over UDP WHEN it arms, takes off, streams SET_ATTITUDE_TARGET and
    switches to offboard with a 20 deg roll step THEN all telemetry it needs arrives, the vehicle
    holds the commanded attitude within 3 deg from 0.5 s after the step (the attitude loop is a
    critically damped 12 rad/s loop: 0.35 deg left at 0.5 s; MAVSDK's executor adds up to tens of
    ms of wall time to when the step reaches the vehicle, so 3 deg rather than 2), and landing
    disarms."""
    s = sitl(speedup=2.0)
    out = asyncio.run(fly(s.url))
    h = out["health"]
    assert h.is_local_position_ok and h.is_global_position_ok and h.is_home_position_ok
    assert out["position"].position.down_m < -2.3
    assert abs(out["global_position"].latitude_deg - 47.397742) < 1e-4
    assert abs(out["imu"].acceleration_frd.down_m_s2 + 9.81) < 0.5
    assert out["offboard_ack"] == 0 and out["mode"].name == "OFFBOARD"
    assert max(out["roll_errors"][10:]) < 3.0, out["roll_errors"]
    assert out["landed"] is False
    report = s.stop()
    assert not report["armed"] and report["stats"].get("internal_errors", 0) == 0
