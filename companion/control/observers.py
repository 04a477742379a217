"""Acceleration-based disturbance observers: torque (15), (19) and force (30).

Both measure the lumped disturbance from the model and an acceleration, then low-pass it with
bandwidth ``Gamma`` (the paper's (19) with rho = 0): ``h_hat' = Gamma (h_meas - h_hat)``,
discretised exactly for a measurement held over the step. Both are fed the wrench that was
*applied* (after rotor saturation), never the request, so saturation is not mistaken for a
disturbance that the controller then fights.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .vector import (
    ZERO3,
    Real,
    Vec3,
    lowpass_alpha,
    scale,
    sub,
)

__all__ = ["TorqueObserver", "ForceObserver", "lowpass_step"]


def lowpass_step(estimate: Vec3, measurement: Vec3, alpha: Vec3) -> Vec3:
    """One step of the first-order filter ``h_hat += alpha (h_meas - h_hat)`` (19)."""
    return (
        estimate[0] + alpha[0] * (measurement[0] - estimate[0]),
        estimate[1] + alpha[1] * (measurement[1] - estimate[1]),
        estimate[2] + alpha[2] * (measurement[2] - estimate[2]),
    )


class _Alpha:
    """Per-axis filter gains for a step length, recomputed only when ``dt`` changes."""

    def __init__(self, bandwidth_rad_s: Vec3) -> None:
        self.bandwidth = bandwidth_rad_s
        self._dt = -1.0
        self._alpha: Vec3 = ZERO3

    def __call__(self, dt_s: float) -> Vec3:
        if dt_s != self._dt:
            b = self.bandwidth
            self._alpha = (lowpass_alpha(b[0], dt_s), lowpass_alpha(b[1], dt_s), lowpass_alpha(b[2], dt_s))
            self._dt = dt_s
        return self._alpha


@dataclass
class TorqueObserver:
    """Torque disturbance estimate ``h_tau_hat`` [N m] from finite-differenced gyro rates.

    ``h_meas,k = J0 omega_dot_k - tau_applied,k-1 + omega_k x (J0 omega_k)``  (15)
    with ``omega_dot_k = (omega_k - omega_k-1) / dt``: the backward difference is the mean
    acceleration over the step in which ``tau_applied,k-1`` acted.
    """

    inertia_kg_m2: Vec3
    bandwidth_rad_s: Vec3
    estimate_nm: Vec3 = ZERO3
    _omega_prev: Vec3 | None = field(default=None, repr=False)
    _alpha: _Alpha = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._alpha = _Alpha(self.bandwidth_rad_s)

    def reset(self) -> None:
        self.estimate_nm = ZERO3
        self._omega_prev = None

    def measure(self, omega_rad_s: Vec3, torque_applied_prev_nm: Vec3, dt_s: float) -> Vec3 | None:
        """The raw measurement of (15); ``None`` on the first call (no rate difference yet)."""
        prev = self._omega_prev
        self._omega_prev = omega_rad_s
        if prev is None:
            return None
        j, w, tau = self.inertia_kg_m2, omega_rad_s, torque_applied_prev_nm
        inv_dt = 1.0 / dt_s
        jw0, jw1, jw2 = j[0] * w[0], j[1] * w[1], j[2] * w[2]
        # J0 (w - w_prev) / dt - tau + w x J0 w
        return (
            j[0] * (w[0] - prev[0]) * inv_dt - tau[0] + (w[1] * jw2 - w[2] * jw1),
            j[1] * (w[1] - prev[1]) * inv_dt - tau[1] + (w[2] * jw0 - w[0] * jw2),
            j[2] * (w[2] - prev[2]) * inv_dt - tau[2] + (w[0] * jw1 - w[1] * jw0),
        )

    def update(
        self, omega_rad_s: Vec3, torque_applied_prev_nm: Vec3, dt_s: float, model_torque_nm: Vec3 = ZERO3
    ) -> Vec3:
        """Advance one step; ``model_torque_nm`` is a known torque (e.g. drag) to leave out."""
        h_meas = self.measure(omega_rad_s, torque_applied_prev_nm, dt_s)
        if h_meas is not None:
            if model_torque_nm is not ZERO3:
                h_meas = sub(h_meas, model_torque_nm)
            self.estimate_nm = lowpass_step(self.estimate_nm, h_meas, self._alpha(dt_s))
        return self.estimate_nm


@dataclass
class ForceObserver:
    """Force disturbance estimate ``h_f_hat`` [N] in NED (30).

    ``h_meas = m0 (r_ddot - g e3) - f``, where ``r_ddot - g e3`` is the accelerometer's
    specific force rotated into NED (or differentiated position minus gravity) and ``f`` is the
    force the vehicle was asked for: the paper's commanded ``-T R(q_d) e3``, or ``-T R(q) e3``
    along the measured attitude (``PositionGains.force_source``).
    """

    mass_kg: float | Real
    bandwidth_rad_s: Vec3
    estimate_n: Vec3 = ZERO3
    _alpha: _Alpha = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._alpha = _Alpha(self.bandwidth_rad_s)

    def reset(self) -> None:
        self.estimate_n = ZERO3

    def update(
        self, specific_force_ned_m_s2: Vec3, force_applied_ned_n: Vec3, dt_s: float,
        model_force_n: Vec3 = ZERO3,
    ) -> Vec3:
        h_meas = sub(scale(self.mass_kg, specific_force_ned_m_s2), force_applied_ned_n)
        if model_force_n is not ZERO3:
            h_meas = sub(h_meas, model_force_n)
        self.estimate_n = lowpass_step(self.estimate_n, h_meas, self._alpha(dt_s))
        return self.estimate_n
