"""The companion over a serial line and over TCP: a full flight of the bundled vehicle over each
(tests/helpers/bridges.py puts a pseudo-terminal pair or a TCP server in front of its UDP port),
and the frame splitter that turns a byte stream back into MAVLink frames."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.stream import FrameSplitter
from helpers.bridges import PtyBridge, TcpBridge
from helpers.processes import LOCKSTEP, LOCKSTEP_SPEEDUP, PAPER, PAPER_OUTPUT

from .test_companion_e2e import segments

pytestmark = pytest.mark.integration


def test_the_frame_splitter_cuts_a_stream_in_any_pieces_and_skips_garbage():
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    frames = [mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                   mavlink.MAV_STATE_STANDBY).pack(mav),
              mav.attitude_quaternion_encode(5, 1, 0, 0, 0, 0, 0, 0, [0.0] * 4).pack(mav),
              mav.statustext_encode(mavlink.MAV_SEVERITY_WARNING, b"hello", 0, 0).pack(mav)]
    stream = b"\x00garbage" + b"".join(frames) + b"\x01\x02"
    for piece in (1, 3, 7, len(stream)):
        s = FrameSplitter()
        out = [f for i in range(0, len(stream), piece) for f in s.feed(stream[i:i + piece])]
        assert out == frames and s.skipped == len(b"\x00garbage") + 2, piece


@pytest.mark.parametrize("link", ["serial", "tcp"])
def test_a_full_flight_over_serial_and_tcp(sitl, companion, link):
    """The hold mission over a pseudo-terminal at 921600 baud, or over TCP: it completes with the
    clean hold's bounds (RMS < 3 cm)."""
    s = sitl(*PAPER, *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    host, port = s.url.split(":")
    bridge = PtyBridge((host, int(port))) if link == "serial" else TcpBridge((host, int(port)))
    try:
        url = f"serial://{bridge.device}:921600" if link == "serial" else f"tcp://127.0.0.1:{bridge.port}"
        c = companion("missions/hold.toml", url, *PAPER_OUTPUT)
        code, out = c.finish(timeout=180)
    finally:
        bridge.close()
    assert code == 0, out
    hold = segments(c.flight_dir())["hold"]
    assert hold["rms_error_m"] < 0.03, hold
    assert bridge.frames_up > 1000 and bridge.frames_down > 1000


def test_a_port_taken_by_another_program_is_one_line_and_nothing_flown(tmp_path):
    """udpin:// on a port another program holds (a second companion, MAVProxy): the companion ends
    at once with one line naming the port (it used to be a traceback), exit 1, no flight folder."""
    import socket
    import subprocess
    import sys

    from helpers.processes import ROOT, child_env

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("0.0.0.0", 0))
        port = held.getsockname()[1]
        r = subprocess.run([sys.executable, "-m", "companion", "fly", "missions/hold.toml", "--connect",
                            f"udpin://0.0.0.0:{port}", "--out", str(tmp_path), "--no-plots"], cwd=ROOT,
                           capture_output=True, text=True, timeout=60, env=child_env())
    lines = (r.stdout + r.stderr).strip().splitlines()
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert lines[-1] == f"companion: aborted: cannot open UDP 0.0.0.0:{port}: Address already in use", lines
    assert not any(tmp_path.iterdir())
