"""MAVLink FTP as clients speak it: the bundled vehicle's event catalogue (what PX4 serves at
/etc/extras/all_events.json.xz) downloaded by MAVProxy's FTP (pymavlink.mavftp, burst reads) and
by the real MAVSDK core (plain reads), byte for byte. Every reply names its request's opcode
(req_opcode): with 0 there, both discarded the replies and timed out, and the vehicle's EVENT
refusals reached them without text."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest
from pymavlink import mavutil
from pymavlink.mavftp import MAVFTP
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink import ftp
from companion.mavlink.events import CATALOGUE_PATH
from sitl.autopilot.events import catalogue

pytestmark = pytest.mark.integration


def test_mavproxys_ftp_downloads_the_event_catalogue(sitl):  # type: ignore[no-untyped-def]
    s = sitl(speedup=4.0)
    m = mavutil.mavlink_connection(f"udpout:{s.url}", source_system=250)
    m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_UNINIT)
    m.wait_heartbeat(timeout=10)
    data = MAVFTP(m, m.target_system, m.target_component).read(CATALOGUE_PATH, 1_000_000)
    assert data == catalogue()
    m.close()


def test_mavsdks_ftp_downloads_the_event_catalogue(sitl, tmp_path):  # type: ignore[no-untyped-def]
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.ftp import FtpAsync

    s = sitl(speedup=4.0)

    async def run() -> None:
        sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        await sdk.add_any_connection(f"udpout://{s.url}")
        system = await sdk.first_autopilot(timeout_s=10)
        assert system is not None
        async for _ in FtpAsync(system).download(CATALOGUE_PATH, str(tmp_path), False):
            pass
        sdk.destroy()

    asyncio.run(asyncio.wait_for(run(), 30))
    assert (tmp_path / Path(CATALOGUE_PATH).name).read_bytes() == catalogue()


def test_every_reply_names_the_request_and_a_burst_ends_complete_or_at_the_end_of_the_file() -> None:
    blob = bytes(range(256)) * 3
    req = ftp.decode(ftp.encode(7, 1, ftp.BURST_READ_FILE, 100, size=80))
    packets = [ftp.decode(p) for p in ftp.burst(req, blob)]
    assert [p.offset for p in packets] == list(range(100, len(blob), 80))
    assert all(p.req_opcode == ftp.BURST_READ_FILE and p.opcode == ftp.ACK for p in packets)
    assert b"".join(p.data for p in packets) == blob[100:]
    raw = [bytes(ftp.burst(req, blob)[k]) for k in (0, -1)]
    assert (raw[0][6], raw[1][6]) == (0, 1)  # burst_complete on the last only
    assert [p.seq for p in packets] == list(range(8, 8 + len(packets)))
    end = ftp.decode(ftp.burst(ftp.decode(ftp.encode(9, 1, ftp.BURST_READ_FILE, len(blob), size=80)), blob)[0])
    assert (end.opcode, end.req_opcode, end.data) == (ftp.NAK, ftp.BURST_READ_FILE, bytes([ftp.ERR_EOF]))
