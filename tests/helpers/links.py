"""The companion's real link fed frames by hand, as its socket would hand them over."""

from __future__ import annotations

import asyncio

from pymavlink.dialects.v20 import common as mavlink

from companion.link.pymavlink_link import PymavlinkLink
from companion.mavlink.modes import COPTER_MODES

VEHICLE_PEER = ("127.0.0.1", 14580)
"""where the frames fed to a link come from"""


class _Sink:
    """Where the link's own sends go while no socket is open: nowhere."""

    def sendto(self, data: bytes, peer: object) -> None:
        pass

    def close(self) -> None:
        pass


def fed_link(frames: list[bytes], peer: tuple[str, int], **options: object) -> PymavlinkLink:
    """A ``PymavlinkLink(**options)`` whose receive path got ``frames`` from ``peer``, after its reader
    ran five event-loop turns (enough to read them) and stopped."""

    async def main() -> PymavlinkLink:
        link = PymavlinkLink("udpin://127.0.0.1:0", **options)  # type: ignore[arg-type]
        link._transport = _Sink()  # type: ignore[assignment]
        for f in frames:
            link._received(f, peer)
        stop = asyncio.Event()
        reader = asyncio.create_task(link.run(stop))
        for _ in range(5):
            await asyncio.sleep(0)
        stop.set()
        await reader
        return link

    return asyncio.run(main())


def locked_link(plant: bool) -> tuple[PymavlinkLink, mavlink.MAVLink, mavlink.MAVLink, list]:
    """A link fed ArduCopter's heartbeat (system 1), and the simulated plant's component's if
    ``plant``, whose outgoing messages are kept in the list returned instead of sent; with the
    autopilot's and the plant's encoders, to feed it their answers. Its reader, once started, locks
    onto the autopilot."""
    link = PymavlinkLink("udpin://127.0.0.1:0", command_timeout_s=0.2, command_retries=2)
    ap = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    sim = mavlink.MAVLink(None, srcSystem=1, srcComponent=25)
    link._received(ap.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                       mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | 128, COPTER_MODES["GUIDED"],
                                       mavlink.MAV_STATE_ACTIVE).pack(ap), VEHICLE_PEER)
    if plant:
        link._received(sim.heartbeat_encode(mavlink.MAV_TYPE_GENERIC, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                            mavlink.MAV_STATE_UNINIT).pack(sim), VEHICLE_PEER)
    sent: list = []
    link._send = sent.append  # type: ignore[method-assign]
    return link, ap, sim, sent
