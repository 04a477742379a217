"""The companion against real ArduCopter SITL (4.8-dev, "+" quad, --speedup 2), pymavlink backend.

ArduCopter's SITL serves MAVLink on TCP 5760 (its SERIAL0) and waits for a connection before its
clock starts; with ``udp_port`` it sends to a UDP port instead, where the companion listens. Its
EKF has an origin about 42 s (vehicle time) after boot: the companion waits for it with progress.
As for PX4, bounds come from ArduPilot itself in the same boot: its own position control (GUIDED
with position targets) flies the same square.
"""

from __future__ import annotations

import signal
import time

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from helpers.processes import RelayProcess, free_udp_port
from helpers.firmware import ArduCopterSitl

from .conftest import segments

pytestmark = [pytest.mark.autopilot, pytest.mark.integration]

SPEEDUP = 2.0
SPREAD = 1.25
GUIDED, BRAKE = 4, 17


def test_square_twice_in_one_boot_within_arducopters_own_figure(arducopter_binary, companion, record_property):
    """Over TCP 5760, ArduPilot's own connect string. Parameters the companion changed are put
    back after each flight (read back through a second TCP port, SERIAL1 on 5762)."""
    with ArduCopterSitl(arducopter_binary, speedup=SPEEDUP) as ap:
        own = companion("missions/square_gps.toml", ap.url, "--controller", "autopilot", "--connect-timeout", "60")
        code, out = own.finish(timeout=300)
        assert code == 0, out
        assert "vehicle found, waiting for its position" in out  # the EKF origin, not a missing vehicle
        figures = {"arducopter": segments(own.flight_dir())["square"]["rms_error_m"]}
        for k in (1, 2):
            c = companion("missions/square_gps.toml", ap.url)
            code, out = c.finish(timeout=300)
            assert code == 0, f"flight {k}: {out}"
            seg = segments(c.flight_dir())
            assert seg["_summary"]["type_mask"] == 7  # no body rates to ArduPilot
            assert seg["_summary"]["params_not_restored"] == {}
            for name in ("GUID_OPTIONS", "GUID_TIMEOUT", "ATC_RATE_FF_ENAB", "ATC_ANGLE_BOOST"):
                assert f"{name} put back to" in out, (name, out)
            figures[f"ism_do_{k}"] = seg["square"]["rms_error_m"]
        gcs = mavutil.mavlink_connection(f"tcp:127.0.0.1:{ap.tcp_port + 2}", source_system=201)
        gcs.wait_heartbeat(timeout=10)
        for name, default in (("GUID_OPTIONS", 0.0), ("GUID_TIMEOUT", 3.0), ("ATC_RATE_FF_ENAB", 1.0)):
            gcs.mav.param_request_read_send(1, 1, name.encode(), -1)
            p = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=5,
                               condition=f'PARAM_VALUE.param_id=="{name}"')
            assert p is not None and p.param_value == default, (name, p)
        gcs.close()
    record_property("square_rms_m", figures)
    for k in (1, 2):
        assert figures[f"ism_do_{k}"] <= SPREAD * figures["arducopter"] + 0.02, figures


def test_a_telemetry_outage_holds_in_brake_and_the_vehicle_keeps_its_altitude(arducopter_binary, companion):
    """Over UDP through the impairment relay (ArduPilot's SERIAL0 sends to the relay, the relay to the
    companion), a 1.5 s outage (3 s of vehicle time at 2x) mid-hold: the companion pauses its
    setpoints and commands hold, which on ArduPilot is BRAKE — it holds position with no pilot (LOITER
    follows a throttle stick that is low without RC, and descended at 2.2 m/s into the ground). Back,
    it sees the vehicle holding after an outage and lands it (exit 1). Bound: the vehicle loses less
    than 0.3 m of altitude from the outage to the landing command."""
    port = free_udp_port()
    r = RelayProcess(f"127.0.0.1:{port}", "--signal-outage-s", "1.5")
    try:
        relay_port = int(r.url.rsplit(":", 1)[1])
        with ArduCopterSitl(arducopter_binary, speedup=SPEEDUP, udp_port=relay_port) as ap:
            assert ap.alive()
            c = companion("missions/hold_gps.toml", f"udpin://127.0.0.1:{port}", "--connect-timeout", "60")
            c.wait_for("step hold", timeout=180)
            time.sleep(2.0)
            r.outage_now()
            code, out = c.finish(timeout=300)
    finally:
        r.stop()
    assert code == 1, out
    assert "commanding hold" in out and "the vehicle holds (BRAKE): landing it" in out, out
    from companion.plots import load_timeseries

    d = load_timeseries(c.flight_dir())
    paused = np.where((d["streaming"] == 0) & (d["offboard"] == 1))[0]
    assert len(paused), "no outage seen"
    z0 = d["z"][paused[0]]
    after = d["z"][paused[0]:]
    lost = float(np.nanmax(after[: int(np.argmax(d["offboard"][paused[0]:] == 0)) + 400]) - z0)
    assert lost < 0.3, lost


def test_ctrl_c_mid_square_holds_lands_and_disarms(arducopter_binary, companion):
    with ArduCopterSitl(arducopter_binary, speedup=SPEEDUP) as ap:
        c = companion("missions/square_gps.toml", ap.url, "--connect-timeout", "60")
        c.wait_for("step square", timeout=180)
        time.sleep(2.0)
        c.proc.send_signal(signal.SIGINT)
        code, out = c.finish(timeout=180)
    assert code == 130, out
    assert "interrupted: holding, then landing" in out and "landed and disarmed" in out
    assert "GUID_TIMEOUT put back to 3" in out


def test_companion_killed_mid_square_the_vehicle_levels_after_guid_timeout(arducopter_binary, companion):
    """SIGKILL mid-square: ArduCopter has no offboard-loss failsafe; it flies the last target for
    GUID_TIMEOUT (the companion made it 0.5 s; with ArduPilot's 3 s and body rates sent along, a
    vehicle pitched to 39 deg and flew 35 m on) and then levels out. Bound: level (< 5 deg) within
    2 s of vehicle time, and no further than 3 m from where it was killed."""
    with ArduCopterSitl(arducopter_binary, speedup=SPEEDUP) as ap:
        c = companion("missions/square_gps.toml", ap.url, "--connect-timeout", "60")
        c.wait_for("step square", timeout=180)
        time.sleep(1.0)
        c.proc.kill()
        c.proc.wait()
        m = mavutil.mavlink_connection(f"tcp:127.0.0.1:{ap.tcp_port + 2}", source_system=201)
        m.wait_heartbeat(timeout=10)
        m.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_ALL, 20, 1)
        first = m.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=10)
        end = time.monotonic() + 2.0 / SPEEDUP + 1.0
        att = None
        while time.monotonic() < end:
            att = m.recv_match(type="ATTITUDE", blocking=True, timeout=1) or att
        pos = m.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=5)
        m.close()
    assert att is not None and abs(att.roll) < 0.09 and abs(att.pitch) < 0.09, att
    assert ((pos.x - first.x) ** 2 + (pos.y - first.y) ** 2) ** 0.5 < 3.0, (first, pos)


def test_a_gcs_taking_control_ends_the_mission_and_the_companion_lets_go(arducopter_binary, companion):
    with ArduCopterSitl(arducopter_binary, speedup=SPEEDUP) as ap:
        c = companion("missions/square_gps.toml", ap.url, "--connect-timeout", "60")
        c.wait_for("step square", timeout=180)
        gcs = mavutil.mavlink_connection(f"tcp:127.0.0.1:{ap.tcp_port + 2}", source_system=201)
        gcs.wait_heartbeat(timeout=10)
        gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                  BRAKE, 0, 0, 0, 0, 0)
        code, out = c.finish(timeout=120)
        assert code == 1, out
        assert "left offboard" in out and "has control: the companion stops here" in out
        h = gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=5,
                           condition=f"HEARTBEAT.custom_mode=={BRAKE} and HEARTBEAT.base_mode & 128")
        gcs.close()
    assert h is not None  # still braking, armed: the companion did not land it
