"""--connect-timeout is kept whatever the peer sends: an autopilot that only heartbeats over TCP
is given up on when the time asked for is up (it was kept "connecting" for 146 s with a 10 s
timeout: 8 s fetching PX4's event texts, 5 s per unanswered stream request, then a silent wait of
at least 120 s for a position). Only a vehicle that sends attitude but has no position yet may be
waited for longer, and only as long as --position-wait says, with progress lines.

The peer is a real TCP server on 127.0.0.1 speaking MAVLink 2 as a PX4 autopilot would, that
answers nothing; it records when the companion connected and when it hung up."""

from __future__ import annotations

import select
import socket
import subprocess
import sys
import threading
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink

from helpers.processes import ROOT, child_env

pytestmark = pytest.mark.integration

HANG_UP_SLACK_S = 3.0
"""wall seconds between the deadline and the peer seeing the connection closed: the error's
report and the process's exit (the old companion took 146 s instead of 10)"""


class MutePeer:
    """A TCP MAVLink peer: one PX4 quadrotor heartbeat a second and, with ``attitude_hz``,
    ATTITUDE_QUATERNION at that rate; never a position, never an answer."""

    def __init__(self, attitude_hz: float = 0.0) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.attitude_hz = attitude_hz
        self.accepted = self.closed = float("nan")
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        conn, _ = self.server.accept()
        self.accepted = time.monotonic()
        mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        next_beat = next_attitude = self.accepted
        k = 0
        try:
            while True:
                now = time.monotonic()
                if now >= next_beat:
                    conn.sendall(mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                                      mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 0,
                                                      mavlink.MAV_STATE_STANDBY).pack(mav))
                    next_beat += 1.0
                if self.attitude_hz and now >= next_attitude:
                    k += 1
                    conn.sendall(mav.attitude_quaternion_encode(round(1000 * k / self.attitude_hz), 1.0, 0.0, 0.0,
                                                                0.0, 0.0, 0.0, 0.0).pack(mav))
                    next_attitude += 1.0 / self.attitude_hz
                readable, _, _ = select.select([conn], [], [], 0.01)  # the hang-up seen within 10 ms
                if readable and conn.recv(65536) == b"":
                    break
        except OSError:
            pass
        self.closed = time.monotonic()
        conn.close()
        self.server.close()

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)


def fly(peer: MutePeer, tmp_path, *args: str) -> tuple[int, str]:
    r = subprocess.run([sys.executable, "-m", "companion", "fly", "missions/hold.toml", "--connect",
                        f"tcp://127.0.0.1:{peer.port}", "--out", str(tmp_path / "flights"), "--no-plots", *args],
                       cwd=ROOT, capture_output=True, text=True, env=child_env(), timeout=90)
    peer.join(10)
    return r.returncode, r.stdout + r.stderr


def test_a_peer_that_only_heartbeats_is_given_up_on_at_the_connect_timeout(tmp_path):
    peer = MutePeer()
    code, out = fly(peer, tmp_path, "--connect-timeout", "5")
    assert code == 1, out
    assert "answers (heartbeat) but sent no attitude and no position within" in out, out
    held = peer.closed - peer.accepted
    assert 5.0 - 0.5 <= held <= 5.0 + HANG_UP_SLACK_S, (held, out)
    assert "waiting for its telemetry" in out, out  # it said what it waited for while it did


def test_a_vehicle_without_a_position_is_waited_for_only_as_long_as_position_wait_says(tmp_path):
    peer = MutePeer(attitude_hz=20.0)
    code, out = fly(peer, tmp_path, "--connect-timeout", "3", "--position-wait", "6")
    assert code == 1, out
    assert "sends attitude but no position (LOCAL_POSITION_NED)" in out, out
    held = peer.closed - peer.accepted
    assert 9.0 - 0.5 <= held <= 9.0 + HANG_UP_SLACK_S, (held, out)
    assert "still no position (LOCAL_POSITION_NED)" in out and "(--position-wait 6)" in out, out


def test_without_position_wait_the_connect_timeout_holds_and_the_error_names_the_option(tmp_path):
    peer = MutePeer(attitude_hz=20.0)
    code, out = fly(peer, tmp_path, "--connect-timeout", "3")
    assert code == 1, out
    assert "--position-wait S" in out, out
    held = peer.closed - peer.accepted
    assert 3.0 - 0.5 <= held <= 3.0 + HANG_UP_SLACK_S, (held, out)
