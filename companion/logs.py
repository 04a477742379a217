"""Readers that bring a flight log to :class:`companion.estimate.FlightSeries`.

- PX4 ULog (pyulog, the optional ``logs`` extra): ``vehicle_attitude.q`` (scalar-first, FRD to
  NED), ``sensor_combined.accelerometer_m_s2`` (FRD), ``vehicle_local_position.v[xyz]`` (NED) and
  the collective thrust, from ``actuator_motors`` (sum of the normalised motor commands) or else
  ``vehicle_thrust_setpoint.xyz[2]``; all resampled onto the accelerometer's time base.
- MAVLink telemetry log .tlog (pymavlink): ATTITUDE_QUATERNION, HIGHRES_IMU (or SCALED_IMU),
  LOCAL_POSITION_NED, and ATTITUDE_TARGET.thrust (normalised).
- CSV with a column map ``field=column`` (fields: t, qw, qx, qy, qz, ax, ay, az (specific force,
  body), vx, vy, vz, thrust, and truth_x, truth_y, truth_z), or the preset ``sitl`` for the
  project's own flight records (``FlightLog.to_csv``: true attitude and velocity, thrust in N,
  the true external force); frames converted with the explicit converters of
  :mod:`companion.estimate`.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Mapping

import numpy as np

from .estimate import (
    Array,
    FlightSeries,
    enu_to_ned,
    flu_to_frd,
    quat_enu_flu_to_ned_frd,
)

__all__ = ["read_log", "read_ulog", "read_tlog", "read_csv", "SITL_COLUMNS", "parse_columns"]

G0 = 9.80665

SITL_COLUMNS: dict[str, str] = {
    "t": "t", "qw": "qw", "qx": "qx", "qy": "qy", "qz": "qz", "vx": "vx", "vy": "vy", "vz": "vz",
    "thrust": "thrust_sp", "truth_x": "hfx", "truth_y": "hfy", "truth_z": "hfz",
}
"""the project's flight records (sitl.lab.simulation.LOG_COLUMNS): thrust in newtons"""


def _interp(t: Array, ts: Array, values: Array) -> Array:
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        return np.interp(t, ts, values)
    return np.stack([np.interp(t, ts, values[:, i]) for i in range(values.shape[1])], axis=-1)


def _unit(q: Array) -> Array:
    # keep a continuous sign before interpolating, then renormalise
    q = q.copy()
    flip = np.cumsum(np.concatenate([[0], (np.sum(q[1:] * q[:-1], axis=1) < 0).astype(int)])) % 2 == 1
    q[flip] *= -1.0
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def read_ulog(path: str | Path) -> FlightSeries:
    try:
        from pyulog import ULog
    except ImportError:  # pragma: no cover - depends on the install
        raise RuntimeError("reading ULog needs pyulog: pip install 'ismdo-companion[logs]'") from None
    topics = ("vehicle_attitude", "sensor_combined", "vehicle_local_position", "actuator_motors",
              "vehicle_thrust_setpoint")
    ulog = ULog(str(path), list(topics))
    data = {}
    for d in ulog.data_list:
        if d.multi_id == 0:
            data[d.name] = d.data
    for need in ("vehicle_attitude", "sensor_combined"):
        if need not in data:
            raise ValueError(f"{path}: no {need} topic in the log")
    imu = data["sensor_combined"]
    t_us = imu["timestamp"].astype(float)
    t = (t_us - t_us[0]) * 1e-6
    att = data["vehicle_attitude"]
    q = _unit(np.stack([att[f"q[{i}]"] for i in range(4)], axis=-1).astype(float))
    q = _interp(t_us, att["timestamp"].astype(float), q)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    sf = np.stack([imu[f"accelerometer_m_s2[{i}]"] for i in range(3)], axis=-1).astype(float)
    vel = None
    if "vehicle_local_position" in data:
        lp = data["vehicle_local_position"]
        vel = _interp(t_us, lp["timestamp"].astype(float), np.stack([lp["vx"], lp["vy"], lp["vz"]], axis=-1))
    if "actuator_motors" in data:
        am = data["actuator_motors"]
        cols = [f"control[{i}]" for i in range(12) if f"control[{i}]" in am]
        u = np.stack([am[c] for c in cols], axis=-1).astype(float)
        used = [i for i in range(u.shape[1]) if np.isfinite(u[:, i]).all() and np.nanmax(np.abs(u[:, i])) > 0]
        thrust = _interp(t_us, am["timestamp"].astype(float), np.clip(u[:, used], 0.0, 1.0).sum(axis=1))
        src = f"actuator_motors ({len(used)} motors, sum of normalised commands)"
    elif "vehicle_thrust_setpoint" in data:
        ts = data["vehicle_thrust_setpoint"]
        thrust = _interp(t_us, ts["timestamp"].astype(float), -ts["xyz[2]"].astype(float))
        src = "vehicle_thrust_setpoint"
    else:
        raise ValueError(f"{path}: no actuator_motors or vehicle_thrust_setpoint: no thrust")
    return FlightSeries(t, q, thrust, False, specific_force_body_m_s2=sf, vel_ned_m_s=vel,
                        source=f"ULog {Path(path).name}, thrust from {src}")


def read_tlog(path: str | Path) -> FlightSeries:
    from pymavlink import mavutil

    mlog = mavutil.mavlink_connection(str(path), robust_parsing=True)
    rows: dict[str, list[tuple[float, ...]]] = {"q": [], "imu": [], "vel": [], "thrust": []}
    while True:
        m = mlog.recv_match(type=["ATTITUDE_QUATERNION", "HIGHRES_IMU", "SCALED_IMU", "LOCAL_POSITION_NED",
                                  "ATTITUDE_TARGET"])
        if m is None:
            break
        kind = m.get_type()
        if kind == "ATTITUDE_QUATERNION":
            rows["q"].append((m.time_boot_ms * 1e-3, m.q1, m.q2, m.q3, m.q4))
        elif kind == "HIGHRES_IMU":
            rows["imu"].append((m.time_usec * 1e-6, m.xacc, m.yacc, m.zacc))
        elif kind == "SCALED_IMU" and not rows["imu"]:
            rows.setdefault("scaled", []).append((m.time_boot_ms * 1e-3, m.xacc * G0 / 1000.0,
                                                  m.yacc * G0 / 1000.0, m.zacc * G0 / 1000.0))
        elif kind == "LOCAL_POSITION_NED":
            rows["vel"].append((m.time_boot_ms * 1e-3, m.vx, m.vy, m.vz))
        elif kind == "ATTITUDE_TARGET":
            rows["thrust"].append((m.time_boot_ms * 1e-3, m.thrust))
    imu = rows["imu"] or rows.get("scaled", [])
    if not rows["q"] or not rows["thrust"]:
        raise ValueError(f"{path}: needs ATTITUDE_QUATERNION and ATTITUDE_TARGET messages")
    base = np.array(rows["vel"] if rows["vel"] else imu)
    if len(base) == 0:
        raise ValueError(f"{path}: neither HIGHRES_IMU/SCALED_IMU nor LOCAL_POSITION_NED")
    t_abs = base[:, 0]
    qa = np.array(rows["q"])
    q = _interp(t_abs, qa[:, 0], _unit(qa[:, 1:]))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ta = np.array(rows["thrust"])
    thrust = _interp(t_abs, ta[:, 0], ta[:, 1])
    sf = _interp(t_abs, np.array(imu)[:, 0], np.array(imu)[:, 1:]) if imu else None
    vel = _interp(t_abs, np.array(rows["vel"])[:, 0], np.array(rows["vel"])[:, 1:]) if rows["vel"] else None
    return FlightSeries(t_abs - t_abs[0], q, thrust, False, specific_force_body_m_s2=sf, vel_ned_m_s=vel,
                        source=f"tlog {Path(path).name}")


def parse_columns(text: str) -> dict[str, str]:
    """``"t=time,qw=q0,..."`` or ``"sitl"`` -> {field: column}."""
    if text == "sitl":
        return dict(SITL_COLUMNS)
    out = {}
    for part in text.split(","):
        field, sep, col = part.partition("=")
        if not sep:
            raise ValueError(f"column map entry {part!r}: expected FIELD=COLUMN")
        out[field.strip()] = col.strip()
    return out


def read_csv(path: str | Path, columns: Mapping[str, str], *, thrust_is_newtons: bool = False,
             world_frame: str = "ned", body_frame: str = "frd") -> FlightSeries:
    """A CSV log; ``columns`` maps the fields above to the file's column names (so a scalar-last
    file simply maps qw to its fourth quaternion column)."""
    import gzip

    opener = gzip.open if str(path).endswith(".gz") else open
    with opener(path, "rt", newline="") as f:  # type: ignore[operator]
        reader = csv.DictReader(f)
        rows = list(reader)
    if not rows:
        raise ValueError(f"{path}: no rows")

    def col(field: str) -> Array | None:
        name = columns.get(field)
        if name is None:
            return None
        if name not in rows[0]:
            raise ValueError(f"{path}: no column {name!r} (for {field}); columns: {', '.join(rows[0])}")
        out = np.empty(len(rows))
        for i, r in enumerate(rows):
            cell = r.get(name)
            try:
                out[i] = float(cell)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                out[i] = math.nan
            if not math.isfinite(out[i]):  # a row cut short, a word, NaN or inf: named, never averaged in
                what = "missing (the row is cut short)" if cell is None else f"{cell!r} is not a finite number"
                raise ValueError(f"{path}: row {i + 2}, column {name!r}: {what}")
        return out

    def vec3(*fields: str) -> Array | None:
        parts = [col(f) for f in fields]
        if all(p is None for p in parts):
            return None
        if any(p is None for p in parts):
            raise ValueError(f"{path}: map all of {', '.join(fields)} or none")
        return np.stack(parts, axis=-1)  # type: ignore[arg-type]

    t = col("t")
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
    if world_frame == "enu":
        vel = enu_to_ned(vel) if vel is not None else None
        truth = enu_to_ned(truth) if truth is not None else None
    if body_frame == "flu":
        sf = flu_to_frd(sf) if sf is not None else None
    if world_frame == "enu" or body_frame == "flu":
        if world_frame != "enu" or body_frame != "flu":
            raise ValueError("attitude conversion supports ned/frd or enu/flu (ROS) pairs")
        q = quat_enu_flu_to_ned_frd(q)
    thrust = col("thrust")
    if thrust is None:
        raise ValueError("the column map needs thrust")
    return FlightSeries(t - t[0], _unit(q), thrust, thrust_is_newtons, specific_force_body_m_s2=sf,
                        vel_ned_m_s=vel, truth_force_ned_n=truth, source=f"CSV {Path(path).name}")


def read_log(path: str | Path, columns: str | None = None, **csv_options: object) -> FlightSeries:
    """By extension: .ulg, .tlog, .csv / .csv.gz (which needs ``columns``). Whatever the file holds,
    a log that cannot be read is a ValueError naming it (the command line prints one line)."""
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
    if name.endswith(".csv") or name.endswith(".csv.gz"):
        if columns is None:
            raise ValueError("a CSV log needs --columns (FIELD=COLUMN,... or 'sitl')")
        cols = parse_columns(columns)
        if columns == "sitl":  # the project's records carry the thrust in newtons
            csv_options["thrust_is_newtons"] = True
        return read_csv(path, cols, **csv_options)  # type: ignore[arg-type]
    raise ValueError(f"{path}: unknown log type (expected .ulg, .tlog, .csv or .csv.gz)")
