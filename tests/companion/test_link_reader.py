"""The pymavlink link's reader: how fast it works off what the socket handed it."""

import asyncio

from pymavlink.dialects.v20 import common as mavlink

from companion.link.pymavlink_link import PymavlinkLink


def test_one_wake_up_parses_the_whole_backlog():
    """300 datagrams (0.15 s of a vehicle at 5x) reach the link's datagram callback while the
    reader is not running, as when this process is starved of CPU. The reader must parse all of
    them in one wake-up: the event loop hands it at most one new datagram per iteration, so a
    reader that parses one per wake-up (it needs two iterations for each, wait_for runs a task)
    never works off a backlog while telemetry keeps coming. The 2 h soak at 5x lost control that
    way: it flew for 6 s on telemetry 0.75 vehicle-seconds old."""

    async def main() -> tuple[int, int, float]:
        link = PymavlinkLink("udpin://127.0.0.1:0")
        vehicle = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        peer = ("127.0.0.1", 14580)
        link._received(vehicle.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                                0, 0, 0).pack(vehicle), peer)
        for k in range(1, 300):
            link._received(vehicle.attitude_quaternion_encode(10 * k, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
                           .pack(vehicle), peer)
        stop = asyncio.Event()
        reader = asyncio.create_task(link.run(stop))
        for _ in range(5):  # five event-loop iterations
            await asyncio.sleep(0)
        depth, t_att = link.rx_queue_depth, link.state.t_att
        stop.set()
        await reader
        return depth, link.stats["received"], t_att

    depth, received, t_att = asyncio.run(main())
    assert received == 300
    assert depth == 0
    assert t_att == 2.99  # the newest attitude (time_boot_ms 2990) is the state
