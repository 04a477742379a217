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
from typing import NamedTuple

import numpy as np

from .attitude import _integrate_with_reset
from .jit import jitable
from .names import controllers_for
from .observers import (
    ForceObserverConst,
    ForceObserverState,
    MomentumConst,
    MomentumState,
    force_observer_const,
    force_observer_init,
    force_observer_step,
    matching_const,
    momentum_init,
    momentum_step,
)
from .stepper import Stepper
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
    "PositionConst",
    "PositionState",
    "position_const",
    "position_init",
    "position_step",
    "PositionController",
]

POSITION_CONTROLLERS = controllers_for("position")
PID, AIBC, PD_DO, ISM_DO, INDI = (POSITION_CONTROLLERS.index(n) for n in ("pid", "aibc", "pd_do", "ism_do", "indi"))
"""``PositionConst.kind``: the index in POSITION_CONTROLLERS (the registry, companion/control/names.py)."""


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


@jitable
def nominal_force(
    mass_kg: Real, gravity_m_s2: float, accel_ref: Vec3, pos_err: Vec3, vel_err: Vec3, k_p: Vec3, k_v: Vec3
) -> Vec3:
    """``f0 = m0 (r_dd_d - g e3 - K_v v~ - K_p r~)``  (29)."""
    return (
        mass_kg * (accel_ref[0] - k_v[0] * vel_err[0] - k_p[0] * pos_err[0]),
        mass_kg * (accel_ref[1] - k_v[1] * vel_err[1] - k_p[1] * pos_err[1]),
        mass_kg * (accel_ref[2] - gravity_m_s2 - k_v[2] * vel_err[2] - k_p[2] * pos_err[2]),
    )


class PositionConst(NamedTuple):
    """What :func:`position_step` needs besides its state: gains derived for one step length."""

    kind: int
    mass_kg: Real
    gravity_m_s2: float
    k_p: Vec3
    k_v: Vec3
    k_i: Vec3
    aibc_p: Vec3
    aibc_v: Vec3
    aibc_i: Vec3
    aibc_velocity_feedback: bool
    aibc_gamma_per_s: Vec3
    k_f: Vec3
    eps: Vec3
    anti_windup: bool
    integral_limit_m_s2: float
    observer: ForceObserverConst
    aibc_observer: MomentumConst
    dt_s: float


class PositionState(NamedTuple):
    xi: Vec3
    """integral of the position error [m s] (PID, AIBC)"""
    z: Vec3
    """ISM integral state of (31) [m/s]"""
    s: Vec3
    estimate_n: Vec3
    """what the controller currently attributes to disturbance [N] (for logs and metrics)"""
    started: bool
    observer: ForceObserverState
    aibc_observer: MomentumState


def position_const(kind: str, gains: PositionGains, mass_kg: Real, gravity_m_s2: float, dt_s: float) -> PositionConst:
    if kind not in POSITION_CONTROLLERS:
        raise ValueError(f"unknown position controller {kind!r}; expected one of {POSITION_CONTROLLERS}")
    g = gains
    matching = matching_const(g.observer_match_delay_s, g.observer_match_cutoff_hz, g.observer_match_order, dt_s)
    observer = force_observer_const(mass_kg, g.observer_gain_rad_s, 1, matching, dt_s)
    if kind == "indi":  # INDI: the same measurement, through a second-order filter
        observer = force_observer_const(mass_kg, g.indi_filter_rad_s, 2, matching, dt_s)
    # the velocity has one difference and one filter less than the acceleration
    vel_matching = matching_const(g.observer_match_delay_s, g.observer_match_cutoff_hz,
                                  max(g.observer_match_order - 1, 0), dt_s)
    aibc_p = aibc_v = aibc_i = ZERO3
    if kind == "aibc":
        coeffs = [aibc_coefficients_per_vehicle(w) for w in g.omega_c_rad_s]
        c1 = tuple(c[0] for c in coeffs)
        c2 = tuple(c[1] for c in coeffs)
        lam = tuple(c[2] for c in coeffs)
        aibc_p = tuple(1.0 + lam[i] + c1[i] * c2[i] for i in range(3))  # type: ignore[assignment]
        aibc_v = tuple(c1[i] + c2[i] for i in range(3))  # type: ignore[assignment]
        aibc_i = tuple(c2[i] * lam[i] for i in range(3))  # type: ignore[assignment]
    eps = g.boundary_layer_m_s
    return PositionConst(
        kind=POSITION_CONTROLLERS.index(kind),
        mass_kg=mass_kg,
        gravity_m_s2=gravity_m_s2,
        k_p=g.k_p(),
        k_v=g.k_v(),
        k_i=g.k_i(),
        aibc_p=aibc_p,
        aibc_v=aibc_v,
        aibc_i=aibc_i,
        aibc_velocity_feedback=g.aibc_estimate == "velocity_feedback",
        aibc_gamma_per_s=g.aibc_gamma_per_s,
        k_f=mul(scale(mass_kg, g.sliding_gain_rad_s), eps),  # K_f = k_s m0 eps
        eps=eps,
        anti_windup=g.anti_windup,
        integral_limit_m_s2=g.integral_limit_m_s2,
        observer=observer,
        aibc_observer=MomentumConst(mass_kg, g.aibc_gamma_per_s, vel_matching),
        dt_s=dt_s,
    )


@jitable
def position_init() -> PositionState:
    return PositionState(ZERO3, ZERO3, ZERO3, ZERO3, False, force_observer_init(), momentum_init())


@jitable
def position_step(
    c: PositionConst,
    st: PositionState,
    pos_err_m: Vec3,
    vel_err_m_s: Vec3,
    accel_ref_m_s2: Vec3,
    specific_force_ned_m_s2: Vec3,
    has_specific_force: bool,
    force_applied_prev_n: Vec3,
) -> tuple[PositionState, Vec3]:
    """One position step: the new state and the force f [N, NED].

    ``specific_force_ned_m_s2`` is ``r_dd - g e3`` (accelerometer rotated to NED, or differentiated
    position minus gravity; ignored unless ``has_specific_force``), ``force_applied_prev_n`` the
    previous step's force as the gains' ``force_source`` asks
    (:func:`~companion.control.outer_loop.observer_force`): the force observer's inputs (30).
    """
    kind, m0, g, dt_s = c.kind, c.mass_kg, c.gravity_m_s2, c.dt_s
    if kind == PID:
        f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, c.k_p, c.k_v)
        xi, integral = _integrate(c, st.xi, pos_err_m, c.k_i)
        estimate = scale(m0, integral)
        return PositionState(xi, st.z, st.s, estimate, st.started, st.observer, st.aibc_observer), sub(f, estimate)
    if kind == AIBC:
        f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, c.aibc_p, c.aibc_v)
        xi, integral = _integrate(c, st.xi, pos_err_m, c.aibc_i)
        aibc_observer = st.aibc_observer
        if c.aibc_velocity_feedback:
            estimate = scale(m0, mul(c.aibc_gamma_per_s, vel_err_m_s))
        else:  # the velocity-error model: v~' = f / m0 + g e3 - r_dd_d + h / m0
            known = (-accel_ref_m_s2[0], -accel_ref_m_s2[1], g - accel_ref_m_s2[2])
            aibc_observer = momentum_step(c.aibc_observer, aibc_observer, vel_err_m_s, force_applied_prev_n, known,
                                          dt_s)
            estimate = aibc_observer.estimate_n
        st = PositionState(xi, st.z, st.s, estimate, st.started, st.observer, aibc_observer)
        return st, sub(sub(f, scale(m0, integral)), estimate)
    f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, c.k_p, c.k_v)
    observer, estimate = st.observer, st.estimate_n
    if has_specific_force:
        observer = force_observer_step(c.observer, observer, specific_force_ned_m_s2, force_applied_prev_n, ZERO3)
        estimate = observer.estimate_n
    f = sub(f, estimate)
    z, s, started = st.z, st.s, st.started
    if kind == ISM_DO:
        z, s, started, term = _sliding_term(c, z, started, pos_err_m, vel_err_m_s)
        f = sub(f, term)
    return PositionState(st.xi, z, s, estimate, started, observer, st.aibc_observer), f


@jitable
def _integrate(c: PositionConst, xi: Vec3, pos_err_m: Vec3, k_i: Vec3) -> tuple[Vec3, Vec3]:
    """``(xi, K_i xi)`` after one step, each element held within ``integral_limit_m_s2`` (anti-windup)."""
    xi = add(xi, scale(c.dt_s, pos_err_m))
    if c.anti_windup:
        lim = c.integral_limit_m_s2
        xi = (
            clip(xi[0], -lim / k_i[0], lim / k_i[0]),
            clip(xi[1], -lim / k_i[1], lim / k_i[1]),
            clip(xi[2], -lim / k_i[2], lim / k_i[2]),
        )
    return xi, mul(k_i, xi)


@jitable
def _sliding_term(c: PositionConst, z: Vec3, started: bool, pos_err_m: Vec3,
                  vel_err_m_s: Vec3) -> tuple[Vec3, Vec3, bool, Vec3]:
    """``K_f sat(s_p / eps_p)``, ``s_p = v~ + K_v r~ + int K_p r~ - v~(0) - K_v r~(0)``  (31).

    Same anti-windup as the attitude loop: an element outside the layer is reset so that it
    restarts from zero, instead of winding up at force onset and release.
    """
    eps = c.eps
    s0 = add(vel_err_m_s, mul(c.k_v, pos_err_m))
    if not started:
        z = (-s0[0], -s0[1], -s0[2])
    s = add(s0, z)
    z = _integrate_with_reset(z, s, s0, mul(c.k_p, pos_err_m), eps, c.dt_s, c.anti_windup)
    return z, s, True, mul(c.k_f, sat(s, eps))


@dataclass
class PositionController(Stepper[PositionConst]):
    """One of POSITION_CONTROLLERS; :meth:`update` returns the force f [N, NED].

    ``specific_force_ned`` is ``r_dd - g e3`` (accelerometer rotated to NED, or differentiated
    position minus gravity), ``force_applied_prev_n`` the previous step's force as the gains'
    ``force_source`` asks (:func:`~companion.control.outer_loop.observer_force`): the force
    observer's inputs (30). A thin wrapper around :func:`position_step` holding its state.
    """

    kind: str
    gains: PositionGains
    mass_kg: Real
    gravity_m_s2: float = 9.81
    state: PositionState = field(default_factory=position_init, repr=False)

    def __post_init__(self) -> None:
        self.const(0.01)  # checks the kind and the gains

    def _build(self, dt_s: float) -> PositionConst:
        return position_const(self.kind, self.gains, self.mass_kg, self.gravity_m_s2, dt_s)

    @property
    def xi(self) -> Vec3:
        return self.state.xi

    @property
    def z(self) -> Vec3:
        return self.state.z

    @property
    def s(self) -> Vec3:
        return self.state.s

    @property
    def estimate_n(self) -> Vec3:
        return self.state.estimate_n

    def reset(self) -> None:
        self.state = position_init()

    def update(
        self,
        pos_err_m: Vec3,
        vel_err_m_s: Vec3,
        accel_ref_m_s2: Vec3,
        specific_force_ned_m_s2: Vec3 | None,
        force_applied_prev_n: Vec3,
        dt_s: float,
    ) -> Vec3:
        has_sf = specific_force_ned_m_s2 is not None
        self.state, f = position_step(self.const(dt_s), self.state, pos_err_m, vel_err_m_s, accel_ref_m_s2,
                                      specific_force_ned_m_s2 if has_sf else ZERO3, has_sf,  # type: ignore[arg-type]
                                      force_applied_prev_n)
        return f
