"""Hostile and malformed input while the vehicle flies offboard: every bad datagram or value is
dropped and counted, the vehicle keeps flying what the last valid setpoint said."""

from __future__ import annotations

import math
import random
import socket
import threading

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.commands import FORCE_ARM_DISARM
from companion.control import quaternion as quat

from helpers.processes import quat_angle_deg
from .test_sitl_pymavlink import OFFBOARD, stream, switch_to_offboard, take_off

pytestmark = pytest.mark.integration

NO_SUCH_MODE = (42, 7)
"""DO_SET_MODE param2, param3 that name no PX4 mode"""
NO_SUCH_COMMAND = 31999
"""a MAV_CMD number no dialect defines"""


def packed(msg_fn, *args, sysid=255) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=190)
    return getattr(mav, msg_fn)(*args).pack(mav)


def stop_while_streaming(s, c, q, thrust) -> dict:
    """The vehicle's final report, taken with the valid setpoint stream still going: a pause of a
    second of vehicle time is offboard loss (LAND), and a test process starved on a busy host can
    pause that long between its last setpoint and the vehicle's stop."""
    done = threading.Event()

    def keep_streaming() -> None:
        while not done.is_set():
            c.attitude_target(q, (0.0, 0.0, 0.0), thrust)
            c.recv(0.01)

    streamer = threading.Thread(target=keep_streaming, daemon=True)
    streamer.start()
    try:
        return s.stop()
    finally:
        done.set()
        streamer.join()


def garbage(q_ok, hover, rng: random.Random) -> dict[str, list[bytes]]:
    """Every kind of bad input, as datagrams, by kind."""
    good = packed("set_attitude_target_encode", 0, 1, 1, 0, list(q_ok), 0.0, 0.0, 0.0, hover)
    corrupted = bytearray(good)
    corrupted[12] ^= 0xFF  # a payload byte: the CRC no longer matches
    sat = "set_attitude_target_encode"
    return {
        "truncated": [good[: len(good) // 2]],
        "corrupted": [bytes(corrupted)],
        "oversized": [bytes(rng.getrandbits(8) for _ in range(10_000))],
        "random": [bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 300))) for _ in range(200)],
        "wrong_target": [
            packed(sat, 0, 7, 1, 0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.9),  # another vehicle
            packed(sat, 0, 1, 99, 0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.9),  # another component
            packed("command_long_encode", 9, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                   0, FORCE_ARM_DISARM, 0, 0, 0, 0, 0),  # force disarm, not us
        ],
        "bad_values": [
            packed(sat, 0, 1, 1, 0, [math.nan, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, hover),
            packed(sat, 0, 1, 1, 0, [math.inf, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, hover),
            packed(sat, 0, 1, 1, 0, [2.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, hover),  # not unit
            packed(sat, 0, 1, 1, 0, [0.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, hover),  # zero quaternion
            packed(sat, 0, 1, 1, 0, list(q_ok), 0.0, 0.0, 0.0, 1.5),  # thrust > 1
            packed(sat, 0, 1, 1, 0, list(q_ok), 0.0, 0.0, 0.0, -0.1),  # thrust < 0
            packed(sat, 0, 1, 1, 0, list(q_ok), 0.0, 0.0, 0.0, math.nan),
            packed(sat, 0, 1, 1, 0, list(q_ok), math.nan, 0.0, 0.0, hover),  # NaN rate
            packed(sat, 0, 1, 1, 0, list(q_ok), 1e6, 0.0, 0.0, hover),  # absurd rate
        ],
        "bad_commands": [
            packed("command_long_encode", 1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, math.nan, math.nan, math.nan, 0, 0, 0,
                   0),
            packed("command_long_encode", 1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0,
                   mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, *NO_SUCH_MODE, 0, 0, 0, 0),
            packed("command_long_encode", 1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 7.0, 0, 0, 0, 0, 0, 0),
                         # arm with 7?
            packed("command_long_encode", 1, 1, NO_SUCH_COMMAND, 0, 0, 0, 0, 0, 0, 0, 0),
            packed("command_long_encode", 1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, math.inf, -5, 0, 0, 0, 0, 0),
            packed("param_set_encode", 1, 1, b"SIM_MASS_FAC", math.nan, mavlink.MAV_PARAM_TYPE_REAL32),
            packed("param_set_encode", 1, 1, b"NO_SUCH_PARAM", 1.0, mavlink.MAV_PARAM_TYPE_REAL32),
        ],
    }


def test_bad_input_is_dropped_counted_and_changes_nothing(sitl, client):
    """GIVEN the vehicle in OFFBOARD holding a level attitude WHEN truncated, corrupted, oversized,
    random, mis-addressed and out-of-range datagrams arrive between valid setpoints THEN it stays
    armed in OFFBOARD, its attitude target stays the last valid one, and every bad input is
    counted by kind (and none raised inside the vehicle)."""
    s = sitl(speedup=2.0)
    c = client(s.url)
    att = take_off(c)
    hover = c.param("MPC_THR_HOVER")
    q_ok = quat.from_yaw(quat.to_euler((att.q1, att.q2, att.q3, att.q4))[2])
    stream(c, q_ok, hover, 1.0)
    switch_to_offboard(c, q_ok, hover)

    rng = random.Random(7)
    bad = garbage(q_ok, hover, rng)
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    got = []
    for datagrams in bad.values():
        for d in datagrams:
            raw.sendto(d, ("127.0.0.1", s.port))
            got += stream(c, q_ok, hover, 0.01, period=0.01)  # keep the valid stream going
    got += stream(c, q_ok, hover, 1.0)
    raw.close()

    heartbeats = [m for m in got if m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1]
    assert heartbeats and all(h.custom_mode == OFFBOARD and h.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
                              for h in heartbeats)
    targets = [m for m in got if m.get_type() == "ATTITUDE_TARGET"]
    assert targets and all(quat_angle_deg(t.q, q_ok) < 0.01 for t in targets)  # float32 on the wire
    assert all(abs(t.thrust - hover) < 1e-6 for t in targets)
    attitudes = [m for m in got if m.get_type() == "ATTITUDE_QUATERNION"][-50:]
    assert max(quat_angle_deg((a.q1, a.q2, a.q3, a.q4), q_ok) for a in attitudes) < 2.0

    report = stop_while_streaming(s, c, q_ok, hover)
    assert "Rejected" in c.text("Rejected", timeout=1.0)  # sent before the stop: queued or already read
    st, rej = report["stats"], report["rejections"]
    assert report["armed"] and report["mode"] == "OFFBOARD"
    assert st.get("internal_errors", 0) == 0 and st.get("handler_errors", 0) == 0
    assert st["oversized"] == 1
    assert st["truncated"] >= 1
    assert st["bad_data"] >= 1 + 50  # the corrupted one, and most of 200 random datagrams
    assert st["wrong_target"] == 3
    for reason in ("non-finite quaternion", "non-unit quaternion", "thrust outside [0, 1]",
                   "non-finite body rate", "body rate out of range"):
        assert rej[f"attitude target: {reason}"] >= 1, (reason, rej)
    assert sum(v for k, v in rej.items() if k.startswith("command")) >= 4
    assert sum(v for k, v in rej.items() if k.startswith("param set")) == 2
    assert st["rejected"] >= 9
