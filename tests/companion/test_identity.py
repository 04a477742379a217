"""Identity: telemetry counts only from the autopilot's own component, a COMMAND_ACK only when it is
addressed to us and answers a command we sent, and a heartbeat of another kind from the autopilot's
component does not end a flight. Fed to the real link's receive path (as the socket would)."""

import asyncio

from pymavlink.dialects.v20 import common as mavlink

from companion.mavlink.modes import COPTER_MODES, px4_custom_mode
from companion.link.pymavlink_link import PymavlinkLink
from helpers.links import VEHICLE_PEER, fed_link, locked_link

PEER = VEHICLE_PEER


def link_with(frames) -> PymavlinkLink:
    return fed_link(frames, PEER)


def mav(sysid=1, compid=1) -> mavlink.MAVLink:
    return mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)


OFFBOARD = px4_custom_mode("OFFBOARD")


def heartbeat(m, autopilot=mavlink.MAV_AUTOPILOT_PX4, kind=mavlink.MAV_TYPE_QUADROTOR, custom_mode=OFFBOARD):
    return m.heartbeat_encode(kind, autopilot, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | 128, custom_mode,
                              mavlink.MAV_STATE_ACTIVE).pack(m)


def test_telemetry_from_another_component_of_the_same_system_is_ignored():
    ap, camera = mav(1, 1), mav(1, 100)
    link = link_with([
        heartbeat(ap),
        ap.local_position_ned_encode(1000, 1.0, 2.0, -3.0, 0, 0, 0).pack(ap),
        camera.local_position_ned_encode(1010, 50.0, 50.0, -50.0, 0, 0, 0).pack(camera),
        camera.attitude_quaternion_encode(1010, 0.7071, 0.7071, 0, 0, 0, 0, 0).pack(camera),
    ])
    assert link.state.pos_ned_m == (1.0, 2.0, -3.0) and link.state.q == (1.0, 0.0, 0.0, 0.0)
    assert link.stats["foreign_messages"] == 2


def test_a_heartbeat_of_another_kind_from_the_autopilots_component_does_not_change_the_mode():
    ap = mav(1, 1)
    link = link_with([heartbeat(ap), heartbeat(ap, autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                               custom_mode=COPTER_MODES["LAND"]),
                      heartbeat(ap, kind=mavlink.MAV_TYPE_GCS, custom_mode=0)])
    assert link.state.mode == "OFFBOARD" and link.state.offboard and link.state.armed
    assert link.stats["heartbeats_of_another_kind"] == 2


def test_a_command_ack_counts_only_when_addressed_to_us_and_answering_a_command_in_flight():
    async def main() -> tuple[int, int, int]:
        link = PymavlinkLink("udpin://127.0.0.1:0", command_timeout_s=0.2, command_retries=2)
        ap = mav(1, 1)
        link._received(heartbeat(ap), PEER)
        stop = asyncio.Event()
        reader = asyncio.create_task(link.run(stop))
        await asyncio.sleep(0.05)
        link._peer = None  # sending goes nowhere: only the forged answers below arrive
        pending = asyncio.create_task(link.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1))
        await asyncio.sleep(0.01)
        # answers to someone else, and an answer to a command we never sent
        link._received(ap.command_ack_encode(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_RESULT_ACCEPTED, 0, 0,
                                             42, 1).pack(ap), PEER)
        link._received(ap.command_ack_encode(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_RESULT_ACCEPTED, 0, 0, 255,
                                             191).pack(ap), PEER)
        await asyncio.sleep(0.05)
        assert not pending.done()
        link._received(ap.command_ack_encode(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_RESULT_FAILED, 0, 0,
                                             255, 191).pack(ap), PEER)  # ours: FAILED
        result = await pending
        stop.set()
        await reader
        return result, link.stats["acks_not_for_us"], link.stats["acks_unasked"]

    result, not_ours, unasked = asyncio.run(main())
    assert result == mavlink.MAV_RESULT_FAILED and not_ours == 1 and unasked == 1


def _param_error(ap, name: str) -> bytes:
    return ap.param_error_encode(255, 191, name.encode(), -1, mavlink.MAV_PARAM_ERROR_DOES_NOT_EXIST).pack(ap)


def test_the_autopilots_late_no_such_parameter_does_not_refuse_the_plants_write():
    """ArduPilot answers PARAM_ERROR to a read of SIM_FORCE_X (not its parameter) after the plant
    has answered it: arriving while the write to the plant waits for its echo, it must not end
    that wait (a hover45 flight aborted 'parameter SIM_FORCE_X was not acknowledged' this way)."""
    async def main():
        link, ap, sim, sent = locked_link(plant=True)
        stop = asyncio.Event()
        reader = asyncio.create_task(link.run(stop))
        await asyncio.sleep(0.02)
        write = asyncio.create_task(link.set_param("SIM_FORCE_X", 6.0))
        await asyncio.sleep(0.02)
        asked = sorted(m.target_component for m in sent if m.get_type() == "PARAM_REQUEST_READ")
        link._received(sim.param_value_encode(b"SIM_FORCE_X", 0.0, mavlink.MAV_PARAM_TYPE_REAL32, 23, 6).pack(sim),
                       PEER)
        await asyncio.sleep(0.02)
        link._received(_param_error(ap, "SIM_FORCE_X"), PEER)  # late, for the read
        await asyncio.sleep(0.02)
        sets = [(m.target_component, m.param_value) for m in sent if m.get_type() == "PARAM_SET"]
        link._received(sim.param_value_encode(b"SIM_FORCE_X", 6.0, mavlink.MAV_PARAM_TYPE_REAL32, 23, 6).pack(sim),
                       PEER)
        try:
            echoed = await asyncio.wait_for(write, 5.0)
        finally:
            stop.set()
            await reader
        return asked, sets, echoed

    asked, sets, echoed = asyncio.run(main())
    assert asked == [1, 25]
    assert sets == [(25, 6.0)]
    assert echoed == 6.0


def test_no_such_parameter_from_the_autopilot_ends_a_read_at_once_when_there_is_no_plant():
    """Without a plant's component the autopilot's PARAM_ERROR is the whole answer: one request,
    not the retries of a read nobody will answer."""
    async def main():
        link, ap, _, sent = locked_link(plant=False)
        stop = asyncio.Event()
        reader = asyncio.create_task(link.run(stop))
        await asyncio.sleep(0.02)
        read = asyncio.create_task(link.get_param("SIM_THRUST_MAX", 0.5, 3))
        await asyncio.sleep(0.02)
        link._received(_param_error(ap, "SIM_THRUST_MAX"), PEER)
        try:
            value = await asyncio.wait_for(read, 5.0)
        finally:
            stop.set()
            await reader
        return value, sum(m.get_type() == "PARAM_REQUEST_READ" for m in sent)

    value, requests = asyncio.run(main())
    assert value is None
    assert requests == 2  # one request, to the autopilot and to a plant that may exist
