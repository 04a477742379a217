"""The flight record: time series, raw MAVLink traffic, per-segment summary, all streamed to disk.

A flight folder holds

- ``timeseries.csv``: one row per control tick (state, reference, setpoint, estimates);
- ``traffic.tlog``: every datagram sent and received, each prefixed with its 8-byte big-endian
  microsecond UNIX time (the format MAVProxy writes and pymavlink's ``mavlogdump``/MAVExplorer read);
- ``health.csv``: every 10 vehicle seconds, the companion's memory, CPU, receive queue, message
  and setpoint rates (:mod:`companion.flight.health`);
- ``segments.json`` and ``summary.md``: per mission step, RMS and peak position error, peak tilt,
  the final external-force estimate and the thrust-scale estimate (strict JSON: no NaN);
- ``metadata.json``: what a researcher cites — project version and commit, the mission as flown
  (its file copied beside it), controller, gains and every other parameter, the autopilot's kind,
  version and a parameter snapshot, the host.

Rows go straight to the file and the segment statistics are running sums, so memory stays flat
however long the flight. A disk that fills or fails mid-flight stops the recording, with one
warning, and never the flight: the flight goes on and lands as it would have.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import shutil
import struct
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import IO

from companion.control import quaternion as quat

from .health import HEALTH_COLUMNS
from .offboard import PositionTarget, Tick
from companion.link.state import VehicleState
from companion.mavlink.wire import frames

__all__ = ["COLUMNS", "SegmentStats", "FlightRecorder"]

COLUMNS = (
    "t", "wall", "step", "offboard", "streaming",
    "x", "y", "z", "vx", "vy", "vz",
    "x_ref", "y_ref", "z_ref", "vx_ref", "vy_ref", "vz_ref", "yaw_ref",
    "qw", "qx", "qy", "qz",
    "qw_d", "qx_d", "qy_d", "qz_d", "p_d", "q_d", "r_d",
    "thrust_n", "thrust", "fx", "fy", "fz", "hfx", "hfy", "hfz",
    "thrust_max_n", "thrust_max_est_n", "t_pos", "error_m",
)
"""t: vehicle clock [s]; wall: seconds since the flight started; step: mission step index;
offboard: the autopilot flies our setpoints (1/0); streaming: a setpoint was sent this tick;
positions NED [m], in the frame the flight began in (the autopilot's estimate less the estimator
resets found: companion/link/resets.py; the estimate itself is in traffic.tlog); *_ref the reference;
q* the vehicle's attitude, q*_d and p_d.. the setpoint
(rates in rad/s); thrust_n the controller's thrust [N], thrust the normalised value sent;
f* the controller's force [N]; hf* the force-disturbance estimate [N]; thrust_max_n the scale in
use, thrust_max_est_n its online estimate [N]; t_pos: the vehicle time the position was measured at
[s]; error_m: the distance from the reference *at t_pos* [m] (the tracking error: x - x_ref
compares a position some ms old with the reference at the controller's time, t)."""


class ReferenceTrail:
    """The recent reference positions, to read the reference at a measurement's own time.

    Telemetry reaches the controller some ms after it was measured, and the controller's time
    runs that much ahead of it: at 2 m/s each 10 ms of that latency would count as 2 cm of
    "error" that no controller could remove. The tracking error compares like with like."""

    def __init__(self, length: int = 128) -> None:
        self._t: deque[float] = deque(maxlen=length)
        self._p: deque[tuple[float, float, float]] = deque(maxlen=length)

    def add(self, t: float, pos: tuple[float, float, float]) -> None:
        if not self._t or t > self._t[-1]:
            self._t.append(t)
            self._p.append(pos)

    def at(self, t: float) -> tuple[float, float, float] | None:
        """The reference at vehicle time ``t`` (linear between ticks; the ends beyond the trail)."""
        ts, ps = self._t, self._p
        if not ts:
            return None
        if t >= ts[-1]:
            return ps[-1]
        for i in range(len(ts) - 1, 0, -1):
            if ts[i - 1] <= t:
                w = (t - ts[i - 1]) / (ts[i] - ts[i - 1])
                a, b = ps[i - 1], ps[i]
                return (a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2]))
        return ps[0]


@dataclass
class SegmentStats:
    """Running statistics of one mission step."""

    index: int
    name: str
    action: str
    t_start: float
    t_end: float = math.nan
    samples: int = 0
    sum_sq_error: float = 0.0
    peak_error_m: float = 0.0
    peak_tilt_deg: float = 0.0
    force_estimate_n: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    thrust_max_est_n: float = math.nan
    position_resets: int = 0
    """estimator resets found during the step (re-anchored: companion/link/resets.py)"""
    ok: bool = True
    note: str = ""

    @property
    def rms_error_m(self) -> float:
        return math.sqrt(self.sum_sq_error / self.samples) if self.samples else math.nan

    def as_dict(self) -> dict:
        d = asdict(self)
        d["rms_error_m"] = self.rms_error_m
        return d


_ROW = ",".join(("%.4f", "%.4f", "%d", "%d", "%d", *("%.5g",) * (len(COLUMNS) - 7), "%.4f", "%.5g")) + "\r\n"
"""one row of timeseries.csv, formatted in one operation (the csv module's own line ending)"""

FLUSH_INTERVAL_S = 0.25
"""the record is handed to the operating system at least this often (wall time): a companion killed
outright (kill -9, a crash) loses at most the last quarter second of its record"""


@dataclass
class FlightRecorder:
    folder: Path
    segments: list[SegmentStats] = field(default_factory=list)

    warn: Callable[[str], None] = print
    failed: str | None = None
    """why the recording stopped (a full or failing disk), or None"""

    def __post_init__(self) -> None:
        """Creates the folder and its files: OSError if that cannot be done (the caller refuses to fly)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        self._csv_file: IO[str] = open(self.folder / "timeseries.csv", "w", newline="", buffering=1 << 16)
        self._csv = csv.writer(self._csv_file)
        self._csv.writerow(COLUMNS)
        self._tlog: IO[bytes] = open(self.folder / "traffic.tlog", "wb", buffering=1 << 16)
        self._wall0 = time.monotonic()
        self.rows = 0
        self._health: IO[str] | None = None
        self._trail = ReferenceTrail()
        self._flushed = self._wall0

    def _flush_due(self) -> None:
        """Hand what is buffered to the operating system every FLUSH_INTERVAL_S."""
        now = time.monotonic()
        if now - self._flushed >= FLUSH_INTERVAL_S:
            self._flushed = now
            self._csv_file.flush()
            self._tlog.flush()

    def _fail(self, exc: OSError) -> None:
        """Stop recording (the flight goes on); say so once."""
        if self.failed is None:
            self.failed = f"{exc.strerror or exc} ({self.folder})"
            self.warn(f"WARNING: the flight record stopped: {self.failed}; the flight goes on")
            for f in (self._csv_file, self._tlog, self._health):
                with contextlib.suppress(Exception):
                    if f is not None:
                        f.close()

    # --- raw traffic -------------------------------------------------------------------------

    def traffic(self, datagram: bytes) -> None:
        """A datagram into the .tlog: one record per frame (a datagram may carry several; readers
        such as pymavlink's expect one), or the datagram whole if it is not whole frames."""
        if self.failed is not None:
            return
        try:
            stamp = struct.pack(">Q", int(time.time() * 1e6))
            self._tlog.write(b"".join(stamp + frame for frame in frames(datagram) or (datagram,)))
            self._flush_due()
        except OSError as exc:
            self._fail(exc)

    # --- segments ------------------------------------------------------------------------

    def begin(self, index: int, name: str, action: str, t: float) -> SegmentStats:
        if self.segments and math.isnan(self.segments[-1].t_end):
            self.segments[-1].t_end = t
        seg = SegmentStats(index, name, action, t)
        self.segments.append(seg)
        return seg

    def end(self, t: float, ok: bool = True, note: str = "") -> None:
        if self.segments:
            seg = self.segments[-1]
            if math.isnan(seg.t_end):
                seg.t_end = t
            seg.ok = seg.ok and ok
            if note:
                seg.note = note

    # --- rows ------------------------------------------------------------------------------

    def row(self, state: VehicleState, tick: Tick | None, streaming: bool, thrust_max_n: float,
            thrust_max_est_n: float) -> None:
        seg = self.segments[-1] if self.segments else None
        wall = time.monotonic() - self._wall0
        p, v, q = state.pos_ned_m, state.vel_ned_m_s, state.q
        tilt = math.degrees(quat.tilt_angle(q))
        if tick is None:
            nan = math.nan
            ref = (nan,) * 7
            sp = (nan,) * 7
            thrust = (nan, nan)
            force = (nan,) * 6
            t = state.t
            err = nan
        else:
            r = tick.reference
            ref = (*r.pos_ned_m, *r.vel_ned_m_s, r.yaw_rad)
            a = tick.attitude
            if isinstance(tick.setpoint, PositionTarget):  # the autopilot's own position control flies
                sp = (*a.q_d, math.nan, math.nan, math.nan)
                thrust = (math.nan, math.nan)
            else:
                sp = (*tick.setpoint.q, *tick.setpoint.body_rates_rad_s)
                thrust = (float(a.thrust_n), tick.setpoint.thrust)
            force = (*tick.force_n, *tick.estimate_n)
            t = tick.t
            self._trail.add(t, r.pos_ned_m)
            ref_then = self._trail.at(state.t_pos)
            err = math.dist(p, ref_then if ref_then is not None else r.pos_ned_m)
            if seg is not None:
                seg.samples += 1
                seg.sum_sq_error += err * err
                seg.peak_error_m = max(seg.peak_error_m, err)
                if not math.isnan(tick.estimate_n[0]):
                    seg.force_estimate_n = tuple(float(x) for x in tick.estimate_n)  # type: ignore[assignment]
                seg.thrust_max_est_n = thrust_max_est_n
        if seg is not None:
            seg.peak_tilt_deg = max(seg.peak_tilt_deg, tilt)
        if self.failed is not None:
            return
        try:
            self._csv_file.write(_ROW % (
                t, wall, seg.index if seg else -1, int(state.offboard), int(streaming),
                *p, *v, *ref, *q, *sp, *thrust, *force, thrust_max_n, thrust_max_est_n, state.t_pos, err,
            ))
            self._flush_due()
        except OSError as exc:
            self._fail(exc)
            return
        self.rows += 1

    def health(self, row: tuple) -> None:
        """A row of ``health.csv`` (:mod:`companion.flight.health`)."""
        if self.failed is not None:
            return
        try:
            if self._health is None:
                self._health = open(self.folder / "health.csv", "w", newline="", buffering=1)
                csv.writer(self._health).writerow(HEALTH_COLUMNS)
            csv.writer(self._health).writerow(row)
        except OSError as exc:
            self._fail(exc)

    def metadata(self, meta: dict, mission_file: Path | None = None) -> None:
        """``metadata.json`` (and a copy of the mission file beside it)."""
        if self.failed is not None:
            return
        try:
            if mission_file is not None and mission_file.is_file():
                shutil.copyfile(mission_file, self.folder / f"mission{mission_file.suffix}")
            (self.folder / "metadata.json").write_text(strict_json(meta))
        except OSError as exc:
            self._fail(exc)

    # --- closing -------------------------------------------------------------------------

    def close(self, summary: dict) -> None:
        data = {**summary, "segments": [s.as_dict() for s in self.segments]}
        data["record"] = "complete" if self.failed is None else f"stopped: {self.failed}"
        if self.failed is not None:
            return
        try:
            self._csv_file.close()
            self._tlog.close()
            if self._health is not None:
                self._health.close()
            (self.folder / "segments.json").write_text(strict_json(data))
            (self.folder / "summary.md").write_text(summary_markdown(data))
        except OSError as exc:
            self._fail(exc)


def _finite(x: object) -> object:
    """JSON's own values only: a non-finite float is null, tuples are lists, anything else its text."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if x is None or isinstance(x, (bool, int, str)):
        return x
    return str(x)


def strict_json(data: object) -> str:
    """JSON as RFC 8259 has it (no NaN or Infinity, which other tools refuse)."""
    return json.dumps(_finite(data), indent=1, allow_nan=False)


def summary_markdown(data: dict) -> str:
    lines = [
        f"# Flight: {data.get('mission', '')}",
        "",
        f"- result: **{data.get('result', '')}**",
        f"- controller: {data.get('controller', '')} at {data.get('rate_hz', '')} Hz, "
        f"backend {data.get('backend', '')}, autopilot {data.get('autopilot', '')}",
        f"- thrust scale: {_fmt(data.get('thrust_max_n'))} N in use, online estimate "
        f"{_fmt(data.get('thrust_max_est_n'))} N",
        f"- setpoints sent: {data.get('setpoints_sent', '')} "
        f"({_fmt(data.get('setpoint_rate_hz'))} Hz measured over the offboard flight, "
        f"{data.get('rate_hz', '')} Hz asked for), rejected by the guard: {data.get('setpoints_rejected', '')}",
        *([f"- skipped on this vehicle: {'; '.join(data['skipped_steps'])}"] if data.get("skipped_steps") else []),
        *([f"- parameters NOT put back: {data['params_not_restored']}"] if data.get("params_not_restored") else []),
        *([f"- parameters put back: {data['params_restored']}"] if data.get("params_restored") else []),
        *([f"- parameters kept (the mission's keep): {data['params_kept']}"] if data.get("params_kept") else []),
        *(["- estimator resets (re-anchored, position jumps the vehicle did not make): "
           + "; ".join(f"{math.hypot(*r['shift_ned_m']):.2f} m at t={r['t']:.2f} s "
                       f"({'announced' if r['announced'] else 'not announced'})" for r in data["position_resets"])]
          if data.get("position_resets") else []),
        "",
        "Times and durations are vehicle seconds (the autopilot's clock), not wall time.",
        "",
        "| step | action | duration [s] | RMS error [m] | peak error [m] | peak tilt [deg] "
        "| force estimate N/E/D [N] | ok |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in data.get("segments", []):
        f = s.get("force_estimate_n") or (None, None, None)
        dur = (s["t_end"] - s["t_start"]) if s.get("t_end") is not None and s.get("t_start") is not None else None
        lines.append(
            f"| {s['name']} | {s['action']} | {_fmt(dur)} | {_fmt(s.get('rms_error_m'))} | "
            f"{_fmt(s.get('peak_error_m') if s.get('samples') else None)} | {_fmt(s.get('peak_tilt_deg'))} | "
            f"{' / '.join(_fmt(x) for x in f)} | {'yes' if s.get('ok') else 'NO: ' + s.get('note', '')} |"
        )
    return "\n".join(lines) + "\n"


def _fmt(x: object) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, float):
        return f"{x:.3g}"
    return str(x)
