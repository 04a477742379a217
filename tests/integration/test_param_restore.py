"""Every parameter the companion writes is put back on every way a flight ends — a mission's
set_param steps and the take-off's own MIS_TAKEOFF_ALT too — except those a step marks ``keep``;
the summary names each. Real processes: the bundled vehicle in lockstep, the companion over UDP,
SIGTERM to the companion, a relay that loses the link and gives it back."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest

from helpers.missions import flight_mission, sim_param, step
from helpers.processes import LOCKSTEP, LOCKSTEP_SPEEDUP, PAPER, PAPER_OUTPUT, RelayProcess

from .test_companion_e2e import segments

pytestmark = pytest.mark.integration

DEFAULTS = {"MIS_TAKEOFF_ALT": 2.5, "MPC_LAND_SPEED": 0.7, "SIM_WIND_E": 0.0, "COM_DISARM_LAND": 2.0}
"""the bundled vehicle's values at boot (sitl/autopilot/parameters.py, the paper scenario's calm air)"""


def params_mission(tmp_path: Path, hold_s: float = 60.0) -> str:
    """Take-off to 1.5 m (PX4 takes it from MIS_TAKEOFF_ALT, 2.5 m at boot), offboard, three
    set_param steps (one kept), a long hold to be interrupted in, land."""
    p = tmp_path / "params.toml"
    p.write_text(flight_mission(
        "params",
        step("set_param", "slower landing", param="MPC_LAND_SPEED", value=0.5),
        sim_param("wind", "SIM_WIND_E", 0.5),
        step("set_param", "disarm later", param="COM_DISARM_LAND", value=3.0, keep=True),
        step("hold", "windy hold", duration_s=hold_s),
        step("land")))
    return str(p)


def values(client) -> dict[str, float]:
    return {name: round(client.param(name), 3) for name in DEFAULTS}


def wait_for_the_hold(gcs) -> None:
    """Until the vehicle announces the last set_param step's value: the mission is in its long hold
    (the vehicle tells every client of every change; the companion's own output comes in chunks)."""
    gcs.wait("PARAM_VALUE", lambda p: p.param_id == "COM_DISARM_LAND" and p.param_value == 3.0, timeout=180)


def test_sigterm_after_set_param_steps_puts_every_written_parameter_back(sitl, client, companion, tmp_path):
    """SIGTERM mid-hold: the companion lands the vehicle and puts back MIS_TAKEOFF_ALT (written by the
    take-off), MPC_LAND_SPEED and SIM_WIND_E (the steps), leaves COM_DISARM_LAND (keep = true), and
    lists each in segments.json's summary. The old code left all three changed and named none."""
    s = sitl(*PAPER, *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    gcs = client(s.url, source_system=200)
    gcs.wait("HEARTBEAT")
    assert values(gcs) == DEFAULTS
    c = companion(params_mission(tmp_path), s.url, *PAPER_OUTPUT)
    wait_for_the_hold(gcs)
    c.proc.send_signal(signal.SIGTERM)
    code, out = c.finish(timeout=180)
    assert code == 130, out
    after = values(client(s.url, source_system=201))
    assert after == DEFAULTS | {"COM_DISARM_LAND": 3.0}, (after, out)
    summary = segments(c.flight_dir())["_summary"]
    restored = {"MIS_TAKEOFF_ALT": 2.5, "MPC_LAND_SPEED": 0.7, "SIM_WIND_E": 0.0}
    assert summary["params_restored"] == pytest.approx(restored, abs=1e-6), summary  # float32 on the wire
    assert summary["params_kept"] == {"COM_DISARM_LAND": 3.0} and summary["params_not_restored"] == {}, summary
    assert "parameters put back" in (c.flight_dir() / "summary.md").read_text()
    assert not s.stop()["armed"]


def test_a_completed_mission_puts_its_parameters_back(sitl, client, companion, tmp_path):
    s = sitl(*PAPER, *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    c = companion(params_mission(tmp_path, hold_s=2.0), s.url, *PAPER_OUTPUT)
    code, out = c.finish(timeout=180)
    assert code == 0, out
    assert values(client(s.url, source_system=201)) == DEFAULTS | {"COM_DISARM_LAND": 3.0}, out
    assert not s.stop()["armed"]


def test_a_link_lost_and_regained_gets_its_parameters_back(sitl, client, companion, tmp_path):
    """The link goes down mid-hold past link_lost_s (3 s wall): the companion gives up the flight
    (exit 3; the vehicle's failsafe lands it) but keeps trying to put the parameters back for
    RESTORE_WITHIN_S (10 s); the link comes back about 4 s after the loss was declared, and they are all
    put back. The old code tried once, with no reader running, and listed them as not put back."""
    s = sitl(*PAPER, "--wait-for-setpoints", "0.05", speedup=2.0)
    gcs = client(s.url, source_system=200)  # beside the relay: hears the vehicle all along
    r = RelayProcess(s.url)
    try:
        c = companion(params_mission(tmp_path), r.url, *PAPER_OUTPUT)
        wait_for_the_hold(gcs)
        r.proc.send_signal(signal.SIGSTOP)  # the link goes down
        time.sleep(3.0 + 4.0)  # link_lost_s, then 4 s into the restore's 10
        r.proc.send_signal(signal.SIGCONT)  # and comes back
        code, out = c.finish(timeout=60)
    finally:
        r.proc.send_signal(signal.SIGCONT)
        r.stop()
    assert code == 3, out
    assert values(client(s.url, source_system=201)) == DEFAULTS | {"COM_DISARM_LAND": 3.0}, out
    summary = segments(c.flight_dir())["_summary"]
    assert summary["params_not_restored"] == {}, (summary, out)
    assert set(summary["params_restored"]) == {"MIS_TAKEOFF_ALT", "MPC_LAND_SPEED", "SIM_WIND_E"}, summary
