"""Readers that bring a flight log to :class:`companion.estimate.FlightSeries`.

- PX4 ULog (pyulog, the optional ``logs`` extra): ``vehicle_attitude.q`` (scalar-first, FRD to
  NED), ``sensor_combined.accelerometer_m_s2`` (FRD), ``vehicle_local_position`` (v[xyz], z; NED)
  and the thrust, all resampled onto the accelerometer's time base. The thrust, by what the
  version logs: ``actuator_motors`` (PX4 1.13 with control allocation and later: the sum of the
  normalised motor commands, a per-motor scale; the motors from CA_ROTOR_COUNT), else
  ``vehicle_thrust_setpoint.xyz[2]`` (the collective), else ``actuator_controls_0.control[3]``
  (before 1.13: the collective). ``vehicle_land_detected.landed`` says when it flew.
- MAVLink telemetry log .tlog (pymavlink), of PX4 or ArduPilot: the attitude from
  ATTITUDE_QUATERNION or else ATTITUDE (Euler, what ArduPilot streams), the accelerometer from
  HIGHRES_IMU, SCALED_IMU or ArduPilot's RAW_IMU (milli-g), LOCAL_POSITION_NED, the collective
  from ATTITUDE_TARGET.thrust or else VFR_HUD.throttle (ArduCopter's motor throttle, in per
  cent), and airborne from EXTENDED_SYS_STATE.landed_state or else ArduCopter's HEARTBEAT
  system_status. Messages without a stamp (VFR_HUD, HEARTBEAT, EXTENDED_SYS_STATE) take the
  newest stamp of the same vehicle before them.
- ArduPilot DataFlash log .bin (pymavlink's DFReader): ATT (Euler, degrees), IMU (instance 0),
  XKF1 (EKF3; NKF1 for EKF2) velocity and position down, CTUN.ThO (the collective thrust, 0..1),
  and airborne from the land detector's events (EV LAND_COMPLETE / NOT_LANDED; landed at the
  start: ArduCopter logs from boot or arming, on the ground). The rotors from FRAME_CLASS.
- CSV with a column map ``field=column`` (fields: t, qw, qx, qy, qz, ax, ay, az (specific force,
  body), vx, vy, vz, z (position down), thrust, landed (1/0), and truth_x, truth_y, truth_z), or
  the preset ``sitl`` for the project's own flight records (``FlightLog.to_csv``: true attitude
  and velocity, thrust in N, the true external force); frames converted with the explicit
  converters of :mod:`companion.estimate`. Read row by row into the mapped columns only: memory
  is 8 bytes per mapped cell, whatever the width of the file.
"""

from __future__ import annotations

import csv
import math
from array import array
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from .control import quaternion as quat
from .estimate import (
    Array,
    FlightSeries,
    enu_to_ned,
    flu_to_frd,
    quat_enu_flu_to_ned_frd,
)

__all__ = ["read_log", "read_ulog", "read_tlog", "read_dataflash", "read_csv", "SITL_COLUMNS", "parse_columns",
           "CSV_FIELDS"]

G0 = 9.80665

SITL_COLUMNS: dict[str, str] = {
    "t": "t", "qw": "qw", "qx": "qx", "qy": "qy", "qz": "qz", "vx": "vx", "vy": "vy", "vz": "vz", "z": "z",
    "thrust": "thrust_sp", "truth_x": "hfx", "truth_y": "hfy", "truth_z": "hfz",
}
"""the project's flight records (sitl.lab.simulation.LOG_COLUMNS): thrust in newtons"""

CSV_FIELDS = ("t", "qw", "qx", "qy", "qz", "ax", "ay", "az", "vx", "vy", "vz", "z", "thrust", "landed",
              "truth_x", "truth_y", "truth_z")

COPTER_FRAME_ROTORS = {1: 4, 2: 6, 3: 8, 4: 8, 5: 6, 7: 3, 12: 12, 14: 10}
"""ArduCopter FRAME_CLASS -> rotors: quad, hexa, octa, octaquad, Y6, tri, dodecahexa, deca
(AP_Motors_Class.h motor_frame_class; helicopters, tailsitters and scripted frames say nothing)"""

EV_LAND_COMPLETE = 18
EV_NOT_LANDED = 28
"""ArduPilot's LogEvent ids for its land detector (libraries/AP_Logger/AP_Logger.h)"""


def _interp(t: Array, ts: Array, values: Array) -> Array:
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        return np.interp(t, ts, values)
    return np.stack([np.interp(t, ts, values[:, i]) for i in range(values.shape[1])], axis=-1)


def _hold(t: Array, ts: Array, values: Array) -> Array:
    """The newest value at or before each ``t`` (the first value before the first stamp): a state
    that changes in steps (landed or not) is never interpolated."""
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 1)
    return np.asarray(values)[i]


def _unit(q: Array) -> Array:
    # keep a continuous sign before interpolating, then renormalise
    q = q.copy()
    flip = np.cumsum(np.concatenate([[0], (np.sum(q[1:] * q[:-1], axis=1) < 0).astype(int)])) % 2 == 1
    q[flip] *= -1.0
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _quat_on(t: Array, ts: Array, q: Array) -> Array:
    out = _interp(t, ts, _unit(q))
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def _quat_from_euler(roll: Array, pitch: Array, yaw: Array) -> Array:
    return np.stack([np.asarray(c, dtype=float) for c in quat.from_euler(roll, pitch, yaw)], axis=-1)


# --- PX4 ULog ----------------------------------------------------------------------------------


def read_ulog(path: str | Path) -> FlightSeries:
    try:
        from pyulog import ULog
    except ImportError:  # pragma: no cover - depends on the install
        raise RuntimeError("reading ULog needs pyulog: pip install 'ismdo-companion[logs]'") from None
    from .mavlink.airframe import lifted_by_rotors, rotor_count

    topics = ("vehicle_attitude", "sensor_combined", "vehicle_local_position", "actuator_motors",
              "vehicle_thrust_setpoint", "actuator_controls_0", "vehicle_land_detected")
    ulog = ULog(str(path), list(topics))
    data = {}
    for d in ulog.data_list:
        if d.multi_id == 0:
            data[d.name] = d.data
    for need in ("vehicle_attitude", "sensor_combined"):
        if need not in data:
            raise ValueError(f"{path}: no {need} topic in the log")
    params = ulog.initial_parameters
    if "MAV_TYPE" in params and not lifted_by_rotors(int(params["MAV_TYPE"])):
        raise ValueError(f"{path}: MAV_TYPE {int(params['MAV_TYPE'])} is not a multicopter: its thrust is not along "
                         "the body's z axis")
    imu = data["sensor_combined"]
    t_us = imu["timestamp"].astype(float)
    t = (t_us - t_us[0]) * 1e-6
    att = data["vehicle_attitude"]
    q = _quat_on(t_us, att["timestamp"].astype(float), np.stack([att[f"q[{i}]"] for i in range(4)], axis=-1))
    sf = np.stack([imu[f"accelerometer_m_s2[{i}]"] for i in range(3)], axis=-1).astype(float)
    vel = down = None
    if "vehicle_local_position" in data:
        lp = data["vehicle_local_position"]
        ts = lp["timestamp"].astype(float)
        vel = _interp(t_us, ts, np.stack([lp["vx"], lp["vy"], lp["vz"]], axis=-1))
        down = _interp(t_us, ts, lp["z"])
    motors = int(params["CA_ROTOR_COUNT"]) if params.get("CA_ROTOR_COUNT") else None
    if motors is None and "MAV_TYPE" in params:
        motors = rotor_count(int(params["MAV_TYPE"]))
    per_motor = False
    if "actuator_motors" in data:
        am = data["actuator_motors"]
        cols = [f"control[{i}]" for i in range(12) if f"control[{i}]" in am]
        u = np.stack([am[c] for c in cols], axis=-1).astype(float)
        used = [i for i in range(u.shape[1]) if np.isfinite(u[:, i]).all() and np.nanmax(np.abs(u[:, i])) > 0]
        motors = motors or (len(used) or None)
        thrust = _interp(t_us, am["timestamp"].astype(float), np.clip(u[:, used], 0.0, 1.0).sum(axis=1))
        per_motor = True
        src = f"actuator_motors (the sum of {motors or 'the'} motors' normalised commands)"
    elif "vehicle_thrust_setpoint" in data:
        ts_ = data["vehicle_thrust_setpoint"]
        thrust = _interp(t_us, ts_["timestamp"].astype(float), -ts_["xyz[2]"].astype(float))
        src = "vehicle_thrust_setpoint (the collective)"
    elif "actuator_controls_0" in data:
        ac = data["actuator_controls_0"]
        thrust = _interp(t_us, ac["timestamp"].astype(float), ac["control[3]"].astype(float))
        src = "actuator_controls_0 (the collective, PX4 before 1.13)"
    else:
        raise ValueError(f"{path}: no actuator_motors, vehicle_thrust_setpoint or actuator_controls_0: no thrust")
    airborne = None
    if "vehicle_land_detected" in data:
        ld = data["vehicle_land_detected"]
        airborne = ~_hold(t_us, ld["timestamp"].astype(float), ld["landed"].astype(bool))
    return FlightSeries(t, q, thrust, False, specific_force_body_m_s2=sf, vel_ned_m_s=vel,
                        source=f"ULog {Path(path).name}, thrust from {src}", thrust_per_motor=per_motor,
                        motor_count=motors, airborne=airborne, airborne_source="vehicle_land_detected",
                        down_m=down, starts_on_ground=True)


# --- MAVLink telemetry log ---------------------------------------------------------------------

_TLOG_TYPES = ["HEARTBEAT", "ATTITUDE_QUATERNION", "ATTITUDE", "HIGHRES_IMU", "SCALED_IMU", "RAW_IMU",
               "LOCAL_POSITION_NED", "ATTITUDE_TARGET", "VFR_HUD", "EXTENDED_SYS_STATE"]


class _TlogVehicle:
    """The rows of one vehicle's messages, each with a stamp in seconds of its boot clock."""

    def __init__(self) -> None:
        self.rows: dict[str, list[tuple[float, ...]]] = {k: [] for k in _TLOG_TYPES}
        self.stamp = math.nan
        self.autopilot: int | None = None
        self.mav_type: int | None = None

    def add(self, m: object) -> None:
        from pymavlink import mavutil

        kind = m.get_type()  # type: ignore[attr-defined]
        if hasattr(m, "time_boot_ms"):
            t = m.time_boot_ms * 1e-3  # type: ignore[attr-defined]
        elif hasattr(m, "time_usec"):
            t = m.time_usec * 1e-6  # type: ignore[attr-defined]
        else:
            t = self.stamp  # undated: the newest stamp before it
        self.stamp = t if not t < self.stamp else self.stamp
        if kind == "HEARTBEAT":
            if m.autopilot == mavutil.mavlink.MAV_AUTOPILOT_INVALID:  # type: ignore[attr-defined]
                return
            self.autopilot, self.mav_type = m.autopilot, m.type  # type: ignore[attr-defined]
            self.rows[kind].append((t, m.system_status))  # type: ignore[attr-defined]
        elif kind == "ATTITUDE_QUATERNION":
            self.rows[kind].append((t, m.q1, m.q2, m.q3, m.q4))  # type: ignore[attr-defined]
        elif kind == "ATTITUDE":
            self.rows[kind].append((t, m.roll, m.pitch, m.yaw))  # type: ignore[attr-defined]
        elif kind in ("HIGHRES_IMU", "SCALED_IMU", "RAW_IMU"):
            self.rows[kind].append((t, m.xacc, m.yacc, m.zacc))  # type: ignore[attr-defined]
        elif kind == "LOCAL_POSITION_NED":
            self.rows[kind].append((t, m.vx, m.vy, m.vz, m.z))  # type: ignore[attr-defined]
        elif kind == "ATTITUDE_TARGET":
            self.rows[kind].append((t, m.thrust))  # type: ignore[attr-defined]
        elif kind == "VFR_HUD":
            self.rows[kind].append((t, m.throttle / 100.0))  # type: ignore[attr-defined]
        elif kind == "EXTENDED_SYS_STATE":
            self.rows[kind].append((t, m.landed_state))  # type: ignore[attr-defined]

    def stamped(self, kind: str) -> Array:
        rows = [r for r in self.rows[kind] if math.isfinite(r[0])]
        return np.array(rows, dtype=float) if rows else np.empty((0, 2))


def read_tlog(path: str | Path) -> FlightSeries:
    from pymavlink import mavutil

    from .mavlink.airframe import (
        airborne_from_landed_state,
        ardupilot_airborne_from_system_status,
        lifted_by_rotors,
        rotor_count,
    )

    mlog = mavutil.mavlink_connection(str(path), robust_parsing=True)
    vehicles: dict[int, _TlogVehicle] = {}
    while True:
        m = mlog.recv_match(type=_TLOG_TYPES)
        if m is None:
            break
        if m.get_srcComponent() != mavutil.mavlink.MAV_COMP_ID_AUTOPILOT1:
            continue  # a ground station's, a companion's or a simulator's own messages
        vehicles.setdefault(m.get_srcSystem(), _TlogVehicle()).add(m)
    if not vehicles:
        raise ValueError(f"{path}: no messages from an autopilot (component 1)")
    v = max(vehicles.values(), key=lambda x: len(x.rows["ATTITUDE_QUATERNION"]) + len(x.rows["ATTITUDE"]))
    ardupilot = v.autopilot == mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    if v.mav_type is not None and not lifted_by_rotors(v.mav_type):
        raise ValueError(f"{path}: the vehicle's HEARTBEAT type {v.mav_type} is not a multicopter: its thrust is not "
                         "along the body's z axis")
    quat_rows, euler_rows = v.stamped("ATTITUDE_QUATERNION"), v.stamped("ATTITUDE")
    if not len(quat_rows) and not len(euler_rows):
        raise ValueError(f"{path}: needs ATTITUDE_QUATERNION or ATTITUDE messages")
    imu, imu_kind = v.stamped("HIGHRES_IMU"), "HIGHRES_IMU"
    if not len(imu):
        imu, imu_kind = v.stamped("SCALED_IMU"), "SCALED_IMU"
        if not len(imu) and ardupilot:  # ArduPilot's RAW_IMU is its first IMU, scaled as SCALED_IMU
            imu, imu_kind = v.stamped("RAW_IMU"), "RAW_IMU"
        if len(imu):
            imu[:, 1:] *= G0 / 1000.0  # milli-g
    pos = v.stamped("LOCAL_POSITION_NED")
    thrust_rows, thrust_kind = v.stamped("ATTITUDE_TARGET"), "ATTITUDE_TARGET.thrust"
    if not len(thrust_rows):
        thrust_rows, thrust_kind = v.stamped("VFR_HUD"), "VFR_HUD.throttle"
    if not len(thrust_rows):
        raise ValueError(f"{path}: needs ATTITUDE_TARGET or VFR_HUD messages (the thrust)")
    base = pos if len(pos) else imu
    if len(base) == 0:
        raise ValueError(f"{path}: neither HIGHRES_IMU/SCALED_IMU/RAW_IMU nor LOCAL_POSITION_NED")
    t_abs = base[:, 0]
    if len(quat_rows):
        q, att_kind = _quat_on(t_abs, quat_rows[:, 0], quat_rows[:, 1:]), "ATTITUDE_QUATERNION"
    else:
        euler = _quat_from_euler(euler_rows[:, 1], euler_rows[:, 2], euler_rows[:, 3])
        q, att_kind = _quat_on(t_abs, euler_rows[:, 0], euler), "ATTITUDE"
    thrust = _interp(t_abs, thrust_rows[:, 0], thrust_rows[:, 1])
    sf = _interp(t_abs, imu[:, 0], imu[:, 1:]) if len(imu) else None
    vel = _interp(t_abs, pos[:, 0], pos[:, 1:4]) if len(pos) else None
    down = _interp(t_abs, pos[:, 0], pos[:, 4]) if len(pos) else None
    airborne, airborne_source = _tlog_airborne(t_abs, v, ardupilot, airborne_from_landed_state,
                                               ardupilot_airborne_from_system_status)
    motors = rotor_count(v.mav_type) if v.mav_type is not None else None
    what = ", ".join(x for x in (att_kind, imu_kind if len(imu) else "", "LOCAL_POSITION_NED" if len(pos) else "",
                                 thrust_kind) if x)
    return FlightSeries(t_abs - t_abs[0], q, thrust, False, specific_force_body_m_s2=sf, vel_ned_m_s=vel,
                        source=f"tlog {Path(path).name} ({what})", motor_count=motors, airborne=airborne,
                        airborne_source=airborne_source, down_m=down, starts_on_ground=True)


def _tlog_airborne(t: Array, v: _TlogVehicle, ardupilot: bool, from_landed_state, from_status  # type: ignore[no-untyped-def]
                   ) -> tuple[Array | None, str]:
    for kind, convert, name in (("EXTENDED_SYS_STATE", from_landed_state, "EXTENDED_SYS_STATE.landed_state"),
                                ("HEARTBEAT", from_status if ardupilot else None, "HEARTBEAT.system_status")):
        if convert is None:
            continue
        said = [(r[0], convert(int(r[1]))) for r in v.stamped(kind)]
        said = [(ts, a) for ts, a in said if a is not None]
        if said:
            stamps = np.array([s[0] for s in said])
            return _hold(t, stamps, np.array([s[1] for s in said], dtype=bool)), name
    return None, ""


# --- ArduPilot DataFlash -----------------------------------------------------------------------


def read_dataflash(path: str | Path) -> FlightSeries:
    """An ArduCopter DataFlash log (.bin). Each message's TimeUS is its stamp."""
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()):  # DFReader prints a line per damaged header
        return _read_dataflash(path)


def _read_dataflash(path: str | Path) -> FlightSeries:
    from pymavlink import DFReader

    log = DFReader.DFReader_binary(str(path))
    rows: dict[str, list[tuple[float, ...]]] = {k: [] for k in ("ATT", "IMU", "KF", "CTUN", "EV")}
    frame_class = None
    kf_name = None
    while True:
        m = log.recv_match(type=["ATT", "IMU", "XKF1", "NKF1", "CTUN", "EV", "PARM", "MSG"])
        if m is None:
            break
        kind = m.get_type()
        if kind == "MSG":
            other = next((v for v in ("ArduPlane", "ArduRover", "ArduSub", "Blimp") if m.Message.startswith(v)), None)
            if other is not None:  # ArduPlane's CTUN has a ThO too: a forward thrust
                raise ValueError(f"{path}: an {other} log ({m.Message.strip()}): companion estimate reads "
                                 "multicopters (ArduCopter)")
            continue
        if kind == "PARM":
            if m.Name == "FRAME_CLASS":
                frame_class = int(m.Value)
            continue
        t = m.TimeUS * 1e-6
        if kind == "ATT":
            rows["ATT"].append((t, math.radians(m.Roll), math.radians(m.Pitch), math.radians(m.Yaw)))
        elif kind == "IMU":
            if getattr(m, "I", 0) == 0:
                rows["IMU"].append((t, m.AccX, m.AccY, m.AccZ))
        elif kind in ("XKF1", "NKF1"):
            if getattr(m, "C", 0) == 0 and kf_name in (None, kind):  # the primary core of one EKF
                kf_name = kind
                rows["KF"].append((t, m.VN, m.VE, m.VD, m.PD))
        elif kind == "CTUN":
            rows["CTUN"].append((t, m.ThO))
        elif kind == "EV":
            if m.Id in (EV_LAND_COMPLETE, EV_NOT_LANDED):
                rows["EV"].append((t, 1.0 if m.Id == EV_NOT_LANDED else 0.0))
    for need, what in (("ATT", "ATT (attitude)"), ("IMU", "IMU (accelerometer)"), ("CTUN", "CTUN.ThO (thrust)")):
        if not rows[need]:
            raise ValueError(f"{path}: no {what} messages: not an ArduCopter DataFlash log, or its LOG_BITMASK "
                             "leaves them out")
    imu = np.array(rows["IMU"])
    t_abs = imu[:, 0]
    att = np.array(rows["ATT"])
    q = _quat_on(t_abs, att[:, 0], _quat_from_euler(att[:, 1], att[:, 2], att[:, 3]))
    ctun = np.array(rows["CTUN"])
    thrust = _interp(t_abs, ctun[:, 0], ctun[:, 1])
    vel = down = None
    if rows["KF"]:
        kf = np.array(rows["KF"])
        vel, down = _interp(t_abs, kf[:, 0], kf[:, 1:4]), _interp(t_abs, kf[:, 0], kf[:, 4])
    # the land detector: landed at the start (ArduCopter logs from boot or arming), then its events
    ev = np.array([(t_abs[0], 0.0), *rows["EV"]])
    airborne = _hold(t_abs, ev[:, 0], ev[:, 1].astype(bool))
    return FlightSeries(t_abs - t_abs[0], q, thrust, False, specific_force_body_m_s2=imu[:, 1:], vel_ned_m_s=vel,
                        source=f"DataFlash {Path(path).name} (ATT, IMU, {kf_name or 'no EKF'}, CTUN.ThO)",
                        motor_count=COPTER_FRAME_ROTORS.get(frame_class) if frame_class is not None else None,
                        airborne=airborne, airborne_source="ArduCopter's land detector (EV events)", down_m=down,
                        starts_on_ground=True)


# --- CSV ---------------------------------------------------------------------------------------


def parse_columns(text: str) -> dict[str, str]:
    """``"t=time,qw=q0,..."`` or ``"sitl"`` -> {field: column}."""
    if text == "sitl":
        return dict(SITL_COLUMNS)
    out = {}
    for part in text.split(","):
        field, sep, col = part.partition("=")
        if not sep:
            raise ValueError(f"column map entry {part!r}: expected FIELD=COLUMN")
        field = field.strip()
        if field not in CSV_FIELDS:
            raise ValueError(f"column map entry {part!r}: unknown field {field!r} (fields: {', '.join(CSV_FIELDS)})")
        out[field] = col.strip()
    return out


def _read_columns(path: str | Path, rows: Iterable[list[str]], columns: Mapping[str, str]) -> dict[str, Array]:
    """The mapped columns of a CSV, row by row: one float per mapped cell, nothing else kept. A
    row cut short, a word, NaN or inf is named by row and column, never averaged in."""
    it = iter(rows)
    header = next(it, None)
    if header is None:
        raise ValueError(f"{path}: no rows")
    where = {name: i for i, name in reversed(list(enumerate(header)))}
    for field, name in columns.items():
        if name not in where:
            raise ValueError(f"{path}: no column {name!r} (for {field}); columns: {', '.join(header)}")
    fields = list(columns)
    index = [where[columns[f]] for f in fields]
    out = [array("d") for _ in fields]
    for row_no, row in enumerate(it, start=2):
        if not row:
            continue  # a blank line, as csv.DictReader skips it
        for j, i in enumerate(index):
            cell = row[i] if i < len(row) else None
            try:
                value = float(cell)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                value = math.nan
            if not math.isfinite(value):
                what = "missing (the row is cut short)" if cell is None else f"{cell!r} is not a finite number"
                raise ValueError(f"{path}: row {row_no}, column {columns[fields[j]]!r}: {what}")
            out[j].append(value)
    if out and not len(out[0]):
        raise ValueError(f"{path}: no rows")
    return {f: np.frombuffer(a, dtype=float) for f, a in zip(fields, out)}


def read_csv(path: str | Path, columns: Mapping[str, str], *, thrust_is_newtons: bool = False,
             world_frame: str = "ned", body_frame: str = "frd") -> FlightSeries:
    """A CSV log; ``columns`` maps the fields above to the file's column names (so a scalar-last
    file simply maps qw to its fourth quaternion column)."""
    import gzip

    opener = gzip.open if str(path).endswith(".gz") else open
    with opener(path, "rt", newline="") as f:  # type: ignore[operator]
        cols = _read_columns(path, csv.reader(f), columns)

    def vec3(*fields: str) -> Array | None:
        parts = [cols.get(f) for f in fields]
        if all(p is None for p in parts):
            return None
        if any(p is None for p in parts):
            raise ValueError(f"{path}: map all of {', '.join(fields)} or none")
        return np.stack(parts, axis=-1)  # type: ignore[arg-type]

    t = cols.get("t")
    if t is None:
        raise ValueError("the column map needs t")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise ValueError(f"{path}: row {i + 2}, column {columns['t']!r}: time goes backwards ({t[i]:g} after "
                         f"{t[i - 1]:g})")
    q = vec3("qw", "qx", "qy", "qz")
    if q is None:
        raise ValueError("the column map needs qw, qx, qy, qz")
    sf = vec3("ax", "ay", "az")
    vel = vec3("vx", "vy", "vz")
    truth = vec3("truth_x", "truth_y", "truth_z")
    down = cols.get("z")
    if world_frame == "enu":
        vel = enu_to_ned(vel) if vel is not None else None
        truth = enu_to_ned(truth) if truth is not None else None
        down = -down if down is not None else None
    if body_frame == "flu":
        sf = flu_to_frd(sf) if sf is not None else None
    if world_frame == "enu" or body_frame == "flu":
        if world_frame != "enu" or body_frame != "flu":
            raise ValueError("attitude conversion supports ned/frd or enu/flu (ROS) pairs")
        q = quat_enu_flu_to_ned_frd(q)
    thrust = cols.get("thrust")
    if thrust is None:
        raise ValueError("the column map needs thrust")
    landed = cols.get("landed")
    return FlightSeries(t - t[0], _unit(q), thrust, thrust_is_newtons, specific_force_body_m_s2=sf,
                        vel_ned_m_s=vel, truth_force_ned_n=truth, source=f"CSV {Path(path).name}",
                        airborne=None if landed is None else landed == 0.0,
                        airborne_source=f"column {columns.get('landed')!r}", down_m=down)


# --- by extension ------------------------------------------------------------------------------


def read_log(path: str | Path, columns: str | None = None, **csv_options: object) -> FlightSeries:
    """By extension: .ulg, .tlog, .bin, .csv / .csv.gz (which needs ``columns``). Whatever the file
    holds, a log that cannot be read is a ValueError naming it (the command line prints one line)."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{path}: is a directory, not a log")
    if not p.is_file():
        raise ValueError(f"{path}: no such file")
    if p.stat().st_size == 0:
        raise ValueError(f"{path}: the file is empty")
    try:
        return _read_log(path, columns, **csv_options)
    except (ValueError, RuntimeError, OSError):
        raise
    except Exception as exc:  # a damaged file makes the parsers raise anything (pyulog, pymavlink)
        raise ValueError(f"{path}: cannot be read as its extension says ({type(exc).__name__}: {exc})") from None


def _read_log(path: str | Path, columns: str | None = None, **csv_options: object) -> FlightSeries:
    name = str(path).lower()
    if name.endswith(".ulg"):
        return read_ulog(path)
    if name.endswith(".tlog"):
        return read_tlog(path)
    if name.endswith(".bin"):
        return read_dataflash(path)
    if name.endswith(".csv") or name.endswith(".csv.gz"):
        if columns is None:
            raise ValueError("a CSV log needs --columns (FIELD=COLUMN,... or 'sitl')")
        cols = parse_columns(columns)
        if columns == "sitl":  # the project's records carry the thrust in newtons
            csv_options["thrust_is_newtons"] = True
        return read_csv(path, cols, **csv_options)  # type: ignore[arg-type]
    raise ValueError(f"{path}: unknown log type (expected .ulg, .tlog, .bin, .csv or .csv.gz)")
