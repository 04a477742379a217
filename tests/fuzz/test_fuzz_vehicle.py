"""Fuzzing the simulated vehicle's MAVLink input path (``MavlinkServer.datagram_received``, the
function the UDP socket calls) while it flies offboard.

Each example starts from the same vehicle hovering in OFFBOARD under system 255, feeds it a
sequence of hostile datagrams with physics steps in between, and then checks: no exception got
out and none was caught inside either (a caught one is still a bug), the vehicle's state is
finite, and every table a sender can grow is bounded. (Where the vehicle flies is not checked:
frames from system 255, the offboard owner, are obeyed when valid, and a valid setpoint may
command any attitude, as on PX4.)
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.autopilot import world
from sitl.autopilot.logic import Autopilot, Mode
from sitl.autopilot.server import MAX_PEERS, MAX_REASONS, MavlinkServer, ServerConfig
from tests.sitl.test_autopilot import airborne, make, run, stream

from .strategies import FUZZ, datagram
from .watchdog import no_hang

CORPUS = Path(__file__).parent / "corpus" / "vehicle"

INPUTS = tuple(getattr(mavlink, f"MAVLink_{n}_message") for n in (
    "command_long", "command_int", "set_attitude_target", "set_position_target_local_ned", "param_request_list",
    "param_request_read", "param_set", "ping", "timesync", "request_data_stream", "mission_request_list",
    "heartbeat", "setup_signing", "manual_control", "set_mode"))


class _Wire:
    """Stands in for the socket's send side; the frames are packed for real (counted, not sent)."""

    def __init__(self) -> None:
        self.sent = 0

    def sendto(self, buf: bytes, addr: tuple[str, int]) -> None:
        assert isinstance(buf, (bytes, bytearray)) and len(buf) <= 280
        self.sent += 1


def _flying_autopilot() -> Autopilot:
    """Hovering in OFFBOARD under system 255 (built once, copied for each example)."""
    ap = make()
    airborne(ap)
    stream(ap, 1.2, sender=255)
    assert ap.set_mode(Mode.OFFBOARD, 255).result == mavlink.MAV_RESULT_ACCEPTED
    return ap


_BASE: list[Autopilot] = []


def fresh_server() -> MavlinkServer:
    if not _BASE:
        _BASE.append(_flying_autopilot())
    server = MavlinkServer(copy.deepcopy(_BASE[0]), ServerConfig())
    server.transport = _Wire()  # type: ignore[assignment]
    server.peers.add(("127.0.0.1", 14550), server.ap.t, pinned=True)
    return server


def feed(server: MavlinkServer, datagrams: list[bytes], steps: list[int]) -> None:
    with no_hang(seconds=20):
        for i, (data, n) in enumerate(zip(datagrams, steps)):
            server.datagram_received(data, ("127.0.0.1", 40000 + i % 40))
            for _ in range(n):
                world.step(server.ap)
        run(server.ap, 0.05)


def check(server: MavlinkServer) -> None:
    st_ = server.stats
    assert st_["internal_errors"] == 0 and st_["handler_errors"] == 0, dict(st_)
    s = server.ap.vehicle.state
    assert all(math.isfinite(c) for c in (*s.pos_ned_m, *s.vel_ned_m_s, *s.q, *s.omega_rad_s)), s
    assert len(server.peers) <= MAX_PEERS
    assert len(server.rejections) <= MAX_REASONS + 1 and len(server._last_warning) <= MAX_REASONS + 1
    assert len(server.ap.messages) <= 32


@FUZZ
@given(st.lists(st.tuples(datagram(INPUTS, srcs=(255, 255, 42)), st.integers(0, 30)), min_size=1, max_size=12))
def test_no_datagram_sequence_breaks_the_flying_vehicle(inputs: list[tuple[bytes, int]]) -> None:
    server = fresh_server()
    feed(server, [d for d, _ in inputs], [n for _, n in inputs])
    check(server)


@FUZZ
@given(st.lists(st.binary(min_size=1, max_size=64), min_size=1, max_size=40))
def test_made_up_parameter_names_and_commands_do_not_grow_memory(names: list[bytes]) -> None:
    """Every PARAM_REQUEST_READ of an unknown name and every unknown command is a distinct rejection
    reason; the tables that count them stay bounded however many distinct ones arrive."""
    server = fresh_server()
    mav = mavlink.MAVLink(None, srcSystem=42, srcComponent=190)
    for i, name in enumerate(names * 3):
        server.datagram_received(mav.param_request_read_encode(1, 1, name[:16], -1).pack(mav), ("127.0.0.1", 4))
        server.datagram_received(mav.command_long_encode(1, 1, 30000 + i, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav),
                                 ("127.0.0.1", 4))
    check(server)


def corpus() -> list[Path]:
    return sorted(CORPUS.glob("*.bin"))


@pytest.mark.parametrize("path", corpus(), ids=lambda p: p.stem)
def test_regression_corpus(path: Path) -> None:
    """Inputs that once broke something (or nearly did): one datagram per line of hex."""
    server = fresh_server()
    datagrams = [bytes.fromhex(line) for line in path.read_text().split() if line]
    feed(server, datagrams, [5] * len(datagrams))
    check(server)
