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
                                                0, 0, mavlink.MAV_STATE_UNINIT).pack(vehicle), peer)
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


def test_the_udp_endpoint_reads_every_waiting_datagram_in_one_wake_up():
    """Over a real UDP socket on 127.0.0.1: 200 datagrams arrive while the event loop is busy
    (time.sleep stands for a loop stepping physics). One wake-up must read all of them; asyncio's
    own datagram transport reads one per loop iteration, so under a steady stream a busy loop
    never works off the backlog (the vehicle flew setpoints 0.5-1.9 vehicle-seconds old in the
    soak). A flood is read in batches of ``max_batch``."""
    import socket
    import time

    from companion.mavlink.udp import UdpEndpoint

    async def main() -> tuple[list[int], list[int]]:
        got: list[bytes] = []
        ep = UdpEndpoint(lambda data, addr: got.append(data), max_batch=120)
        ep.open(("127.0.0.1", 0))
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            for k in range(200):  # fits the default receive buffer (~270 small datagrams)
                tx.sendto(k.to_bytes(2, "big"), ep.sockname)
            time.sleep(0.05)  # the loop is busy; everything is waiting in the socket
            counts = []
            for _ in range(4):
                await asyncio.sleep(0)  # one event-loop iteration each (this task runs first)
                counts.append(len(got))
            return counts, [int.from_bytes(d, "big") for d in got]
        finally:
            tx.close()
            ep.close()

    counts, order = asyncio.run(main())
    assert counts[:3] == [0, 120, 200], counts  # nothing yet, a batch, the rest
    assert order == list(range(200))
