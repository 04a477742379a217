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
from companion.control.jit import kernel

from ..plant.scenario import Segment
from .simulation import FlightLog

__all__ = ["SegmentMetrics", "segment_metrics", "flight_metrics", "tilt_deg", "rate_cmd_deg_s", "euler_deg",
           "pid_prediction"]


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
    peak_body_rate_deg_s: float
    """largest |omega| (what the gyro must measure: the paper's are rated to 300 deg/s)"""
    mean_attitude_error_deg: float
    """mean angle between the attitude and the attitude setpoint"""
    rms_torque_lowpass_error_nm: float
    """RMS of h_tau_hat minus the true torque disturbance through the observer's own low-pass
    (Gamma_a of the scenario): zero for an observer that is exactly (19)"""
    mean_sliding_att_rad_s: float
    """|mean of the attitude sliding variable s| over the segment"""
    rms_pid_prediction_m: float
    """horizontal RMS error that the ideal PID with the scenario's omega_c,p (a point mass, no
    inner loop) would have under the disturbance force this flight met: a yardstick for baselines"""
    force_estimate_drift_n: float
    """|mean h_f_hat over the last fifth - over the fifth before|: ~0 once an estimate has settled"""
    peak_speed_m_s: float

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


@kernel
def _lowpass(x: NDArray[np.float64], bandwidth_rad_s: float, dt_s: float) -> NDArray[np.float64]:
    """First-order low-pass y' = b (x - y), exact for x held over each sample, from y = 0.

    Compiled (as :func:`pid_prediction`): a loop over every logged sample, 3 ms a call in Python,
    was a fifth of a sweep batch's time next to the compiled flights. Both read nothing outside
    this file, whose edits numba's own cache notices."""
    a = 1.0 - math.exp(-bandwidth_rad_s * dt_s)
    y = np.empty_like(x)
    acc = 0.0
    for k in range(x.shape[0]):
        acc += a * (x[k] - acc)
        y[k] = acc
    return y


@kernel
def pid_prediction(t: NDArray[np.float64], force_n: NDArray[np.float64], mass_kg: float,
                   omega_c_rad_s: float) -> NDArray[np.float64]:
    """Position error of a point mass under the ideal PID of section V (``K_v = 2 w``,
    ``K_p = w^2``, ``K_i = w / 4``) driven by ``force_n(t)``, from rest (semi-implicit Euler)."""
    kv, kp, ki = 2.0 * omega_c_rad_s, omega_c_rad_s**2, 0.25 * omega_c_rad_s
    x = v = xi = 0.0
    out = np.empty_like(force_n)
    for k in range(force_n.shape[0]):
        h = force_n[k]
        dt = t[k] - t[k - 1] if k > 0 else 0.0
        xi += x * dt
        v += (h / mass_kg - kv * v - kp * x - ki * xi) * dt
        x += v * dt
        out[k] = x
    return out


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
    sc = log.scenario
    q = (log["qw"], log["qx"], log["qy"], log["qz"])
    q_d = (log["qw_d"], log["qx_d"], log["qy_d"], log["qz_d"])
    att_err = np.degrees(quat.angle_between(q, q_d))[m]  # type: ignore[arg-type]
    dt_log = float(t[1] - t[0]) if len(t) > 1 else 1.0
    gamma_a = sc.attitude.observer_gain_rad_s
    lp_err = np.stack([log[f"ht{a}_hat"] - _lowpass(log[f"ht{a}"], float(gamma_a[i]), dt_log)
                       for i, a in enumerate("xyz")], axis=-1)[m]
    s_att_mean = _vec(log, "sx_att", "sy_att", "sz_att")[m].mean(axis=0)
    w_c = sc.position.omega_c_rad_s
    pred = [pid_prediction(t, log[f"hf{a}"], float(sc.vehicle.mass_kg), float(w_c[i])) for i, a in enumerate("xy")]
    pred_h = np.sqrt(pred[0][m] ** 2 + pred[1][m] ** 2)
    f_tail = f_hat[-n_tail:].mean(axis=0)
    before = f_hat[max(0, len(f_hat) - 2 * n_tail):len(f_hat) - n_tail]
    f_before = before.mean(axis=0) if len(before) else f_tail
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
        peak_body_rate_deg_s=float(np.degrees(np.linalg.norm(_vec(log, "p", "q", "r")[m], axis=1).max())),
        mean_attitude_error_deg=float(att_err.mean()),
        rms_torque_lowpass_error_nm=float(np.sqrt(np.mean(np.sum(lp_err**2, axis=1)))),
        mean_sliding_att_rad_s=float(np.linalg.norm(s_att_mean)),
        rms_pid_prediction_m=float(np.sqrt(np.mean(pred_h**2))),
        force_estimate_drift_n=float(np.linalg.norm(f_tail - f_before)),
        peak_speed_m_s=float(np.linalg.norm(_vec(log, "vx", "vy", "vz")[m], axis=1).max()),
    )


def flight_metrics(log: FlightLog) -> list[SegmentMetrics]:
    """Metrics for each of the scenario's segments (or the whole flight if it defines none)."""
    segs = log.scenario.segments or (Segment("flight", 0.0, float(log.t[-1]) + 1e-9),)
    return [segment_metrics(log, s) for s in segs]
