"""Position controllers computing the inertial control force f [N] (section IV, section V).

All four share the PID's local closed-loop gains (section V): ``K_v = 2 omega_c``,
``K_p = omega_c^2``, ``K_i = omega_c / 4``::

    PID     f = m0 (r_dd_d - g e3 - K_v v~ - K_p r~ - K_i xi)                    xi = int r~
    AIBC    f = m0 (r_dd_d - g e3 - (1 + lam + c1 c2) r~ - (c1 + c2) v~ - c2 lam xi) - h
            with h the velocity-based estimate of bandwidth gamma (see below)
    PD+DO   f = f0 - h_f_hat                                                    (29), (30)
    ISM+DO  f = f0 - h_f_hat - K_f sat(s_p / eps_p)                             (29)-(31)
    INDI    f = f_f + m0 (a_ref - a_f) = f0 - LP2(m0 (r_dd - g e3) - f)

INDI for the outer loop (Tal & Karaman 2018): the force now, plus the mass times the missing
acceleration, with the measured acceleration and the force through the same second-order
low-pass (``indi_filter_rad_s``). Written out it is PD plus a second-order estimate of the same
measurement as (30): the incremental form and the DO differ in the filter, not the signal.

``f0 = m0 (r_dd_d - g e3 - K_v v~ - K_p r~)``; the gravity term makes the hover force
``-m0 g e3`` (up).

AIBC: read literally, the paper's printed law feeds ``+c1 lam xi`` back, which is unstable. The
backstepping of [18], [19] with ``e1 = r~``, ``e2 = v~ + c1 e1 + lam xi`` and
``V = 1/2 (lam xi^2 + e1^2 + e2^2)`` gives ``V' = -c1 e1^2 - c2 e2^2`` for the law above. Its
characteristic polynomial ``s^3 + (c1 + c2) s^2 + (1 + lam + c1 c2) s + c2 lam`` equals the PID's
``s^3 + K_v s^2 + K_p s + K_i`` when :func:`aibc_coefficients` picks c1, c2, lam.

AIBC's estimate, "h_x = gamma e'" in the paper, must not undo that match (section V: the same
local closed-loop gains). Read as ``h = gamma v~`` it is velocity feedback: the velocity gain
becomes ``c1 + c2 + gamma`` (3 -> 7 or 11 with the paper's gamma), and no positive c1, c2, lam
can absorb it (that needs ``c1 + c2 = 2 w - gamma < 0`` for gamma > 3); the same holds for any
estimate that is a linear function of the tracking errors (``h' = gamma v~`` would need
``1 + lam + c1 c2 = w^2 - gamma < 0``). So the estimate is an observer that is zero in nominal
flight, driven by the velocity error alone (:class:`~.observers.MomentumObserver` on
``v~' = f / m0 + g e3 - r_dd_d + h / m0``, bandwidth gamma): the matched poles stay the PID's,
and the estimate converges to a constant. ``aibc_estimate = "velocity_feedback"`` keeps the
literal reading for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .attitude import _integrate_with_reset
from .observers import ForceObserver, MatchingFilter, MomentumObserver
from .params import PositionGains
from .vector import (
    ZERO3,
    Real,
    Vec3,
    add,
    clip,
    mul,
    sat,
    scale,
    sub,
)

__all__ = [
    "POSITION_CONTROLLERS",
    "aibc_coefficients",
    "aibc_coefficients_per_vehicle",
    "nominal_force",
    "PositionController",
]

POSITION_CONTROLLERS = ("pid", "aibc", "pd_do", "ism_do", "indi")


def aibc_coefficients(omega_c_rad_s: float) -> tuple[float, float, float]:
    """``(c1, c2, lam)`` whose AIBC closed loop has the PID's poles (all positive).

    Solves ``c1 + c2 = 2 w``, ``1 + lam + c1 c2 = w^2``, ``c2 lam = w / 4``: eliminating c1 and
    lam leaves ``g(c2) = 1 + w / (4 c2) + (2w - c2) c2 - w^2 = 0`` on ``0 < c2 < 2w``, where g goes
    from +inf to ``9/8 - w^2``; it has a root there exactly when ``w^2 > 9/8``.
    """
    w = float(omega_c_rad_s)
    if w * w <= 1.125:
        raise ValueError(f"AIBC cannot match PID gains for omega_c = {w} rad/s (needs omega_c^2 > 9/8)")

    def g(c2: float) -> float:
        return 1.0 + w / (4.0 * c2) + (2.0 * w - c2) * c2 - w * w

    lo, hi = 1e-9, 2.0 * w
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if g(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    c2 = 0.5 * (lo + hi)
    return 2.0 * w - c2, c2, w / (4.0 * c2)


def aibc_coefficients_per_vehicle(omega_c_rad_s: Real) -> tuple[Real, Real, Real]:
    """:func:`aibc_coefficients` for one vehicle (a float) or a batch (an array, element by element)."""
    if isinstance(omega_c_rad_s, np.ndarray):
        coeffs = [aibc_coefficients(float(w)) for w in omega_c_rad_s.ravel()]
        c1, c2, lam = (np.array([c[i] for c in coeffs]).reshape(omega_c_rad_s.shape) for i in range(3))
        return c1, c2, lam
    return aibc_coefficients(omega_c_rad_s)


def nominal_force(
    mass_kg: Real, gravity_m_s2: float, accel_ref: Vec3, pos_err: Vec3, vel_err: Vec3, k_p: Vec3, k_v: Vec3
) -> Vec3:
    """``f0 = m0 (r_dd_d - g e3 - K_v v~ - K_p r~)``  (29)."""
    return (
        mass_kg * (accel_ref[0] - k_v[0] * vel_err[0] - k_p[0] * pos_err[0]),
        mass_kg * (accel_ref[1] - k_v[1] * vel_err[1] - k_p[1] * pos_err[1]),
        mass_kg * (accel_ref[2] - gravity_m_s2 - k_v[2] * vel_err[2] - k_p[2] * pos_err[2]),
    )


@dataclass
class PositionController:
    """One of POSITION_CONTROLLERS; :meth:`update` returns the force f [N, NED].

    ``specific_force_ned`` is ``r_dd - g e3`` (accelerometer rotated to NED, or differentiated
    position minus gravity), ``force_applied_prev_n`` the previous step's force as the gains'
    ``force_source`` asks (:func:`~companion.control.outer_loop.observer_force`): the force
    observer's inputs (30).
    """

    kind: str
    gains: PositionGains
    mass_kg: Real
    gravity_m_s2: float = 9.81
    xi: Vec3 = ZERO3
    """integral of the position error [m s] (PID, AIBC)"""
    z: Vec3 = ZERO3
    """ISM integral state of (31) [m/s]"""
    s: Vec3 = ZERO3
    estimate_n: Vec3 = ZERO3
    """what the controller currently attributes to disturbance [N] (for logs and metrics)"""
    _started: bool = field(default=False, repr=False)
    observer: ForceObserver = field(init=False)

    def __post_init__(self) -> None:
        if self.kind not in POSITION_CONTROLLERS:
            raise ValueError(f"unknown position controller {self.kind!r}; expected one of {POSITION_CONTROLLERS}")
        g = self.gains
        self._k_v, self._k_p, self._k_i = g.k_v(), g.k_p(), g.k_i()
        matching = MatchingFilter(g.observer_match_delay_s, g.observer_match_cutoff_hz, g.observer_match_order)
        self.observer = ForceObserver(self.mass_kg, g.observer_gain_rad_s, matching=matching)
        # the velocity has one difference and one filter less than the acceleration
        vel_matching = MatchingFilter(g.observer_match_delay_s, g.observer_match_cutoff_hz,
                                      max(g.observer_match_order - 1, 0))
        self.aibc_observer = MomentumObserver(self.mass_kg, g.aibc_gamma_per_s, matching=vel_matching)
        if self.kind == "indi":  # INDI: the same measurement, through a second-order filter
            self.observer = ForceObserver(self.mass_kg, g.indi_filter_rad_s, matching=matching, order=2)
        if self.kind == "aibc":
            coeffs = [aibc_coefficients_per_vehicle(w) for w in g.omega_c_rad_s]
            c1 = tuple(c[0] for c in coeffs)
            c2 = tuple(c[1] for c in coeffs)
            lam = tuple(c[2] for c in coeffs)
            self._aibc_p = tuple(1.0 + lam[i] + c1[i] * c2[i] for i in range(3))
            self._aibc_v = tuple(c1[i] + c2[i] for i in range(3))
            self._aibc_i = tuple(c2[i] * lam[i] for i in range(3))
        eps = g.boundary_layer_m_s
        self._k_f = mul(scale(self.mass_kg, g.sliding_gain_rad_s), eps)  # K_f = k_s m0 eps

    def reset(self) -> None:
        self.xi = self.z = self.s = self.estimate_n = ZERO3
        self._started = False
        self.observer.reset()
        self.aibc_observer.reset()

    def update(
        self,
        pos_err_m: Vec3,
        vel_err_m_s: Vec3,
        accel_ref_m_s2: Vec3,
        specific_force_ned_m_s2: Vec3 | None,
        force_applied_prev_n: Vec3,
        dt_s: float,
    ) -> Vec3:
        kind = self.kind
        m0, g = self.mass_kg, self.gravity_m_s2
        if kind == "pid":
            f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, self._k_p, self._k_v)
            integral = self._integrate(pos_err_m, self._k_i, dt_s)
            self.estimate_n = scale(m0, integral)
            return sub(f, self.estimate_n)
        if kind == "aibc":
            f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, self._aibc_p, self._aibc_v)  # type: ignore[arg-type]
            integral = self._integrate(pos_err_m, self._aibc_i, dt_s)  # type: ignore[arg-type]
            if self.gains.aibc_estimate == "velocity_feedback":
                self.estimate_n = scale(m0, mul(self.gains.aibc_gamma_per_s, vel_err_m_s))
            else:  # the velocity-error model: v~' = f / m0 + g e3 - r_dd_d + h / m0
                known = (-accel_ref_m_s2[0], -accel_ref_m_s2[1], g - accel_ref_m_s2[2])
                self.estimate_n = self.aibc_observer.update(vel_err_m_s, force_applied_prev_n, known, dt_s)
            return sub(sub(f, scale(m0, integral)), self.estimate_n)
        f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, self._k_p, self._k_v)
        if specific_force_ned_m_s2 is not None:
            self.estimate_n = self.observer.update(specific_force_ned_m_s2, force_applied_prev_n, dt_s)
        f = sub(f, self.estimate_n)
        if kind == "ism_do":
            f = sub(f, self._sliding_term(pos_err_m, vel_err_m_s, dt_s))
        return f

    def _integrate(self, pos_err_m: Vec3, k_i: Vec3, dt_s: float) -> Vec3:
        """``K_i xi`` after one step, each element held within ``integral_limit_m_s2`` (anti-windup)."""
        xi = add(self.xi, scale(dt_s, pos_err_m))
        if self.gains.anti_windup:
            lim = self.gains.integral_limit_m_s2
            xi = (
                clip(xi[0], -lim / k_i[0], lim / k_i[0]),
                clip(xi[1], -lim / k_i[1], lim / k_i[1]),
                clip(xi[2], -lim / k_i[2], lim / k_i[2]),
            )
        self.xi = xi
        return mul(k_i, xi)

    def _sliding_term(self, pos_err_m: Vec3, vel_err_m_s: Vec3, dt_s: float) -> Vec3:
        """``K_f sat(s_p / eps_p)``, ``s_p = v~ + K_v r~ + int K_p r~ - v~(0) - K_v r~(0)``  (31).

        Same anti-windup as the attitude loop: an element outside the layer is reset so that it
        restarts from zero, instead of winding up at force onset and release.
        """
        eps = self.gains.boundary_layer_m_s
        s0 = add(vel_err_m_s, mul(self._k_v, pos_err_m))
        if not self._started:
            self.z = (-s0[0], -s0[1], -s0[2])
            self._started = True
        z = self.z
        s = add(s0, z)
        self.s = s
        self.z = _integrate_with_reset(z, s, s0, mul(self._k_p, pos_err_m), eps, dt_s, self.gains.anti_windup)
        return mul(self._k_f, sat(s, eps))

