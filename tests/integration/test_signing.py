"""MAVLink 2 signing end to end: the companion and the vehicle share a key (one from a file, the
other from the environment); attackers on the same network send setpoints and commands while the
signed waypoint mission flies. Everything over UDP on 127.0.0.1, separate processes."""

from __future__ import annotations

import glob
import math
import socket
import threading
from collections import Counter
from pathlib import Path

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat
from companion.mavlink.signing import enable_signing, write_key_file
from helpers.processes import LOCKSTEP, PAPER, PAPER_OUTPUT

from .test_companion_e2e import SPEEDUP, segments
from .test_link_faults import Observer

pytestmark = pytest.mark.integration

WRONG_KEY = bytes(32)
ATTACK_SPEEDUP = 2.0
"""slower than the other end-to-end tests (4x): this test's own process verifies every telemetry
signature in Python (the observer) and runs the attacker, so at 4x the harness alone takes most of
a core of this 2-core machine and starves the vehicle and the companion"""
ROGUE_Q = list(quat.from_euler(math.radians(60), 0.0, 0.0))  # 60 deg roll at full thrust: a crash if obeyed


class Attacker:
    """On its own socket at 50 Hz: setpoints and commands unsigned (posing as the companion, sysid
    255), signed with a wrong key, and signed with the right key by a system (42) that did not take
    offboard control; plus replays of the companion's own signed setpoints, read from its .tlog."""

    def __init__(self, url: str, key: bytes, flights: Path) -> None:
        host, port = url.rsplit(":", 1)
        self.addr = (host, int(port))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.flights = flights
        self.unsigned = mavlink.MAVLink(None, srcSystem=255, srcComponent=191)
        self.wrong = mavlink.MAVLink(None, srcSystem=255, srcComponent=191)
        enable_signing(self.wrong, WRONG_KEY)
        self.other = mavlink.MAVLink(None, srcSystem=42, srcComponent=190)
        enable_signing(self.other, key)
        self.sent: Counter[str] = Counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _setpoint(self, mav: mavlink.MAVLink) -> bytes:
        return mav.set_attitude_target_encode(0, 1, 1, 0, ROGUE_Q, 0, 0, 0, 1.0).pack(mav)

    def _companion_frames(self) -> list[bytes]:
        """The companion's signed SET_ATTITUDE_TARGETs so far (as captured by a sniffer)."""
        logs = glob.glob(str(self.flights / "*" / "traffic.tlog"))
        if not logs:
            return []
        log = mavutil.mavlink_connection(logs[0])
        frames = []
        while (msg := log.recv_match(type="SET_ATTITUDE_TARGET")) is not None:
            if msg.get_srcSystem() == 255:
                frames.append(bytes(msg.get_msgbuf()))
        return frames

    def _send(self, what: str, buf: bytes) -> None:
        self.sock.sendto(buf, self.addr)
        self.sent[what] += 1

    def _run(self) -> None:
        replay: list[bytes] = []
        n = 0
        while not self._stop.wait(0.02):
            n += 1
            self._send("unsigned SET_ATTITUDE_TARGET", self._setpoint(self.unsigned))
            self._send("wrong key SET_ATTITUDE_TARGET", self._setpoint(self.wrong))
            self._send("other system SET_ATTITUDE_TARGET", self._setpoint(self.other))
            if n % 10 == 0:  # land, then force-disarm: 5 Hz each
                cmd = (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196) if n % 20 else (
                    mavlink.MAV_CMD_DO_SET_MODE, 0, 1, 4, 6)
                buf = self.unsigned.command_long_encode(1, 1, cmd[0], 0, *cmd[1:], *[0] * (8 - len(cmd))).pack(
                    self.unsigned)
                self._send("unsigned COMMAND_LONG", buf)
            if n % 100 == 0 and len(replay) < 300:
                replay = self._companion_frames()[-300:]
            if replay:
                self._send("replayed SET_ATTITUDE_TARGET", replay[n % len(replay)])

    def stop(self) -> Counter[str]:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()
        return self.sent


def test_signed_flight_completes_while_unsigned_forged_replayed_and_foreign_senders_are_ignored(
        sitl, companion, tmp_path, record_property):
    """With the key on both ends the waypoint square must meet its clean bounds (RMS < 5 cm, peak
    < 15 cm, test_companion_e2e): nothing the attackers send may reach the controller. Each refused
    frame is counted by reason and kind — every one sent (loopback UDP loses none; 2% allowed for a
    frame in flight at shutdown) — and each reason is reported once, not per frame."""
    key_file = tmp_path / "mavlink.key"
    key = write_key_file(key_file)
    s = sitl("--signing-key-file", str(key_file), *PAPER, *LOCKSTEP, speedup=ATTACK_SPEEDUP)
    assert any("signing on" in line for line in s.banner)
    observer = Observer(s.url, signing_key=key)
    c = companion("missions/waypoints.toml", s.url, *PAPER_OUTPUT, env={"MAVLINK_SIGNING_KEY": key.hex()})
    c.wait_for("signing on")
    attacker = Attacker(s.url, key, tmp_path / "flights")
    # the attack lasts while the companion flies offboard and before: after it hands the vehicle to
    # the landing, a setpoint of system 42 is no longer refused by the owner check (nobody holds
    # offboard), and how long that lasts in wall time depends on the pace of lockstep, not on signing
    c.wait_for("step 5: land")
    sent = attacker.stop()
    code, out = c.finish()
    positions = observer.stop()
    report = s.stop()
    assert code == 0, out
    seg = segments(c.flight_dir())
    square = seg["square"]
    assert square["ok"] and square["rms_error_m"] < 0.05 and square["peak_error_m"] < 0.15, square
    summary = seg["_summary"]
    assert summary["signing"] != "off" and summary["signing_rejections"] == {}  # the vehicle's frames all good
    assert not report["armed"] and positions[:, 3].max() < 0.1  # landed, and never below the ground
    dropped = report["signing_rejections"]
    for kind in ("unsigned SET_ATTITUDE_TARGET", "wrong key SET_ATTITUDE_TARGET", "unsigned COMMAND_LONG",
                 "replayed SET_ATTITUDE_TARGET"):
        assert sent[kind] > (100 if "ATTITUDE" in kind else 20), sent
        assert 0.98 * sent[kind] <= dropped.get(kind, 0) <= sent[kind], (kind, sent, dropped)
    # system 42 holds the key, so its frames pass the signature check; the owner check refuses
    # them once the companion has offboard control (before that any system may pre-stream)
    owner = report["rejections"].get("attitude target: setpoint from a system without offboard control", 0)
    assert owner > 0.5 * sent["other system SET_ATTITUDE_TARGET"], (owner, sent)
    record_property("square", {k: square[k] for k in ("rms_error_m", "peak_error_m")})
    record_property("sent", dict(sent))
    record_property("dropped", dropped)
    record_property("owner_rejections", owner)
    texts = Counter(t.split(" from ")[0] for t in observer.texts if t.startswith("Dropped "))
    assert texts == Counter({"Dropped unsigned": 1, "Dropped wrong key": 1, "Dropped replayed": 1}), observer.texts


def test_a_companion_without_the_vehicles_key_gets_nothing_and_says_why(sitl, companion, tmp_path):
    """A signing vehicle ignores unsigned and wrongly signed frames, so a companion without its key
    (or with another) never learns of it; a companion with a key facing a vehicle that does not
    sign sees heartbeats it cannot trust. Each says which, and nothing arms."""
    key_file = tmp_path / "mavlink.key"
    write_key_file(key_file)
    signing = sitl("--signing-key-file", str(key_file), speedup=SPEEDUP)
    plain = sitl(speedup=SPEEDUP)
    wrong = {"MAVLINK_SIGNING_KEY": "not the vehicle's passphrase"}
    for url, env, expected in ((signing.url, None, "give its key"),
                               (signing.url, wrong, "does it have ours (fingerprint"),
                               (plain.url, wrong, "not signed: the vehicle does not sign")):
        code, out = companion("missions/hold.toml", url, "--connect-timeout", "3", env=env).finish(timeout=30)
        assert code == 1 and expected in out, out
    report = signing.stop()
    assert report["signing_rejections"].get("unsigned HEARTBEAT", 0) == 0  # allowed unsigned, yet taught nothing
    assert report["signing_rejections"].get("wrong key HEARTBEAT", 0) >= 2
    assert report["stats"].get("sent", 0) == 0 and not report["armed"]  # it never sent the strangers a thing
    assert not plain.stop()["armed"]
