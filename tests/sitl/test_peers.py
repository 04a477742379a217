"""Clients of the simulated vehicle do not interfere: per-client stream rates, paced parameter lists,
per-client request budgets and a peer table that a churn of addresses cannot empty. In-process
(the server's receive path and step, a transport that records what is sent where); the same over
real UDP is tests/integration/test_sitl_clients.py; the peer table's own rules are
tests/sitl/test_peer_table.py."""

from __future__ import annotations

import time
from collections import Counter

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.autopilot import world
from sitl.autopilot.server import MAX_PEERS, MavlinkServer, ServerConfig
from tests.sitl.test_autopilot import make

CONTROLLER = ("127.0.0.1", 40001)
GCS = ("127.0.0.1", 40002)
ATTACKER = ("127.0.0.1", 40003)
ATT_Q = mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION
IMU = mavlink.MAVLINK_MSG_ID_HIGHRES_IMU
ROLL_PITCH_RATES_IGNORED = 0b011  # an attitude with the yaw rate only, as PX4 v1.16 flies it


class Wire:
    """The socket's send side: what went to whom, decoded."""

    def __init__(self) -> None:
        self.sent: list[tuple[bytes, tuple[str, int]]] = []
        self.parser = mavlink.MAVLink(None)

    def sendto(self, buf: bytes, addr: tuple[str, int]) -> None:
        self.sent.append((bytes(buf), addr))

    def kinds(self, addr: tuple[str, int]) -> Counter[str]:
        out: Counter[str] = Counter()
        for buf, a in self.sent:
            if a == addr:
                out[self.parser.decode(bytearray(buf)).get_type()] += 1
        return out

    def clear(self) -> None:
        self.sent.clear()


def server() -> tuple[MavlinkServer, Wire]:
    s = MavlinkServer(make(), ServerConfig())
    wire = Wire()
    s.transport = wire  # type: ignore[assignment]
    return s, wire


def frame(sysid: int, encode: str, *args) -> bytes:  # type: ignore[no-untyped-def]
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=190)
    return getattr(mav, encode)(*args).pack(mav)


def heartbeat(sysid: int = 255) -> bytes:
    return frame(sysid, "heartbeat_encode", mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                 mavlink.MAV_STATE_ACTIVE)


def interval(msg_id: int, us: float, sysid: int = 255) -> bytes:
    return frame(sysid, "command_long_encode", 1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id, us, 0, 0, 0, 0, 0)


def join(s: MavlinkServer, addr: tuple[str, int], sysid: int = 255) -> None:
    """Three heartbeats: an established client (the stream share of newcomers is counted in wall
    time, which these tests, stepping faster than real time, would exhaust)."""
    for _ in range(3):
        s.datagram_received(heartbeat(sysid), addr)


def steps(s: MavlinkServer, seconds: float) -> None:
    for _ in range(int(round(seconds / s.ap.dt))):
        world.step(s.ap)
        s._telemetry_tick()


def test_a_clients_stream_stops_and_rates_change_only_its_own_streams() -> None:
    """The attacker stops every stream it can (interval -1 for each, REQUEST_DATA_STREAM stop) and
    asks for 1 Hz attitude; the controller asked for 50 Hz attitude; the ground station asked for
    nothing. Over 2 simulated seconds each gets exactly what it asked for, the ground station the
    defaults (attitude 100 Hz, IMU 100 Hz)."""
    s, wire = server()
    for addr in (CONTROLLER, GCS, ATTACKER):
        join(s, addr)
    s.datagram_received(interval(ATT_Q, 20_000), CONTROLLER)
    for msg_id in s.telemetry.encoders:
        s.datagram_received(interval(msg_id, -1, sysid=66), ATTACKER)
    s.datagram_received(frame(66, "request_data_stream_encode", 1, 1, mavlink.MAV_DATA_STREAM_ALL, 0, 0), ATTACKER)
    s.datagram_received(interval(ATT_Q, 1_000_000, sysid=66), ATTACKER)
    steps(s, 0.1)
    wire.clear()
    steps(s, 2.0)
    controller, gcs, attacker = wire.kinds(CONTROLLER), wire.kinds(GCS), wire.kinds(ATTACKER)
    assert controller["ATTITUDE_QUATERNION"] == pytest.approx(100, abs=1)
    assert controller["HIGHRES_IMU"] == gcs["HIGHRES_IMU"] == pytest.approx(200, abs=1)
    assert gcs["ATTITUDE_QUATERNION"] == pytest.approx(200, abs=1)
    assert gcs["HEARTBEAT"] == controller["HEARTBEAT"] == 2
    assert attacker["ATTITUDE_QUATERNION"] == 2 and attacker["HIGHRES_IMU"] == 0 and attacker["HEARTBEAT"] == 0


def test_a_parameter_list_is_paced_per_client_and_repeated_requests_add_nothing() -> None:
    """Fifty PARAM_REQUEST_LISTs in a burst: nothing is sent from the receive path; the requester
    then gets every parameter exactly once, at most two per plant step and 1,000 per second of wall
    time (sitl.autopilot.server.PARAM_VALUES_PER_S), and no other client gets any."""
    s, wire = server()
    s.datagram_received(heartbeat(), GCS)
    wire.clear()
    burst = frame(66, "param_request_list_encode", 1, 1) * 50
    s.datagram_received(burst, ATTACKER)
    assert not [a for _, a in wire.sent]
    n = len(s.params)
    per_step = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < 2.0:
        before = wire.kinds(ATTACKER)["PARAM_VALUE"]
        steps(s, 0.001)
        per_step.append(wire.kinds(ATTACKER)["PARAM_VALUE"] - before)
        if sum(per_step) >= n + 10:
            break
    wall = time.monotonic() - t0
    got = [s.telemetry.mav.decode(bytearray(b)) for b, a in wire.sent if a == ATTACKER]
    indices = [m.param_index for m in got if m.get_type() == "PARAM_VALUE"]
    assert sorted(indices) == list(range(n))
    assert max(per_step) <= 2 and n <= 1000.0 * wall + 4
    assert wire.kinds(GCS)["PARAM_VALUE"] == 0


def test_requests_beyond_a_clients_budget_are_dropped_and_other_clients_are_answered() -> None:
    s, wire = server()
    storm = frame(66, "ping_encode", 1, 1, 0, 0) * 100
    for _ in range(20):  # 2,000 pings in a few ms of wall time
        s.datagram_received(storm, ATTACKER)
    assert 100 <= wire.kinds(ATTACKER)["PING"] <= 110  # the burst, and what refilled meanwhile
    assert s.stats["rate_limited"] >= 1890
    s.datagram_received(frame(255, "ping_encode", 7, 7, 0, 0), GCS)
    assert wire.kinds(GCS)["PING"] == 1
    assert not [a for _, a in wire.sent if a not in (ATTACKER, GCS)]


def test_a_churn_of_addresses_never_evicts_the_controller_or_an_established_client() -> None:
    """The controller streams setpoints; a ground station has sent three heartbeats; then 5,000
    addresses send one heartbeat each. Both keep their place (and their streams), the table stays
    bounded, and the churn only ever displaced itself."""
    s, wire = server()
    q = [1.0, 0.0, 0.0, 0.0]
    join(s, GCS)
    setpoint = frame(255, "set_attitude_target_encode", 0, 1, 1, ROLL_PITCH_RATES_IGNORED, q, 0, 0, 0, 0.3)
    s.datagram_received(setpoint, CONTROLLER)
    for i in range(5000):
        s.datagram_received(heartbeat(sysid=100), ("127.0.0.2", 20000 + i))
    assert CONTROLLER in s.peers and GCS in s.peers and len(s.peers) == MAX_PEERS
    wire.clear()
    steps(s, 0.05)
    assert wire.kinds(CONTROLLER)["ATTITUDE_QUATERNION"] == wire.kinds(GCS)["ATTITUDE_QUATERNION"] in (5, 6)


def test_a_flood_from_one_address_is_dropped_unparsed_beyond_its_budget_but_the_controller_is_not() -> None:
    s, _ = server()
    q = [1.0, 0.0, 0.0, 0.0]
    setpoint = frame(255, "set_attitude_target_encode", 0, 1, 1, ROLL_PITCH_RATES_IGNORED, q, 0, 0, 0, 0.3)
    s.datagram_received(setpoint, CONTROLLER)
    for _ in range(3000):
        s.datagram_received(heartbeat(sysid=66), ATTACKER)
        s.datagram_received(setpoint, CONTROLLER)
    assert s.stats["flood_dropped"] >= 3000 - 2 * 400 - 50  # budget: 400 at once, 400/s x speed-up after
    assert s.ap.rejected == {} and s.ap.setpoints_accepted == 3001  # every setpoint handled
