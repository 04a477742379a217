"""The companion against real PX4 v1.16 (SIH quadrotor, lockstep at 4x), over real UDP.

Bounds come from PX4 itself, flown in the same boot: its own position controller flies the same
mission and reference (``--controller autopilot``: the reference as SET_POSITION_TARGET_LOCAL_NED),
and the companion's ISM+DO must do no worse than that figure plus its run-to-run spread. The
simulated GPS makes both wander by tens of centimetres (PX4's own hold: 0.2-0.4 m standard
deviation), so the square's waypoints count as reached within 0.5 m (missions/square_gps.toml).
"""

from __future__ import annotations

import csv
import math
import signal
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.modes import PX4_MODES, px4_custom_mode
from companion.control.params import TrajectoryParams
from helpers.firmware import Px4Sih
from helpers.processes import CompanionProcess, kill_left_over

from .conftest import segments

pytestmark = [pytest.mark.autopilot, pytest.mark.integration]

SPEED = 4.0
SPREAD = 1.25
"""the companion's square RMS may be up to 25% above PX4's own in the same boot (run-to-run spread
of either on the simulated GPS, measured over 6 boots: docs/autopilots.md)"""
TOUCHDOWN_M_S2 = 5.0 * 9.80665
"""an accelerometer reading past 5 g in the air is a touchdown: SIH's quadrotor has a thrust-to-weight
ratio of about 2, so its specific force in flight stays near 2 g, and SIH stops a body that reaches
its ground within one step, which the accelerometer reads as v / dt (0.3 m/s in 5 ms: 6 g). At
1.5 m up this happened mid-square and mid-hold, because EKF2's height on SIH's GPS and barometer is
off by up to ~1.6 m (docs/autopilots.md, "Ground contact, not a simulator fault"); the missions fly
5 m up, and a touchdown before the landing fails the flight"""
OFFBOARD = px4_custom_mode("OFFBOARD")
HOLD = px4_custom_mode("HOLD")
LAND = px4_custom_mode("LAND")


def observer(port: int, timeout: float = 10.0) -> mavutil.mavfile:
    """A pymavlink ground station listening where PX4 sends its API link (the companion is gone)."""
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=200)
    m.wait_heartbeat(timeout=timeout)
    return m


def wait_heartbeat(m: mavutil.mavfile, cond, timeout: float):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        h = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if h is not None and h.get_srcComponent() == 1 and cond(h):
            return h
    raise AssertionError(f"no such heartbeat within {timeout} s")


def _offboard_left_between(m: mavutil.mavfile, timeout: float) -> tuple[int, int, object]:
    """(ms of the last heartbeat saying OFFBOARD, ms of the first that does not, that heartbeat): each
    heartbeat dated by the newest time_boot_ms seen before it (the mode changed inside that bracket)."""
    end = time.monotonic() + timeout
    now_ms = still_ms = 0
    while time.monotonic() < end:
        msg = m.recv_match(blocking=True, timeout=0.5)
        if msg is None or msg.get_srcComponent() != 1:
            continue
        if msg.get_type() == "HEARTBEAT" and now_ms:
            if msg.custom_mode == OFFBOARD:
                still_ms = now_ms
            elif still_ms:
                return still_ms, now_ms, msg
        elif hasattr(msg, "time_boot_ms"):
            now_ms = max(now_ms, msg.time_boot_ms)
    raise AssertionError(f"PX4 did not leave OFFBOARD within {timeout} s (or was out of it already)")


def touchdowns_s(flight_dir, names=("square",), threshold_m_s2: float = TOUCHDOWN_M_S2) -> list[float]:  # type: ignore[no-untyped-def]
    """Vehicle times in the segments ``names`` at which the recorded HIGHRES_IMU read past
    ``threshold_m_s2`` (TOUCHDOWN_M_S2): the vehicle touched the ground in the air."""
    seg = segments(flight_dir)
    spans = [(seg[n]["t_start"], seg[n]["t_end"]) for n in names]
    log = mavutil.mavlink_connection(str(flight_dir / "traffic.tlog"))
    found = []
    while (m := log.recv_match(type="HIGHRES_IMU")) is not None:
        t = m.time_usec * 1e-6
        if any(a <= t <= b for a, b in spans) and max(abs(m.xacc), abs(m.yacc), abs(m.zacc)) > threshold_m_s2:
            found.append(round(t, 3))
    log.close()
    return found


def fly_clear(companion, mission: str, url: str, args: tuple[str, ...], names: tuple[str, ...],  # type: ignore[no-untyped-def]
              label: str, timeout: float):
    """Fly ``mission`` to its end (exit 0) and check that the vehicle did not touch the ground during
    the segments ``names``; returns the companion."""
    c = companion(mission, url, *args)
    code, out = c.finish(timeout=timeout)
    assert code == 0, f"{label}: {out}"
    touched = touchdowns_s(c.flight_dir(), names)
    assert not touched, f"{label}: the vehicle touched the ground in the air at {touched[:5]} s (vehicle time)"
    return c


def test_the_touchdown_check_finds_a_touchdown_in_the_air_and_only_there(tmp_path):
    """:func:`touchdowns_s` on a record written here (no firmware): 200 Hz of HIGHRES_IMU reading a
    1 g hover and 2 g manoeuvres, with one 6 g sample mid-square (what SIH reports when the body
    reaches its ground at 0.3 m/s) and a 9.8 g one in the landing. Found: the square's, and only
    it; a threshold a little higher (7 g) or the landing's span asked for instead say otherwise."""
    import json

    from pymavlink.dialects.v20 import common

    g = 9.80665
    (tmp_path / "segments.json").write_text(json.dumps({"segments": [
        {"name": "square", "t_start": 10.0, "t_end": 20.0}, {"name": "5: land", "t_start": 20.0, "t_end": 30.0}]}))
    mav = common.MAVLink(None, srcSystem=1, srcComponent=1)
    with open(tmp_path / "traffic.tlog", "wb") as fh:
        for k in range(0, 6000):
            t = k * 0.005
            acc = (0.0, 0.0, -g if k % 40 else -2.0 * g)
            if abs(t - 15.0) < 1e-9:
                acc = (0.0, -6.0 * g, -g)
            if abs(t - 25.0) < 1e-9:
                acc = (0.0, 0.0, -9.8 * g)
            msg = mav.highres_imu_encode(round(t * 1e6), *acc, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)
            fh.write(round(t * 1e6).to_bytes(8, "big") + msg.pack(mav))
    assert touchdowns_s(tmp_path, ("square",)) == [15.0]
    assert touchdowns_s(tmp_path, ("5: land",)) == [25.0]
    assert touchdowns_s(tmp_path, ("square",), threshold_m_s2=7.0 * g) == []


BACKENDS = ("pymavlink", "mavsdk")


@pytest.fixture(scope="module")
def squares_in_one_boot(px4_build, tmp_path_factory) -> dict[str, dict | str]:  # type: ignore[no-untyped-def]
    """One boot: PX4 flies the square itself, then the companion flies it with each backend in turn.
    Each of the companion's arms after a disarm in the same boot (that arming used to be refused:
    PX4 restores OFFBOARD after a disarm). Per flight its segments, or why it failed (a flight that
    touches the ground fails: :func:`touchdowns_s`); the tests below judge them (one boot for both
    backends: three squares instead of six, one minute less of the tier)."""
    flights = tmp_path_factory.mktemp("squares")
    procs: list[CompanionProcess] = []

    def start(mission: str, url: str, *args: str) -> CompanionProcess:
        procs.append(p := CompanionProcess(mission, url, flights / str(len(procs)), *args))
        return p

    out: dict[str, dict | str] = {}
    try:
        with Px4Sih(px4_build, speed=SPEED) as px4:
            for label, args in (("px4", ("--controller", "autopilot")),
                                *((b, ("--backend", b)) for b in BACKENDS)):
                try:
                    c = fly_clear(start, "missions/square_gps.toml", px4.url, args, ("square",), label, 240)
                    out[label] = segments(c.flight_dir())
                except Exception as exc:  # noqa: BLE001 - recorded: the test of that flight fails with it
                    out[label] = f"{label}: {type(exc).__name__}: {exc}"
    finally:
        kill_left_over(procs)
    return out


@pytest.mark.xdist_group("px4 squares")  # one worker flies the boot both read
@pytest.mark.parametrize("backend", BACKENDS)
def test_square_in_one_boot_within_px4s_own_figure(squares_in_one_boot, backend, record_property):
    """The companion's square with ``backend`` (its ISM+DO, attitude setpoints only) flies to its end
    without touching the ground, after PX4's own in the same boot, within SPREAD of PX4's RMS."""
    px4, seg = squares_in_one_boot["px4"], squares_in_one_boot[backend]
    assert isinstance(px4, dict), f"PX4's own square: {px4}"
    assert isinstance(seg, dict), seg
    assert seg["_summary"]["output"] == "attitude" and seg["_summary"]["type_mask"] == 3
    figures = {"px4": px4["square"]["rms_error_m"], "ism_do": seg["square"]["rms_error_m"]}
    record_property("square_rms_m", figures)
    assert figures["ism_do"] <= SPREAD * figures["px4"], figures


WANDER_M_S = 0.4
"""how fast PX4's own hold usually drifts on SIH's simulated GPS (horizontal speed, 0.2-0.4 m/s;
0.55 m/s seen once)"""


def switch_tilt_bound_deg(flight_dir, switch: dict) -> float:  # type: ignore[no-untyped-def]
    """The most tilt a bumpless switch asks for: the controller restarts with its reference moving
    as the vehicle moves, and the critically damped reference filter (bandwidth w, 2 rad/s)
    stops that velocity v with an acceleration of 2 w v at first: atan(2 w v / g), for the
    fastest horizontal speed recorded in the switch's segment (at least WANDER_M_S: 9.3 deg),
    plus 1 deg of attitude tracking."""
    with open(flight_dir / "timeseries.csv", newline="") as fh:
        v = max((math.hypot(float(r["vx"]), float(r["vy"])) for r in csv.DictReader(fh)
                 if switch["t_start"] <= float(r["t"]) <= switch["t_end"]), default=0.0)
    w = TrajectoryParams().bandwidth_rad_s
    return math.degrees(math.atan(2.0 * w * max(v, WANDER_M_S) / 9.81)) + 1.0


def test_hold_and_a_bumpless_switch_to_offboard(px4_build, companion):
    """20 s of offboard hold: completes, within 0.5 m RMS of the point (PX4's own hold wanders by
    0.2-0.4 m standard deviation on the simulated GPS). The switch to OFFBOARD is bumpless: the
    controller restarts from the vehicle's state right before it, so the tilt stays within what
    stopping the hold's wander asks for (:func:`switch_tilt_bound_deg`: 10.3-13.6 deg). Without
    the restart the controller keeps what it learnt for 1.2 s while PX4's own HOLD flew: 11.5 deg
    in one of two such flights (5.8 in the other; it used to reach 22 deg), so this flight
    catches only a large learnt state. In twelve flights of the real code the switch
    peaked at 1.6-8.3 deg (8.03 once under load, against an earlier fixed bound of 8 deg). The
    steady hold after the switch is not bounded here: the mission's hold point is where the
    vehicle took off, and flying back from PX4's wander to it tilts by up to ~18 deg by design. The
    vehicle must not touch the ground from the switch to the end of the hold."""
    with Px4Sih(px4_build, speed=SPEED) as px4:
        c = fly_clear(companion, "missions/hold_gps.toml", px4.url, (), ("2: offboard", "hold"), "hold", 180)
    seg = segments(c.flight_dir())
    hold = seg["hold"]
    assert abs(hold["t_end"] - hold["t_start"] - 20.0) < 0.5 and hold["rms_error_m"] < 0.5, hold
    switch = seg["2: offboard"]
    assert switch["peak_tilt_deg"] < switch_tilt_bound_deg(c.flight_dir(), switch), switch


@pytest.mark.parametrize("backend", ["pymavlink", "mavsdk"])
def test_ctrl_c_mid_square_holds_lands_and_disarms(px4_build, companion, backend):
    with Px4Sih(px4_build, speed=SPEED) as px4:
        c = companion("missions/square_gps.toml", px4.url, "--backend", backend)
        c.wait_for("step square", timeout=120)
        time.sleep(2.0)
        c.proc.send_signal(signal.SIGINT)
        code, out = c.finish(timeout=120)
    assert code == 130, out
    assert "interrupted: holding, then landing" in out and "landed and disarmed" in out


@pytest.mark.parametrize("backend", ["pymavlink", "mavsdk"])
def test_companion_killed_mid_square_px4s_failsafe_lands_it(px4_build, companion, backend):
    """SIGKILL mid-square: PX4 v1.16 sees the offboard stream stop (COM_OF_LOSS_T: 4 s in SITL's
    defaults at 4x), leaves OFFBOARD and, with no RC, descends to the ground and disarms (it does not
    hold: the heartbeat says POSCTL while it descends). The switch is bracketed in vehicle time
    between the last heartbeat still saying OFFBOARD and the first that does not (each dated by the
    newest stamped message before it; 1 Hz heartbeats, so about 1 s wide). The last setpoint reached
    PX4 before the kill, so before the first message an observer opened after the kill receives (its
    stamp is an upper bound on the setpoint's arrival, where the companion's own stamp in its .tlog
    can lag on a busy host). Bounds: the bracket ends within COM_OF_LOSS_T + 1.5 s of that first
    message (the bracket's width, PX4's failsafe update), and it does not end before
    COM_OF_LOSS_T - 0.5 s after the companion's last setpoint (the offboard-loss timeout, nothing
    earlier); disarmed within 30 s more, and on the ground by PX4's land detector."""
    from pymavlink import mavutil as mu

    with Px4Sih(px4_build, speed=SPEED) as px4:
        c = companion("missions/square_gps.toml", px4.url, "--backend", backend)
        c.wait_for("step square", timeout=120)
        time.sleep(1.0)
        c.proc.kill()
        c.proc.wait()
        m = observer(px4.api_port)
        try:
            after_kill = _first_stamp(m, timeout=5)
            m.mav.param_request_read_send(px4.sysid, 1, b"COM_OF_LOSS_T", -1)
            loss_t = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=5).param_value
            still, left, h = _offboard_left_between(m, timeout=10)
            armed = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
            wait_heartbeat(m, lambda h: not h.base_mode & armed, timeout=30 / SPEED + 10)
            landed = m.recv_match(type="EXTENDED_SYS_STATE", blocking=True, timeout=5).landed_state
        finally:
            m.close()
    log = mu.mavlink_connection(str(c.flight_dir() / "traffic.tlog"))
    last = 0
    while (msg := log.recv_match(type="SET_ATTITUDE_TARGET")) is not None:
        last = max(last, msg.time_boot_ms)
    figures = (last, after_kill, still, left, loss_t, h.custom_mode)
    assert last and (left - last) * 1e-3 > loss_t - 0.5, figures
    assert (left - after_kill) * 1e-3 < loss_t + 1.5, figures
    # PX4's own judgement, not LOCAL_POSITION_NED's z: its EKF height on the simulated GPS and baro
    # drifts by up to a metre over a flight (-0.65 m and -1.9 m read on the ground after a landing)
    assert landed == mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND, landed


def _first_stamp(m: mavutil.mavfile, timeout: float) -> int:
    """time_boot_ms of the first stamped message from the autopilot."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = m.recv_match(blocking=True, timeout=0.5)
        if msg is not None and msg.get_srcComponent() == 1 and hasattr(msg, "time_boot_ms"):
            return int(msg.time_boot_ms)
    raise AssertionError(f"no stamped message within {timeout} s")


def test_a_gcs_taking_control_ends_the_mission_and_the_companion_lets_go(px4_build, companion):
    """A ground station switches PX4 to HOLD mid-square: the companion stops streaming, says why and
    exits 1; PX4 keeps holding (the companion neither fights for control nor lands it)."""
    with Px4Sih(px4_build, speed=SPEED) as px4:
        c = companion("missions/square_gps.toml", px4.url)
        c.wait_for("step square", timeout=120)
        gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{px4.gcs_port}", source_system=201)
        try:
            gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                   mavlink.MAV_STATE_UNINIT)
            gcs.wait_heartbeat(timeout=10)
            gcs.mav.command_long_send(px4.sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0,
                                      mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, *PX4_MODES["HOLD"], 0, 0, 0, 0)
            code, out = c.finish(timeout=60)
            assert code == 1, out
            assert "left offboard" in out and "has control: the companion stops here" in out
            h = wait_heartbeat(gcs, lambda h: h.custom_mode == HOLD, timeout=10)
            assert h.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        finally:
            gcs.close()


@pytest.mark.parametrize("backend", ["pymavlink", "mavsdk"])
def test_a_refusal_reads_as_text_from_px4s_events(px4_build, backend):
    """PX4 v1.16 explains a refused arming with EVENTs (id 410), not STATUSTEXT: the companion's
    error must carry the readable reason (pymavlink: the catalogue fetched over MAVLink FTP;
    MAVSDK: its events plugin). Provoked by arming in OFFBOARD without a setpoint stream."""
    import asyncio

    from companion.link import LinkError, open_link

    async def refused() -> str:
        with Px4Sih(px4_build, speed=SPEED) as px4:
            link = open_link(px4.url, backend)
            stop = asyncio.Event()
            async with link:
                reader = asyncio.create_task(link.run(stop))
                await link.wait_connected(30)
                await asyncio.sleep(0.5)
                await link.start_offboard()
                try:
                    for _ in range(20):  # until PX4 has taken OFFBOARD (its heartbeat says so)
                        if link.state.offboard:
                            break
                        await asyncio.sleep(0.1)
                    await link.arm()
                except LinkError as exc:
                    return str(exc)
                finally:
                    stop.set()
                    await reader
        return ""

    message = asyncio.run(refused())
    assert "Arming denied" in message or "No offboard signal" in message, message
