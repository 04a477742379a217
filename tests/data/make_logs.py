"""How the ArduPilot logs in tests/data were made (not run by the tests; needs an ArduCopter SITL build).

    python tests/data/make_logs.py ardupilot OUT_DIR [--instance 5] [--speedup 3]

ArduCopter SITL (docs/autopilots.md) flies the project's plant (``sitl --firmware ardupilot``), so
that the external force is known: the plant's SIM_FORCE_X. A pymavlink script acts as a ground
station on the companion's port (tcp 5760+10N): it asks for ArduPilot's data streams at 10 Hz as
MAVProxy and Mission Planner do (REQUEST_DATA_STREAM, all streams) and writes every message it
receives to a .tlog. Three armings, each its own DataFlash log (ArduPilot starts one per
arming) and its own .tlog:

1. ``ground``: armed in GUIDED, left on the ground for 4 s of vehicle time, disarmed: a log that
   never leaves the ground.
2. ``ground_throttle``: armed in STABILIZE, a quarter of the throttle stick (RC override) for 5 s:
   less thrust than the weight, so it stays on the ground, yet ArduCopter's land detector says it
   is flying from the moment the throttle leaves its lower limit.
3. ``flight``: GUIDED take-off to 2 m, 6 s of hover, SIM_FORCE_X = 2 N for 8 s, 0 N again for 6 s,
   LAND until disarmed.

ArduPilot's DataFlash logs (``logs/*.BIN`` of its working directory) are copied out, written with
ArduCopter's default LOG_BITMASK. Nothing of ArduPilot's is copied: only what it wrote.

    python tests/data/make_logs.py trim SRC DST

keeps a log small enough for tests/data: of a .bin the message types :data:`DATAFLASH_KEEP`
(with every FMT, so the file is still a DataFlash log pymavlink reads), of a .tlog the messages
:data:`TLOG_KEEP` with their timestamps, of a .ulg the topics :data:`ULOG_KEEP` (pyulog's
write_ulog). Nothing is changed in what is kept.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import threading
import time
from pathlib import Path

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from companion.mavlink.modes import COPTER_MODES  # noqa: E402
from companion.mavlink.params import PLANT_COMPID  # noqa: E402

MAV = mavutil.mavlink


def wait(m, kind, cond=lambda msg: True, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = m.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and cond(msg):
            return msg
    raise RuntimeError(f"no {kind} within {timeout} s")


def command(m, cmd, *params, timeout=2.0):
    p = list(params) + [0.0] * (7 - len(params))
    for confirmation in range(5):
        m.mav.command_long_send(1, 1, cmd, confirmation, *p)
        try:
            return wait(m, "COMMAND_ACK", lambda a: a.command == cmd, timeout).result
        except RuntimeError:
            continue
    raise RuntimeError(f"no ACK for command {cmd}")


def vehicle_s(m):
    return wait(m, "LOCAL_POSITION_NED", timeout=20).time_boot_ms * 1e-3


def hold(m, seconds, throttle_pwm=None):
    """Until ``seconds`` of vehicle time have passed; with ``throttle_pwm``, RC channel 3 held there
    (RC_CHANNELS_OVERRIDE, sent with every position report: ArduPilot drops an override after 3 s)."""
    t0 = vehicle_s(m)

    def done(p):
        if throttle_pwm is not None:
            m.mav.rc_channels_override_send(1, 1, 0, 0, throttle_pwm, 0, 0, 0, 0, 0)
        return p.time_boot_ms * 1e-3 > t0 + seconds
    wait(m, "LOCAL_POSITION_NED", done, timeout=60 + 10 * seconds)


def set_plant_param(m, name, value):
    for _ in range(5):
        m.mav.param_set_send(1, PLANT_COMPID, name.encode(), value, MAV.MAV_PARAM_TYPE_REAL32)
        try:
            wait(m, "PARAM_VALUE", lambda p: p.param_id == name and abs(p.param_value - value) < 1e-6, 2.0)
            return
        except RuntimeError:
            continue
    raise RuntimeError(f"the plant did not take {name}")


def arm(m):
    end = time.monotonic() + 60
    while command(m, MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1) != 0:
        if time.monotonic() > end:
            raise RuntimeError("never armed")
        time.sleep(0.5)


def disarmed(m, timeout=120):
    wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1 and h.autopilot == MAV.MAV_AUTOPILOT_ARDUPILOTMEGA
         and not h.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED, timeout)


def ardupilot(out: Path, instance: int, speedup: float) -> None:
    from sitl.firmware.builds import find_arducopter
    from sitl.firmware.cli import Session, firmware_scenario
    from sitl.plant.geo import GeoOrigin
    from sitl.plant.scenario import Scenario

    binary, why = find_arducopter()
    if binary is None:
        raise SystemExit(why)
    scenario = firmware_scenario(Scenario(name="sitl"), None, None)
    session = Session("ardupilot", binary, scenario, 1, GeoOrigin(), speedup, 0.0, instance, keep_workdir=True,
                      firmware_params={"LOG_FILE_DSRMROT": 1})  # a DataFlash log per arming
    stop = threading.Event()
    runner = threading.Thread(target=session.run, args=(stop.is_set,), daemon=True)
    runner.start()
    out.mkdir(parents=True, exist_ok=True)
    try:
        m = mavutil.mavlink_connection(f"tcp:127.0.0.1:{session.ports['companion'].rsplit(':', 1)[1]}",
                                       source_system=255, source_component=190)
        m.mav.heartbeat_send(MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_UNINIT)
        wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1, 60)
        m.mav.request_data_stream_send(1, 1, MAV.MAV_DATA_STREAM_ALL, 10, 1)
        wait(m, "LOCAL_POSITION_NED", timeout=120)
        wait(m, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & MAV.MAV_SYS_STATUS_PREARM_CHECK, 120)
        assert command(m, MAV.MAV_CMD_DO_SET_MODE, 1, COPTER_MODES["GUIDED"]) == 0

        m.setup_logfile(str(out / "ardupilot_ground.tlog"), mode="wb")
        arm(m)
        hold(m, 4.0)
        command(m, MAV.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        disarmed(m)
        hold(m, 1.0)
        m.logfile.close()
        m.logfile = None

        m.setup_logfile(str(out / "ardupilot_ground_throttle.tlog"), mode="wb")
        assert command(m, MAV.MAV_CMD_DO_SET_MODE, 1, COPTER_MODES["STABILIZE"]) == 0
        hold(m, 1.0, 1000)
        arm(m)
        hold(m, 5.0, 1250)  # a quarter of the stick: less thrust than the weight, it stays down
        hold(m, 1.0, 1000)
        command(m, MAV.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        disarmed(m)
        hold(m, 1.0)
        m.logfile.close()
        m.logfile = None
        m.mav.rc_channels_override_send(1, 1, 0, 0, 0, 0, 0, 0, 0, 0)  # released
        assert command(m, MAV.MAV_CMD_DO_SET_MODE, 1, COPTER_MODES["GUIDED"]) == 0

        m.setup_logfile(str(out / "ardupilot_flight.tlog"), mode="wb")
        hold(m, 1.0)
        arm(m)
        assert command(m, MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2.0) == 0
        wait(m, "LOCAL_POSITION_NED", lambda p: p.z < -1.8, timeout=120)
        hold(m, 6.0)
        set_plant_param(m, "SIM_FORCE_X", 2.0)
        print(f"force on at {vehicle_s(m):.2f} s", flush=True)
        hold(m, 8.0)
        set_plant_param(m, "SIM_FORCE_X", 0.0)
        print(f"force off at {vehicle_s(m):.2f} s", flush=True)
        hold(m, 6.0)
        assert command(m, MAV.MAV_CMD_DO_SET_MODE, 1, COPTER_MODES["LAND"]) == 0
        disarmed(m, timeout=300)
        hold(m, 1.0)
        m.logfile.close()
        m.logfile = None
        m.close()
    finally:
        stop.set()
        runner.join(timeout=30)
        session.close()
    logs = sorted((session.workdir / "logs").glob("*.BIN"))
    print("DataFlash logs:", [(p.name, p.stat().st_size) for p in logs])
    for name, src in zip(("ardupilot_ground.bin", "ardupilot_ground_throttle.bin", "ardupilot_flight.bin"),
                         logs[-3:]):
        shutil.copyfile(src, out / name)
    shutil.rmtree(session.workdir, ignore_errors=True)


DATAFLASH_KEEP = {"FMT", "FMTU", "UNIT", "MULT", "PARM", "MSG", "MODE", "EV", "ARM", "ATT", "IMU", "XKF1",
                  "CTUN", "VIBE"}
TLOG_KEEP = {"HEARTBEAT", "SYS_STATUS", "ATTITUDE", "RAW_IMU", "LOCAL_POSITION_NED", "VFR_HUD", "PARAM_VALUE",
             "STATUSTEXT", "COMMAND_ACK", "EXTENDED_SYS_STATE"}
ULOG_KEEP = ["vehicle_attitude", "sensor_combined", "vehicle_local_position", "actuator_motors",
             "vehicle_thrust_setpoint", "actuator_controls_0", "vehicle_land_detected"]


def trim_dataflash(src: Path, dst: Path) -> None:
    """DataFlash messages are ``0xA3 0x95 type payload``, their lengths in the FMT messages (type
    128, 89 bytes): copied message by message, the types not kept skipped."""
    data = src.read_bytes()
    lengths, names = {128: 89}, {128: "FMT"}
    out = bytearray()
    i = 0
    while i + 3 <= len(data):
        if data[i] != 0xA3 or data[i + 1] != 0x95:
            i += 1  # a torn write: resynchronise on the next header
            continue
        kind = data[i + 2]
        if kind not in lengths:
            break
        n = lengths[kind]
        msg = data[i:i + n]
        if kind == 128:
            lengths[msg[3]] = msg[4]
            names[msg[3]] = msg[5:9].rstrip(b"\0").decode()
        if names[kind] in DATAFLASH_KEEP:
            out += msg
        i += n
    dst.write_bytes(bytes(out))


def trim_tlog(src: Path, dst: Path) -> None:
    import struct

    log = mavutil.mavlink_connection(str(src), robust_parsing=True)
    with open(dst, "wb") as f:
        while (m := log.recv_match(type=sorted(TLOG_KEEP))) is not None:
            f.write(struct.pack(">Q", int(round(m._timestamp * 1e6))) + m.get_msgbuf())


def trim_ulog(src: Path, dst: Path) -> None:
    from pyulog import ULog

    ULog(str(src), ULOG_KEEP).write_ulog(str(dst))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("kind", choices=("ardupilot", "trim"))
    ap.add_argument("paths", type=Path, nargs="+", help="ardupilot: OUT_DIR; trim: SRC DST")
    ap.add_argument("--instance", type=int, default=5)
    ap.add_argument("--speedup", type=float, default=3.0)
    args = ap.parse_args()
    if args.kind == "ardupilot":
        ardupilot(args.paths[0], args.instance, args.speedup)
        return
    src, dst = args.paths
    trim = {".bin": trim_dataflash, ".tlog": trim_tlog, ".ulg": trim_ulog}[src.suffix.lower()]
    trim(src, dst)


if __name__ == "__main__":
    main()
