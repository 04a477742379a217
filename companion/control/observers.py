"""Acceleration-based disturbance observers: torque (15), (19) and force (30).

Both measure the lumped disturbance from the model and an acceleration, then low-pass it with
bandwidth ``Gamma`` (the paper's (19) with rho = 0): ``h_hat' = Gamma (h_meas - h_hat)``,
discretised exactly for a measurement held over the step. Both are fed the wrench that was
*applied* (after rotor saturation), never the request, so saturation is not mistaken for a
disturbance that the controller then fights.

An acceleration obtained by differentiating and filtering tracking data arrives late and
smoothed, while the force it is compared with in (30) is the present one. The difference between
the two is then not the disturbance but the force's change over the delay: with the commanded
force, that closes a loop through the attitude lag with almost no phase margin at Gamma = 7 rad/s
(E5 rang at 1.7 Hz). :class:`MatchingFilter` passes the force through the same delay and
low-pass as the acceleration, the rule of any disturbance observer: both inputs of the
difference see the same filter, so in the nominal model the difference is exactly zero.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from .vector import (
    ZERO3,
    Real,
    Vec3,
    lowpass_alpha,
    scale,
    sub,
)

__all__ = ["TorqueObserver", "ForceObserver", "MomentumObserver", "MatchingFilter", "IncrementalTorque", "lowpass_step"]


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
class MatchingFilter:
    """A pure delay and ``order`` equal first-order low-passes at ``cutoff_hz`` (0: none).

    Model of how the acceleration measurement was obtained (e.g. 60 Hz positions, 10 ms late,
    differenced twice through 5 Hz filters: about 30 ms and two 5 Hz poles), applied to the
    force input of (30). The first input fills the state, so nothing rings at start.
    """

    delay_s: float = 0.0
    cutoff_hz: float = 0.0
    order: int = 2
    _line: deque[Vec3] = field(default_factory=deque, repr=False)
    _stages: list[Vec3] = field(default_factory=list, repr=False)

    @property
    def active(self) -> bool:
        return self.delay_s > 0.0 or self.cutoff_hz > 0.0

    def reset(self) -> None:
        self._line.clear()
        self._stages = []

    def update(self, u: Vec3, dt_s: float) -> Vec3:
        steps = int(round(self.delay_s / dt_s))
        line = self._line
        line.append(u)
        while len(line) > steps + 1:
            line.popleft()
        y = line[0]
        if self.cutoff_hz <= 0.0 or self.order <= 0:
            return y
        if not self._stages:
            self._stages = [y] * self.order
        a = lowpass_alpha(2.0 * math.pi * self.cutoff_hz, dt_s)
        alpha: Vec3 = (a, a, a)
        for i in range(self.order):
            y = self._stages[i] = lowpass_step(self._stages[i], y, alpha)
        return y


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
    matching: MatchingFilter = field(default_factory=MatchingFilter)
    """the acceleration's delay and filter, applied to the force (see the module docstring)"""
    order: int = 1
    """equal first-order stages of the low-pass (1: (19); 2: INDI's second-order filter)"""
    _alpha: _Alpha = field(init=False, repr=False)
    _stages: list[Vec3] = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        self._alpha = _Alpha(self.bandwidth_rad_s)

    def reset(self) -> None:
        self.estimate_n = ZERO3
        self._stages = []
        self.matching.reset()

    def measure(self, specific_force_ned_m_s2: Vec3, force_ned_n: Vec3) -> Vec3:
        """``m0 (r_dd - g e3) - f``: the raw disturbance measurement of (30) [N]."""
        return sub(scale(self.mass_kg, specific_force_ned_m_s2), force_ned_n)

    def update(
        self, specific_force_ned_m_s2: Vec3, force_applied_ned_n: Vec3, dt_s: float,
        model_force_n: Vec3 = ZERO3,
    ) -> Vec3:
        """Advance one step: ``h_hat' = Gamma (m0 (r_dd - g e3) - f - h_hat)``  (30).

        ``specific_force_ned_m_s2`` is ``r_dd - g e3`` (the accelerometer's reading rotated into
        NED, or a differentiated velocity minus gravity), ``force_applied_ned_n`` the force ``f``
        the rotors were asked for (or produced), ``model_force_n`` a known force (drag) to
        leave out. Returns the estimate [N, NED].
        """
        if self.matching.active:
            force_applied_ned_n = self.matching.update(force_applied_ned_n, dt_s)
        h_meas = self.measure(specific_force_ned_m_s2, force_applied_ned_n)
        if model_force_n is not ZERO3:
            h_meas = sub(h_meas, model_force_n)
        alpha = self._alpha(dt_s)
        if self.order == 1:
            self.estimate_n = lowpass_step(self.estimate_n, h_meas, alpha)
            return self.estimate_n
        if not self._stages:
            self._stages = [ZERO3] * self.order
        y = h_meas
        for i in range(self.order):
            y = self._stages[i] = lowpass_step(self._stages[i], y, alpha)
        self.estimate_n = y
        return y


@dataclass
class MomentumObserver:
    """Force disturbance estimate [N] from a velocity, without differentiating it.

    ``h_hat = Gamma (m0 v - p_hat)``, ``p_hat' = f + m0 a_known + h_hat``, so that
    ``h_hat' = Gamma (m0 v' - f - m0 a_known - h_hat)``: exactly (30) with ``r_dd = v'``, but the
    velocity is used as it is (the generalised-momentum observer). ``a_known`` is whatever
    acceleration the model knows besides ``f / m0`` (gravity ``g e3``; minus the reference's
    acceleration when ``v`` is a velocity error). The force passes through ``matching``, the
    velocity's own delay and filter (see the module docstring).
    """

    mass_kg: float | Real
    bandwidth_rad_s: Vec3
    estimate_n: Vec3 = ZERO3
    matching: MatchingFilter = field(default_factory=MatchingFilter)
    _p_hat: Vec3 | None = field(default=None, repr=False)

    def reset(self) -> None:
        self.estimate_n = ZERO3
        self._p_hat = None
        self.matching.reset()

    def update(self, vel_m_s: Vec3, force_n: Vec3, known_accel_m_s2: Vec3, dt_s: float) -> Vec3:
        """Advance over the step that just ended: ``vel_m_s`` now, ``force_n`` and
        ``known_accel_m_s2`` as they acted during that step. Returns the estimate [N]."""
        m, g = self.mass_kg, self.bandwidth_rad_s
        momentum = scale(m, vel_m_s)
        if self.matching.active:
            force_n = self.matching.update(force_n, dt_s)
        p = self._p_hat
        if p is None:  # no step behind us yet: the model starts where the vehicle is
            self._p_hat = momentum
            return self.estimate_n
        a, h = known_accel_m_s2, self.estimate_n
        p = (p[0] + dt_s * (force_n[0] + m * a[0] + h[0]),
             p[1] + dt_s * (force_n[1] + m * a[1] + h[1]),
             p[2] + dt_s * (force_n[2] + m * a[2] + h[2]))
        self._p_hat = p
        self.estimate_n = (g[0] * (momentum[0] - p[0]), g[1] * (momentum[1] - p[1]), g[2] * (momentum[2] - p[2]))
        return self.estimate_n


@dataclass
class IncrementalTorque:
    """What incremental NDI subtracts (Smeur, Chu & de Croon 2016): ``J0 w'_f - tau_f`` [N m].

    INDI commands ``tau = tau_f + J0 (nu - w'_f)``: the torque the rotors produce now, plus
    the inertia times the missing angular acceleration. ``w'_f`` is the finite-differenced gyro
    and ``tau_f`` the applied torque through the rotors' first-order lag (the actuator model),
    both through the same second-order low-pass (two equal first-order stages): filtered alike,
    their difference holds no filter lag of the control's own action. No model of the body is
    used: gyroscopic torque, inertia error and disturbances all arrive in ``w'``.
    """

    inertia_kg_m2: Vec3
    filter_rad_s: float
    actuator_time_constant_s: float
    estimate_nm: Vec3 = ZERO3
    _omega_prev: Vec3 | None = field(default=None, repr=False)
    _actuator: Vec3 = ZERO3
    _stages: list[Vec3] = field(default_factory=lambda: [ZERO3, ZERO3, ZERO3, ZERO3], repr=False)

    def reset(self) -> None:
        self.estimate_nm = ZERO3
        self._omega_prev = None
        self._actuator = ZERO3
        self._stages = [ZERO3, ZERO3, ZERO3, ZERO3]

    def update(self, omega_rad_s: Vec3, torque_applied_prev_nm: Vec3, dt_s: float) -> Vec3:
        prev = self._omega_prev
        self._omega_prev = omega_rad_s
        tc = self.actuator_time_constant_s
        a_act = 1.0 - math.exp(-dt_s / tc) if tc > 0.0 else 1.0
        self._actuator = lowpass_step(self._actuator, torque_applied_prev_nm, (a_act, a_act, a_act))
        if prev is None:
            return self.estimate_nm
        j, inv = self.inertia_kg_m2, 1.0 / dt_s
        j_w_dot = (j[0] * (omega_rad_s[0] - prev[0]) * inv, j[1] * (omega_rad_s[1] - prev[1]) * inv,
                   j[2] * (omega_rad_s[2] - prev[2]) * inv)
        a = lowpass_alpha(self.filter_rad_s, dt_s)
        alpha: Vec3 = (a, a, a)
        st = self._stages
        st[0] = lowpass_step(st[0], j_w_dot, alpha)
        st[1] = lowpass_step(st[1], st[0], alpha)
        st[2] = lowpass_step(st[2], self._actuator, alpha)
        st[3] = lowpass_step(st[3], st[2], alpha)
        self.estimate_nm = sub(st[1], st[3])
        return self.estimate_nm
