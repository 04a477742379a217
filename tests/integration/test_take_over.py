"""``--take-over`` mid-failsafe: a companion killed outright (kill -9) in OFFBOARD leaves PX4's
offboard-loss failsafe descending; a restarted companion told to take the vehicle over must leave
that descent alone, and must not "hold" a vehicle armed on the ground. Real processes over UDP:
the bundled vehicle (paper flavour, PX4 rules) at 2x, not in lockstep (the failsafe is the subject,
and lockstep would stop the world while the companion is dead)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from helpers.processes import PAPER, PAPER_OUTPUT

from .test_sitl_pymavlink import PREARM

pytestmark = pytest.mark.integration

ON_GROUND = mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND
ARMED = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED


def mission(tmp_path: Path, name: str, hold_s: float) -> str:
    p = tmp_path / f"{name}.toml"
    p.write_text(f'''name = "{name}"
[controller]
position = "ism_do"

[[steps]]
action = "takeoff"
altitude_m = 2.5

[[steps]]
action = "offboard"

[[steps]]
name = "hold"
action = "hold"
duration_s = {hold_s}
position_ned_m = [0.0, 0.0, -2.5]

[[steps]]
action = "land"
''')
    return str(p)


def test_a_take_over_during_the_offboard_loss_descent_leaves_it_to_the_autopilot(sitl, client, companion, tmp_path):
    """The first companion is killed 2 s into its hold; the vehicle's failsafe (COM_OF_LOSS_T 1 s)
    descends at MPC_LAND_SPEED, slowed to 0.2 m/s so that the descent from 2.5 m lasts 12.5 vehicle
    seconds, longer than a companion takes to start. The second companion, --take-over, refuses
    (exit 1, the reason named) and never switches the mode: the failsafe is never cleared and the
    vehicle lands. The old code took the vehicle over, which cleared the failsafe ("Failsafe
    cleared by mode change") and flew the hold from where it was, lower."""
    s = sitl(*PAPER, "--param", "MPC_LAND_SPEED=0.2", speedup=2.0)
    gcs = client(s.url, source_system=200)
    first = companion(mission(tmp_path, "first", 120.0), s.url, *PAPER_OUTPUT)
    gcs.text("Mode OFFBOARD", timeout=120)
    time.sleep(1.0)  # 2 vehicle seconds into the hold
    first.proc.kill()  # kill -9: no landing, no goodbye
    first.proc.wait()
    gcs.text("Failsafe: offboard lost", timeout=10)
    z_at_failsafe = gcs.latest("LOCAL_POSITION_NED").z
    second = companion(mission(tmp_path, "second", 2.0), s.url, *PAPER_OUTPUT, "--take-over")
    code, out = second.finish(timeout=60)
    z_after = gcs.latest("LOCAL_POSITION_NED").z
    assert code == 1, out
    assert "not taken over: the autopilot reports a failsafe in progress" in out, out
    assert "never flew this vehicle" in out and "holding, then landing" not in out, out
    assert z_after > z_at_failsafe, (z_at_failsafe, z_after)  # still descending meanwhile (NED: down is +)
    gcs.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == ON_GROUND, timeout=30)
    gcs.wait("HEARTBEAT", lambda h: h.get_srcSystem() == 1 and not h.base_mode & ARMED, timeout=20)
    assert not any("Failsafe cleared" in t for t in gcs.texts), gcs.texts


def test_a_vehicle_armed_on_the_ground_is_not_taken_over(sitl, client, companion, tmp_path):
    """A ground station arms the vehicle and leaves it on the ground: --take-over refuses (exit 1)
    instead of skipping the take-off and holding it there in OFFBOARD; nothing is armed, switched or
    streamed by the companion, and the vehicle disarms by itself (COM_DISARM_PRFLT)."""
    s = sitl(*PAPER, "--param", "COM_DISARM_PRFLT=60", speedup=2.0)
    gcs = client(s.url, source_system=200)
    gcs.wait("SYS_STATUS", lambda m: m.onboard_control_sensors_health & PREARM, timeout=20)
    assert gcs.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
    c = companion(mission(tmp_path, "ground", 2.0), s.url, *PAPER_OUTPUT, "--take-over")
    code, out = c.finish(timeout=60)
    assert code == 1, out
    assert "not taken over: the vehicle is armed on the ground" in out, out
    assert not any("Mode OFFBOARD" in t for t in gcs.texts), gcs.texts
    assert gcs.latest("EXTENDED_SYS_STATE").landed_state == ON_GROUND
