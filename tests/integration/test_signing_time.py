"""MAVLink 2 signing over time, over UDP on 127.0.0.1 with separate processes: timestamps follow
the clock (10 µs units since 2015-01-01 UTC), so ends that start minutes apart still trust each
other; a genuine frame timestamped far in the future is refused without locking anyone out; and a
companion that cannot connect says which rule the vehicle's frames broke."""

from __future__ import annotations

import math
import socket
import threading
import time
from collections import Counter

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.commands import FORCE_ARM_DISARM
from companion.mavlink.modes import px4_custom_mode
from companion.control import quaternion as quat
from companion.mavlink.signing import signing_timestamp, write_key_file

from helpers.missions import hold_mission
from helpers.processes import free_udp_port
from .test_companion_e2e import WAIT, segments
from .test_link_faults import Observer

pytestmark = pytest.mark.integration

SPEEDUP = 2.0
"""both vehicles of the first test run at once beside two companions on this 2-core host"""
LATER_S = 65.0
"""more than the one minute a new stream may lag our clock (NEW_STREAM_WINDOW)"""
SHORT_HOLD = hold_mission("short", 8.0)


def test_ends_started_more_than_a_minute_apart_trust_each_other(sitl, companion, tmp_path, record_property):
    """Two pairs, one wait. A vehicle runs alone for 65 s before its companion starts; another
    companion waits 65 s for its vehicle to start (heartbeating into nothing meanwhile). Each end's
    signing timestamps must be its clock, so each receiver (which judges a new stream against its
    own clock: at most 60 s behind) accepts the other, and both short missions fly signed.
    pymavlink's counter (the start time plus 10 us per frame sent) would be ~65 s behind the clock
    in both cases: the late companion would refuse the old vehicle's heartbeats as stale, and the
    new vehicle would drop the old companion's frames (and so never learn its address)."""
    key_file = tmp_path / "mavlink.key"
    key = write_key_file(key_file)
    env = {"MAVLINK_SIGNING_KEY": key.hex()}
    mission = tmp_path / "short.toml"
    mission.write_text(SHORT_HOLD)
    old_vehicle = sitl("--signing-key-file", str(key_file), *WAIT, speedup=SPEEDUP)
    new_port = free_udp_port()
    early = companion(str(mission), f"127.0.0.1:{new_port}", "--connect-timeout", str(LATER_S + 30), env=env)
    time.sleep(LATER_S)
    new_vehicle = sitl("--signing-key-file", str(key_file), *WAIT, speedup=SPEEDUP, port=new_port)
    late = companion(str(mission), old_vehicle.url, env=env)
    results = {}
    for name, c, v in (("late companion, old vehicle", late, old_vehicle),
                       ("early companion, new vehicle", early, new_vehicle)):
        code, out = c.finish(timeout=180)
        report = v.stop()
        results[name] = (code, report["signing_rejections"])
        assert code == 0, (name, out[-3000:])
        summary = segments(c.flight_dir())["_summary"]
        assert summary["signing"] != "off" and summary["signing_rejections"] == {}, (name, summary)
        assert report["signing_rejections"] == {}, (name, report["signing_rejections"])
        assert not report["armed"]
    record_property("results", results)


def signer(sysid: int, compid: int, key: bytes, timestamp: int, link_id: int = 0) -> mavlink.MAVLink:
    """A sender with pymavlink's own signing state, starting at ``timestamp`` (1 unit more per frame:
    over these tests' few seconds, that is the clock it was given)."""
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    mav.signing.secret_key, mav.signing.link_id, mav.signing.sign_outgoing = key, link_id, True
    mav.signing.timestamp = timestamp
    return mav


class FakeVehicle:
    """A PX4-looking heartbeat source signed with ``key`` on a clock ``offset_s`` from ours: it
    answers whoever talks to it with 5 Hz heartbeats."""

    def __init__(self, key: bytes, offset_s: float) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.url = f"127.0.0.1:{self.sock.getsockname()[1]}"
        self.mav = signer(1, 1, key, signing_timestamp(time.time() + offset_s))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        peer = None
        while not self._stop.is_set():
            try:
                _, peer = self.sock.recvfrom(4096)
            except OSError:
                pass
            if peer is not None:
                hb = self.mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                               mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, px4_custom_mode("HOLD"),
                                               mavlink.MAV_STATE_STANDBY)
                self.sock.sendto(hb.pack(self.mav), peer)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


@pytest.mark.parametrize("offset_s, key, cause", [
    (-300.0, "same", "timestamped more than 60 s behind our clock"),
    (+300.0, "same", "timestamped more than 60 s ahead of our clock"),
    (0.0, "other", "signed with another key"),
])
def test_a_companion_that_cannot_trust_the_vehicle_names_the_cause(companion, tmp_path, offset_s, key, cause):
    """A vehicle whose clock is five minutes behind or ahead of ours, or that signs with another
    key: the companion refuses its heartbeats and its error says which of these it is (not always
    "another key")."""
    ours = bytes(range(32))
    fake = FakeVehicle(ours if key == "same" else bytes(32), offset_s)
    try:
        code, out = companion("missions/hold.toml", fake.url, "--connect-timeout", "3",
                              env={"MAVLINK_SIGNING_KEY": ours.hex()}).finish(timeout=30)
    finally:
        fake.stop()
    assert code == 1 and cause in out, out


ROGUE_Q = list(quat.from_euler(math.radians(60), 0.0, 0.0))


def test_a_far_future_frame_on_another_link_is_refused_and_the_companion_keeps_control(
        sitl, companion, tmp_path, record_property):
    """Mid-hold, a system holding the key signs on link 7 with a clock a day ahead: 60-degree,
    full-thrust setpoints and force-disarms, posing as the companion (255/191), at 50 Hz for 2 s.
    Every one must be refused as a future timestamp (more than 60 s ahead of the vehicle's clock)
    and never flown; the companion keeps control and completes the hold within the clean bounds of
    test_signing.py (RMS < 5 cm, peak < 15 cm; a 60-degree setpoint flown for 20 ms alone would
    move it further); and a ground station that starts after
    the attack (a new stream, judged against the vehicle's clock and not the attacker's timestamp)
    is answered."""
    key_file = tmp_path / "mavlink.key"
    key = write_key_file(key_file)
    s = sitl("--signing-key-file", str(key_file), *WAIT, speedup=SPEEDUP)
    before = Observer(s.url, signing_key=key)
    c = companion("missions/hold.toml", s.url, env={"MAVLINK_SIGNING_KEY": key.hex()})
    c.wait_for("] step hold", timeout=90)
    time.sleep(2.0)
    rogue = signer(255, 191, key, signing_timestamp(time.time() + 86400.0), link_id=7)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent: Counter[str] = Counter()
    for i in range(100):
        setpoint = rogue.set_attitude_target_encode(0, 1, 1, 0, ROGUE_Q, 0, 0, 0, 1.0)
        sock.sendto(setpoint.pack(rogue), ("127.0.0.1", s.port))
        sent["SET_ATTITUDE_TARGET"] += 1
        if i % 10 == 0:
            cmd = rogue.command_long_encode(1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                            0, FORCE_ARM_DISARM, 0, 0, 0, 0, 0)
            sock.sendto(cmd.pack(rogue), ("127.0.0.1", s.port))
            sent["COMMAND_LONG"] += 1
        time.sleep(0.02)
    sock.close()
    after = Observer(s.url, signing_key=key)  # a new stream, after the attack
    end = time.monotonic() + 10
    while time.monotonic() < end and not after.positions:
        time.sleep(0.1)
    answered_after = len(after.positions)
    code, out = c.finish()
    after.stop()
    before.stop()
    report = s.stop()
    assert code == 0, out
    hold = segments(c.flight_dir())["hold"]
    assert hold["ok"] and hold["rms_error_m"] < 0.05 and hold["peak_error_m"] < 0.15, hold
    dropped = report["signing_rejections"]
    for kind, n in sent.items():
        assert dropped.get(f"future timestamp {kind}", 0) == n, (sent, dropped)
    assert answered_after > 0, "a ground station starting after the attack got no telemetry"
    assert any(t.startswith("Dropped future timestamp from 255: SET_ATTITUDE") for t in before.texts), before.texts
    record_property("sent", dict(sent))
    record_property("dropped", dropped)
    record_property("hold", {k: hold[k] for k in ("rms_error_m", "peak_error_m")})
