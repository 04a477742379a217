"""Metrics of a flight log, per segment: the numbers the experiments report and test.

All errors are true position minus reference (NED, m). ``swing_past_m`` is SPEC section 7's
reading of "no overshoot": along the axis of the segment's largest excursion, how far the
vehicle goes past its resting position (the mean over the last fifth of the segment) on the
way back, in the direction opposite to the excursion.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from companion.control import quaternion as quat

from .scenario import Segment
from .simulation import FlightLog

__all__ = ["SegmentMetrics", "segment_metrics", "flight_metrics", "tilt_deg", "rate_cmd_deg_s", "euler_deg"]


@dataclass(frozen=True)
class SegmentMetrics:
    segment: str
    rms_error_m: float
    rms_horizontal_error_m: float
    rms_vertical_error_m: float
    peak_error_m: float
    excursion_m: float
    """signed peak error along the axis of the largest excursion"""
    swing_past_m: float
    settling_time_s: float
    """from the segment start until the error stays inside the band; NaN if it never does"""
    steady_tilt_deg: float
    """mean tilt over the last fifth of the segment"""
    peak_tilt_deg: float
    peak_rate_cmd_deg_s: float
    rms_rate_cmd_deg_s: float
    """RMS of |omega_d|: in hover, the noise that (34) passes on to the attitude loop"""
    rms_yaw_error_deg: float
    rms_force_estimate_error_n: float
    """|h_f_hat - h_f| over the second half of the segment (true lumped drag + external force)"""
    steady_force_estimate_n: float
    """|h_f_hat| averaged over the last fifth of the segment"""
    rms_torque_estimate_error_nm: float

    def as_row(self) -> dict[str, float | str]:
        return asdict(self)


def tilt_deg(log: FlightLog) -> NDArray[np.float64]:
    return np.degrees(quat.tilt_angle((log["qw"], log["qx"], log["qy"], log["qz"])))  # type: ignore[arg-type]


def euler_deg(log: FlightLog) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    r, p, y = quat.to_euler((log["qw"], log["qx"], log["qy"], log["qz"]))
    return np.degrees(r), np.degrees(p), np.degrees(y)  # type: ignore[return-value]


def rate_cmd_deg_s(log: FlightLog) -> NDArray[np.float64]:
    return np.degrees(np.sqrt(log["p_d"] ** 2 + log["q_d"] ** 2 + log["r_d"] ** 2))


def _vec(log: FlightLog, a: str, b: str, c: str) -> NDArray[np.float64]:
    return np.stack([log[a], log[b], log[c]], axis=-1)


def segment_metrics(log: FlightLog, seg: Segment) -> SegmentMetrics:
    t = log.t
    m = (t >= seg.start_s) & (t < seg.stop_s)
    if not m.any():
        raise ValueError(f"segment {seg.name!r} ({seg.start_s}..{seg.stop_s} s) is outside the flight")
    err = _vec(log, "x", "y", "z") - _vec(log, "x_ref", "y_ref", "z_ref")
    e = err[m]
    tt = t[m]
    dist = np.linalg.norm(e, axis=1)
    horiz = np.linalg.norm(e[:, :2], axis=1)
    n_tail = max(1, len(tt) // 5)

    axis = int(np.argmax(np.max(np.abs(e), axis=0)))
    ea = e[:, axis]
    k_peak = int(np.argmax(np.abs(ea)))
    excursion = float(ea[k_peak])
    rest = float(ea[-n_tail:].mean())
    direction = -math.copysign(1.0, excursion - rest)
    swing = float(max(0.0, np.max(direction * (ea[k_peak:] - rest))))

    outside = np.nonzero(dist > seg.settle_band_m)[0]
    if len(outside) == 0:
        settling = 0.0
    elif outside[-1] == len(dist) - 1:
        settling = math.nan
    else:
        settling = float(tt[outside[-1] + 1] - seg.start_s)

    tilt = tilt_deg(log)[m]
    yaw = np.degrees(np.unwrap(quat.to_euler((log["qw"], log["qx"], log["qy"], log["qz"]))[2]))  # type: ignore[arg-type]
    yaw_err = (yaw - np.degrees(log["yaw_ref"]) + 180.0) % 360.0 - 180.0
    half = tt >= 0.5 * (seg.start_s + seg.stop_s)
    f_err = np.linalg.norm(_vec(log, "hfx_hat", "hfy_hat", "hfz_hat")[m] - _vec(log, "hfx", "hfy", "hfz")[m], axis=1)
    t_err = np.linalg.norm(_vec(log, "htx_hat", "hty_hat", "htz_hat")[m] - _vec(log, "htx", "hty", "htz")[m], axis=1)
    f_hat = _vec(log, "hfx_hat", "hfy_hat", "hfz_hat")[m]
    return SegmentMetrics(
        segment=seg.name,
        rms_error_m=float(np.sqrt(np.mean(dist**2))),
        rms_horizontal_error_m=float(np.sqrt(np.mean(horiz**2))),
        rms_vertical_error_m=float(np.sqrt(np.mean(e[:, 2] ** 2))),
        peak_error_m=float(dist.max()),
        excursion_m=excursion,
        swing_past_m=swing,
        settling_time_s=settling,
        steady_tilt_deg=float(tilt[-n_tail:].mean()),
        peak_tilt_deg=float(tilt.max()),
        peak_rate_cmd_deg_s=float(rate_cmd_deg_s(log)[m].max()),
        rms_rate_cmd_deg_s=float(np.sqrt(np.mean(rate_cmd_deg_s(log)[m] ** 2))),
        rms_yaw_error_deg=float(np.sqrt(np.mean(yaw_err[m] ** 2))),
        rms_force_estimate_error_n=float(np.sqrt(np.mean(f_err[half] ** 2))),
        steady_force_estimate_n=float(np.linalg.norm(f_hat[-n_tail:].mean(axis=0))),
        rms_torque_estimate_error_nm=float(np.sqrt(np.mean(t_err[half] ** 2))),
    )


def flight_metrics(log: FlightLog) -> list[SegmentMetrics]:
    """Metrics for each of the scenario's segments (or the whole flight if it defines none)."""
    segs = log.scenario.segments or (Segment("flight", 0.0, float(log.t[-1]) + 1e-9),)
    return [segment_metrics(log, s) for s in segs]
