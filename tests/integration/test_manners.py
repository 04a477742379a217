"""Good manners toward the autopilot: someone else's vehicle is left alone unless we are told, every
parameter the companion changed is put back on every way a flight ends, and the failsafe
settings are shown before anything arms."""

from __future__ import annotations

import math
import signal
import time

import pytest
from pymavlink import mavutil

from helpers.processes import LOCKSTEP, LOCKSTEP_SPEEDUP, PAPER, PAPER_OUTPUT, POSITION_WAIT, RelayProcess

from .test_companion_e2e import segments
from .test_sitl_pymavlink import take_off

pytestmark = pytest.mark.integration

ARDUPILOT_DEFAULTS = {"GUID_OPTIONS": 0.0, "GUID_TIMEOUT": 3.0}


def test_an_armed_vehicle_held_by_another_station_is_refused_unless_taken_over(sitl, client, companion):
    """Another ground station holds an armed vehicle at 2.5 m: the companion refuses it, says why and
    leaves it exactly as it was (exit 1, still armed and holding); with --take-over it flies the
    mission from there (no take-off) and lands."""
    s = sitl(*PAPER, *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    gcs = client(s.url, source_system=200)
    take_off(gcs)
    c = companion("missions/hold.toml", s.url, *PAPER_OUTPUT)
    code, out = c.finish(timeout=60)
    assert code == 1 and "already armed" in out and "--take-over" in out, out
    assert "never flew this vehicle" in out and "holding, then landing" not in out
    h = gcs.latest("HEARTBEAT")
    assert h.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert -gcs.latest("LOCAL_POSITION_NED").z > 2.0  # still up there
    c = companion("missions/hold.toml", s.url, *PAPER_OUTPUT, "--take-over")
    code, out = c.finish(timeout=180)
    assert code == 0, out
    assert "skipped (taken over in the air)" in out
    assert not s.stop()["armed"]


def ardupilot_params(gcs) -> dict:
    return {name: gcs.param(name) for name in ARDUPILOT_DEFAULTS}


def test_parameters_are_put_back_after_ctrl_c_and_after_a_gcs_takes_control(sitl, client, companion):
    s = sitl("--flavour", "ardupilot", *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    gcs = client(s.url, source_system=200)
    gcs.wait("HEARTBEAT")
    assert ardupilot_params(gcs) == ARDUPILOT_DEFAULTS
    c = companion("missions/hold.toml", s.url, *POSITION_WAIT)
    c.wait_for("step hold", timeout=120)
    c.proc.send_signal(signal.SIGINT)
    code, out = c.finish(timeout=120)
    assert code == 130 and "GUID_TIMEOUT put back to 3" in out, out
    assert ardupilot_params(client(s.url, source_system=203)) == ARDUPILOT_DEFAULTS
    c = companion("missions/hold.toml", s.url)
    c.wait_for("step hold", timeout=120)
    other = client(s.url, source_system=201)  # a fresh station (the first one's socket is full of telemetry)
    other.wait("HEARTBEAT")
    assert other.set_mode(17) == 0  # BRAKE: a ground station takes control
    code, out = c.finish(timeout=120)
    assert code == 1 and "left offboard" in out and "GUID_OPTIONS put back to 0" in out, out
    assert ardupilot_params(client(s.url, source_system=202)) == ARDUPILOT_DEFAULTS


def test_after_a_lost_link_the_parameters_not_put_back_are_listed(sitl, companion, tmp_path):
    """The link stays down past link_lost_s (3 s): the companion cannot reach the autopilot to put
    its parameters back; it says which, in its output and in the flight record."""
    s = sitl("--flavour", "ardupilot", "--wait-for-setpoints", "0.05", speedup=2.0)
    r = RelayProcess(s.url)
    try:
        c = companion("missions/hold.toml", r.url, *POSITION_WAIT)
        c.wait_for("step hold", timeout=120)
        r.proc.send_signal(signal.SIGSTOP)  # the link goes down for good
        code, out = c.finish(timeout=120)
    finally:
        r.proc.send_signal(signal.SIGCONT)
        r.stop()
    assert code == 3, out
    assert "could NOT be put back" in out, out
    summary = segments(c.flight_dir())["_summary"]
    assert set(summary["params_not_restored"]) >= {"GUID_OPTIONS", "GUID_TIMEOUT"}, summary


def test_the_pre_flight_report_shows_the_failsafe_settings_and_warns(sitl, companion):
    s = sitl(*PAPER, *LOCKSTEP, "--param", "COM_OF_LOSS_T=3", speedup=LOCKSTEP_SPEEDUP)
    c = companion("missions/hold.toml", s.url, *PAPER_OUTPUT)
    code, out = c.finish(timeout=180)
    assert code == 0, out
    assert "pre-flight: px4 failsafe settings" in out and "COM_OF_LOSS_T" in out
    assert "WARNING: COM_OF_LOSS_T 3 s: a dead companion is noticed late" in out
    assert out.index("pre-flight") < out.index("step 1: takeoff")
    meta = (c.flight_dir() / "metadata.json").read_text()
    assert "COM_OF_LOSS_T" in meta and math.isfinite(time.time())
