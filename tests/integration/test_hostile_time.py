"""Telemetry whose timestamps cannot be trusted, injected on the vehicle's side of a real UDP path
(tests/helpers/mitm.py) with the autopilot's own system and component id.

The field defect this closes: ten HIGHRES_IMU frames stamped in UNIX time jumped the companion's
clock 1.7e9 s ahead; its controller's time stuck, one tilted setpoint was re-sent for ever and the
mission neither ended nor timed out. Here every class of bad stamp arrives mid-hold, ten frames
each, and the flight must not notice: it completes, the hold lasts its 20 vehicle seconds (the
clock neither jumped nor stalled), the position stays within the clean hold's bounds, and every
forged frame is counted where it was refused.

Bounds: a clean hold in calm air tracks to about 1 cm RMS (docs/faults.md); 5 cm RMS and 15 cm peak
are the waypoint square's clean bounds, far below what any one forged sample believed would do
(a 30 deg attitude flown for one tick moves the vehicle ~1 cm, but a clock 1 h ahead ends the hold
at once, and a position 5 m off commands the full tilt).
"""

from __future__ import annotations

import json
import math
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from helpers.mitm import Mitm
from helpers.missions import hold_mission
from helpers.processes import LOCKSTEP, LOCKSTEP_SPEEDUP, PAPER, PAPER_OUTPUT

from companion.mavlink.boot_time import BOOT_MS_PERIOD_S

pytestmark = pytest.mark.integration
ACCELERATIONS = mavlink.HIGHRES_IMU_UPDATED_XACC | mavlink.HIGHRES_IMU_UPDATED_YACC | mavlink.HIGHRES_IMU_UPDATED_ZACC

def _attacks(mitm: Mitm) -> dict[str, int]:
    """Ten frames of each class, built from the newest genuine messages."""
    f = mitm.forge
    att = mitm.latest("ATTITUDE_QUATERNION")
    pos = mitm.latest("LOCAL_POSITION_NED")
    unix_us = int(time.time() * 1e6)
    tilted = (math.cos(math.radians(15)), math.sin(math.radians(15)), 0.0, 0.0)  # 30 deg of roll
    frames = {
        "unix_time_imu": [f.highres_imu_encode(unix_us + 1000 * k, 0.0, 0.0, -9.81, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                                               ACCELERATIONS) for k in range(10)],
        "jump_forward": [f.attitude_quaternion_encode(att.time_boot_ms + 3_600_000 + k, *tilted, 0, 0, 0)
                         for k in range(10)],
        "backwards": [f.local_position_ned_encode(max(att.time_boot_ms - 30_000, 1) + k, pos.x + 5.0, pos.y,
                                                  pos.z, 0, 0, 0) for k in range(10)],
    }
    for msgs in frames.values():
        mitm.inject(msgs)
    # repeats of the newest position, taken now and sent back to back: built with the others, they were
    # up to 40 injections old when sent, and on a loaded host (2 ms gaps slept as 10) that is more than
    # the 1 s behind that makes a stamp "backwards", not an older sample (CI of 9215b74: 6 of 10)
    pos = mitm.latest("LOCAL_POSITION_NED")
    frames["repeat"] = [f.local_position_ned_encode(pos.time_boot_ms, pos.x + 2.0, pos.y, pos.z, 0, 0, 0)
                        for _ in range(10)]
    mitm.inject(frames["repeat"], gap_s=0.0)
    return {k: len(v) for k, v in frames.items()}


def test_no_timestamp_moves_or_stalls_the_companion_clock(sitl, companion):
    s = sitl(*PAPER, *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    host, port = s.url.split(":")
    mitm = Mitm((host, int(port)))
    try:
        c = companion("missions/hold.toml", mitm.url, *PAPER_OUTPUT)
        c.wait_for("step hold")
        time.sleep(1.0)  # 4 vehicle seconds into the hold
        sent = _attacks(mitm)
        code, out = c.finish(timeout=120)
    finally:
        mitm.close()
    assert code == 0, out
    data = json.loads((c.flight_dir() / "segments.json").read_text())
    hold = next(x for x in data["segments"] if x["name"] == "hold")
    assert abs((hold["t_end"] - hold["t_start"]) - 20.0) < 0.5, hold
    assert hold["rms_error_m"] < 0.05 and hold["peak_error_m"] < 0.15, hold
    stats = data["link_stats"]
    assert stats.get("stamp_unix_time", 0) >= sent["unix_time_imu"], stats
    assert stats.get("stamp_jump_forward", 0) >= sent["jump_forward"], stats
    assert stats.get("stamp_backwards", 0) >= sent["backwards"], stats
    assert data["older_samples"] >= sent["repeat"], data
    # as in the wrap test below: before OFFBOARD the vehicle runs free, and on a loaded host one gap
    # there may drop a fraction of a second of catch-up (0.103 s in a fresh-clone CI with six
    # workers); a stamp that moved the clock (an hour forward, 30 s back) would drop seconds
    assert data["controller_time"]["dropped_s"] < 0.25, data["controller_time"]


WRAP_AFTER_S = 40.0
"""simulated seconds from the vehicle's start to the wrap of its time_boot_ms: the 40 s hold
starts 15-20 s after start here (connection, take-off and offboard at up to 8x), so the wrap falls
inside it even if connecting took another 2.5 s of wall time"""

HOLD_ACROSS_THE_WRAP = hold_mission("hold_wrap", 40.0, volume=(10.0, 6.0))


def test_a_vehicle_up_49_7_days_wraps_time_boot_ms_mid_hover_and_the_mission_completes(sitl, companion, tmp_path):
    """``sitl --boot-time`` starts the vehicle 40 s before its time_boot_ms wraps (its time_usec
    runs on). In lockstep the hold crosses the wrap and must not notice: it completes, lasts its 40
    vehicle seconds, holds to the clean hold's bounds, and nothing was refused. Before the wrap was
    told from a jump, every attitude and position after it was refused as going backwards (the
    IMU's time_usec kept the old base alive, so it was never rebased) and the hold timed out."""
    mission = tmp_path / "hold_wrap.toml"
    mission.write_text(HOLD_ACROSS_THE_WRAP)
    s = sitl(*PAPER, *LOCKSTEP, "--boot-time", f"{BOOT_MS_PERIOD_S - WRAP_AFTER_S:.3f}", speedup=LOCKSTEP_SPEEDUP)
    c = companion(str(mission), s.url, *PAPER_OUTPUT)
    code, out = c.finish(timeout=240)
    assert code == 0, out
    data = json.loads((c.flight_dir() / "segments.json").read_text())
    hold = next(x for x in data["segments"] if x["name"] == "hold")
    assert hold["t_start"] < BOOT_MS_PERIOD_S < hold["t_end"], hold  # the wrap fell inside the hold
    assert abs((hold["t_end"] - hold["t_start"]) - 40.0) < 0.5, hold
    assert hold["rms_error_m"] < 0.05 and hold["peak_error_m"] < 0.15, hold
    stats = data["link_stats"]
    assert stats.get("stamp_wrapped") == 1, stats
    assert not any(stats.get(k) for k in ("stamp_backwards", "stamp_jump_forward", "stamp_rebased")), stats
    # before OFFBOARD the vehicle runs free (lockstep holds it only while setpoints fly it): on a
    # loaded host one gap there may drop a fraction of a second of catch-up (0.074 s seen in CI);
    # a wrap taken for a jump would drop seconds
    assert data["controller_time"]["dropped_s"] < 0.25, data["controller_time"]
