"""Parameters never kill, over real UDP against the vehicle process: PARAM_SET at every edge of every
documented range while it hovers, the values that used to kill it, and the deliberate faults, which
end in defined failsafes while the process keeps answering. (The property tests over the whole
ranges are in-process: tests/sitl/test_parameters.py.)"""

from __future__ import annotations

import math
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat

from .test_sitl_pymavlink import HOLD, take_off

pytestmark = pytest.mark.integration

SPEEDUP = 4.0
UPRIGHT_DEG = 85.0
ARMED = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
"""as in tests/sitl/test_parameters.py: the position loop's 70° limit and the landing transient"""
WINDY = ("--param", "SIM_WIND_N=3", "--param", "SIM_TURB_SIGMA=0.6")


def set_param(c, name: str, value: float) -> float:  # type: ignore[no-untyped-def]
    c.m.mav.param_set_send(1, 1, name.encode(), value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
    return c.wait("PARAM_VALUE", lambda p: p.param_id == name, timeout=5).param_value


def hold(c, seconds_sim: float) -> float:  # type: ignore[no-untyped-def]
    """Read telemetry for ``seconds_sim`` of vehicle time; the largest tilt seen [deg]."""
    worst = 0.0
    end = time.monotonic() + seconds_sim / SPEEDUP
    while time.monotonic() < end:
        m = c.recv(0.02)
        if m is not None and m.get_type() == "ATTITUDE_QUATERNION":
            worst = max(worst, math.degrees(quat.tilt_angle((m.q1, m.q2, m.q3, m.q4))))
    return worst


def test_values_that_used_to_kill_the_vehicle_are_refused_and_it_flies_on(sitl, client):
    """Values inside the old ranges that crashed the process (SIM_TORQUE_Z = 1: the plant's
    integration raised ValueError, the step loop died with it) or flipped the vehicle (POS_W_C 5,
    SIM_TORQUE_X 1, SIM_FORCE_X 50, SIM_MASS_FAC 0.5, SIM_WIND_N 20, SIM_TURB_SIGMA 5): each is
    refused now (the old value echoed) and the vehicle hovers on, upright and answering."""
    s = sitl(*WINDY, speedup=SPEEDUP)
    c = client(s.url)
    take_off(c)
    killers = {"SIM_TORQUE_Z": 1.0, "POS_W_C": 5.0, "SIM_TORQUE_X": 1.0, "SIM_FORCE_X": 50.0,
               "SIM_MASS_FAC": 0.5, "SIM_WIND_N": 20.0, "SIM_TURB_SIGMA": 5.0}
    worst = 0.0
    for name, value in killers.items():
        echoed = set_param(c, name, value)
        worst = max(worst, hold(c, 4.0))
        assert s.alive(), f"the vehicle died after {name} = {value:g}"
        assert echoed != value, (name, echoed)
    assert worst < UPRIGHT_DEG, worst
    c.wait("HEARTBEAT",
           lambda h: h.get_srcSystem() == 1 and h.base_mode & ARMED and h.custom_mode == HOLD)
    report = s.stop()
    assert report["armed"] and report["stats"].get("internal_errors", 0) == 0
    assert sum(v for k, v in report["rejections"].items() if k.startswith("param set")) == len(killers)


def test_every_parameter_at_both_edges_of_its_range_over_udp(sitl, client, record_property):
    """Hovering in 3 m/s of wind with 0.6 m/s of turbulence, each writable parameter that is not a
    deliberate fault is set to its maximum for 1 s of vehicle time, then its minimum for 1 s, then
    back: every value is accepted as sent (REAL32 edges included), the vehicle stays upright
    (< 85°) and armed in HOLD, and the process answers throughout."""
    from sitl.autopilot.parameters import COMMON_ROWS, PX4_ROWS

    s = sitl(*WINDY, speedup=SPEEDUP)
    c = client(s.url)
    take_off(c)
    worst: dict[str, float] = {}
    for row in PX4_ROWS + COMMON_ROWS:
        if row.read_only or row.fault or row.name in ("SIM_WIND_N", "SIM_TURB_SIGMA"):
            continue
        default = c.param(row.name)
        for value in (row.maximum, row.minimum):
            echoed = set_param(c, row.name, value)
            assert echoed == pytest.approx(value, rel=1e-6, abs=1e-6), (row.name, value, echoed)
            worst[f"{row.name}={value:g}"] = hold(c, 1.0)
        set_param(c, row.name, default)
        assert s.alive(), row.name
    record_property("worst_tilt_deg", max(worst.values()))
    assert max(worst.values()) < UPRIGHT_DEG, sorted(worst.items(), key=lambda kv: -kv[1])[:5]
    c.wait("HEARTBEAT",
           lambda h: h.get_srcSystem() == 1 and h.base_mode & ARMED and h.custom_mode == HOLD)
    report = s.stop()
    assert report["armed"] and report["terminated"] is None and report["halted"] is None
    assert report["stats"].get("internal_errors", 0) == 0 and report["stats"].get("telemetry_errors", 0) == 0


def test_deliberate_faults_end_in_defined_failsafes_and_the_process_keeps_answering(sitl, client, record_property):
    """A dead motor (SIM_MOT1_EFF = 0) in the hover: the loss-of-control failsafe terminates the
    flight (STATUSTEXT "Loss of control ... motors off", disarmed, arming refused). Then a NaN plant
    state (SIM_STATE_NAN = 1): a numerical fault, reported ("Numerical fault (non-finite state)",
    "World halted"), the world halted; the process still answers PING, parameter reads and
    commands, and reports both in its exit report."""
    s = sitl(speedup=SPEEDUP)
    c = client(s.url)
    take_off(c)
    set_param(c, "SIM_MOT1_EFF", 0.0)
    text = c.text("Loss of control", timeout=10)
    assert text.endswith("motors off") or "motors" in text, text
    c.wait("HEARTBEAT", lambda h: h.get_srcSystem() == 1 and not h.base_mode & ARMED)
    assert c.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavutil.mavlink.MAV_RESULT_DENIED
    assert "restart" in c.text("Arming denied")
    set_param(c, "SIM_STATE_NAN", 1)
    assert "non-finite state" in c.text("Numerical fault", timeout=10)
    c.text("World halted")
    c.m.mav.ping_send(1234, 99, 0, 0)
    assert c.wait("PING", lambda p: p.seq == 99).time_usec == 1234
    assert c.param("SIM_MASS_FAC") == pytest.approx(1.0)
    t0 = c.latest("SYSTEM_TIME").time_boot_ms
    time.sleep(0.5)
    assert c.latest("SYSTEM_TIME").time_boot_ms > t0  # the clock runs on
    report = s.stop()
    record_property("events", report["events"])
    assert report["halted"] == "non-finite state" and report["terminated"].startswith("Numerical fault")
    assert any(t.startswith("Loss of control") for _, t in report["events"]), report["events"]
