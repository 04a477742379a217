"""Requests a client waits on are answered, not met with silence: the real MAVSDK core's LogFiles, Param
and Shell plugins against the bundled vehicle, and the same messages read raw with pymavlink.

Silence cost a MAVSDK script a 3 s timeout per call and six retries of each parameter request (the old
vehicle's exit report counted them); each answer here is one the client understands at once."""

from __future__ import annotations

import asyncio
import math

import pytest
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.log_files import LogFilesAsync
from mavsdk.asyncio.plugins.mission import MissionAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.shell import ShellAsync
from mavsdk.plugins.log_files import LogFilesError, LogFilesResult
from mavsdk.plugins.mission import MissionError, MissionItem, MissionPlan, MissionResult
from mavsdk.plugins.param import ParamError, ParamResult
from mavsdk.plugins.shell import Device
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

pytestmark = pytest.mark.integration
POSITION_ONLY = (mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)
"""SET_POSITION_TARGET_*: the position alone"""


def test_mavsdk_gets_an_empty_log_list_an_unknown_parameter_refused_and_a_shell_that_says_it_is_none(sitl):
    """GIVEN MAVSDK connected WHEN it lists logs, reads and writes a parameter that does not exist, sends a
    shell command and uploads a mission THEN: NO_LOGFILES (one LOG_ENTRY with num_logs 0, the log
    protocol's empty list); DOES_NOT_EXIST for both parameter calls, each asked once (no retries); the
    shell's reply text; UNSUPPORTED for the mission (MISSION_ACK), asked once."""
    s = sitl(speedup=2.0)
    out: dict = {}

    async def run() -> None:
        async with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
            await sdk.add_any_connection(f"udpout://{s.url}")
            system = await sdk.first_autopilot(timeout_s=10)
            assert system is not None
            await ask(system)
            del system

    async def ask(system) -> None:  # type: ignore[no-untyped-def]
        log_files = LogFilesAsync(system)
        try:
            out["entries"] = await log_files.get_entries()
        except LogFilesError as exc:
            out["entries"] = exc.result
        param = ParamAsync(system)
        for call in (param.get_param_float("NO_SUCH_PARAM"), param.set_param_float("NO_SUCH_PARAM", 1.0)):
            try:
                await call
            except ParamError as exc:
                out.setdefault("param", []).append(exc.result)
        shell = ShellAsync(system)
        text: list[str] = []

        async def receive() -> None:
            async for r in shell.subscribe_receive():
                text.append(r.data)
                if "nsh> " in "".join(text):
                    return

        reader = asyncio.create_task(receive())
        await asyncio.sleep(0.2)  # subscribed before sending, as the plugin asks
        await shell.send("ver all", Device.SHELL)
        await asyncio.wait_for(reader, 10)
        out["shell"] = "".join(text)
        mission = MissionAsync(system)
        item = MissionItem(47.3978, 8.5456, 5.0, 2.0, True, math.nan, math.nan, None, math.nan, math.nan, 1.0,
                           math.nan, math.nan, None)
        try:
            await mission.upload_mission(MissionPlan([item]))
        except MissionError as exc:
            out["mission"] = exc.result
        for plugin in (log_files, param, shell, mission):
            plugin.destroy()

    asyncio.run(asyncio.wait_for(run(), 60))
    assert out["entries"] in ([], LogFilesResult.NO_LOGFILES)
    assert out["param"] == [ParamResult.DOES_NOT_EXIST, ParamResult.DOES_NOT_EXIST]
    assert "no shell" in out["shell"] and "--firmware px4" in out["shell"]
    assert out["mission"] == MissionResult.UNSUPPORTED
    rejected = s.stop()["rejections"]
    assert rejected["mission upload: no missions here"] == 1
    assert rejected["param read: unknown parameter 'NO_SUCH_PARAM'"] == 1
    assert rejected["param set: unknown parameter 'NO_SUCH_PARAM'"] == 1


def test_the_answers_on_the_wire(sitl):
    """pymavlink: LOG_ENTRY (id 0, num_logs 0, last_log_num 0); PARAM_ERROR addressed to the asker with the
    name and MAV_PARAM_ERROR_DOES_NOT_EXIST (a read by an index past the end names the index); SERIAL_CONTROL
    replies flagged REPLY from the shell device; a fence upload's MISSION_COUNT refused with MISSION_ACK
    UNSUPPORTED of its type; SET_POSITION_TARGET_GLOBAL_INT refused with a STATUSTEXT, not ignored."""
    s = sitl(speedup=2.0)
    m = mavutil.mavlink_connection(f"udpout:{s.url}", source_system=250, source_component=190)
    m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_UNINIT)
    m.wait_heartbeat(timeout=10)
    m.mav.log_request_list_send(1, 1, 0, 0xFFFF)
    entry = m.recv_match(type="LOG_ENTRY", blocking=True, timeout=5)
    assert entry is not None and (entry.id, entry.num_logs, entry.last_log_num) == (0, 0, 0)
    m.mav.param_request_read_send(1, 1, b"NO_SUCH_PARAM", -1)
    err = m.recv_match(type="PARAM_ERROR", blocking=True, timeout=5)
    assert err is not None and (err.target_system, err.target_component) == (250, 190)
    assert err.param_id == "NO_SUCH_PARAM" and err.error == mavutil.mavlink.MAV_PARAM_ERROR_DOES_NOT_EXIST
    m.mav.param_request_read_send(1, 1, b"", 999)
    err = m.recv_match(type="PARAM_ERROR", blocking=True, timeout=5)
    assert err is not None and err.param_index == 999
    m.mav.serial_control_send(mavutil.mavlink.SERIAL_CONTROL_DEV_SHELL, mavutil.mavlink.SERIAL_CONTROL_FLAG_RESPOND,
                              0, 0, 4, list(b"help".ljust(70, b"\0")))
    reply = m.recv_match(type="SERIAL_CONTROL", blocking=True, timeout=5)
    assert reply is not None and reply.flags & mavutil.mavlink.SERIAL_CONTROL_FLAG_REPLY
    assert reply.device == mavutil.mavlink.SERIAL_CONTROL_DEV_SHELL and reply.count > 0
    m.mav.mission_count_send(1, 1, 3, mavutil.mavlink.MAV_MISSION_TYPE_FENCE)
    ack = m.recv_match(type="MISSION_ACK", blocking=True, timeout=5)
    assert ack is not None and ack.type == mavutil.mavlink.MAV_MISSION_UNSUPPORTED
    assert ack.mission_type == mavutil.mavlink.MAV_MISSION_TYPE_FENCE
    m.mav.set_position_target_global_int_send(0, 1, 1, mavutil.mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                              POSITION_ONLY, 473977420, 85455940, 5.0, 0, 0, 0, 0, 0, 0, 0, 0)
    said = m.recv_match(type="STATUSTEXT", condition="'GLOBAL_INT' in STATUSTEXT.text", blocking=True, timeout=5)
    assert said is not None and said.text == "Rejected: GLOBAL_INT setpoint: use LOCAL_NED"
    m.close()
