"""Position controllers computing the inertial control force f [N] (section IV, section V).

Three families, each a const record holding only what its law uses and a step function over it:
:class:`PidConst` (:func:`pid_step`), :class:`AibcConst` (:func:`aibc_step`) and :class:`DoConst`
(:func:`do_step`: PD+DO, ISM+DO and INDI, which differ in the force observer's filter order and in
whether (31) is added). :func:`position_step` runs the step of its constants' type.

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
from typing import Callable, NamedTuple

import numpy as np

from .attitude import _integrate_with_reset
from .jit import chosen_by_type, jitable
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
    "PidConst",
    "AibcConst",
    "DoConst",
    "PositionState",
    "position_const",
    "pid_const",
    "aibc_const",
    "do_const",
    "position_init",
    "position_step",
    "pid_step",
    "aibc_step",
    "do_step",
    "STEPS",
    "PositionController",
]

POSITION_CONTROLLERS = controllers_for("position")


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


class PidConst(NamedTuple):
    """What :func:`pid_step` needs besides its state: the PID's gains for one step length."""

    mass_kg: Real
    gravity_m_s2: float
    k_p: Vec3
    k_v: Vec3
    k_i: Vec3
    anti_windup: bool
    integral_limit_m_s2: float
    dt_s: float


class AibcConst(NamedTuple):
    """What :func:`aibc_step` needs besides its state. ``k_p``, ``k_v``, ``k_i`` are the
    backstepping's ``1 + lam + c1 c2``, ``c1 + c2``, ``c2 lam`` (:func:`aibc_coefficients`)."""

    mass_kg: Real
    gravity_m_s2: float
    k_p: Vec3
    k_v: Vec3
    k_i: Vec3
    anti_windup: bool
    integral_limit_m_s2: float
    velocity_feedback: bool
    """``h = m0 gamma v~`` (the literal reading) instead of the observer"""
    gamma_per_s: Vec3
    observer: MomentumConst
    """the velocity-error observer of bandwidth gamma [1/s]"""
    dt_s: float


class DoConst(NamedTuple):
    """What :func:`do_step` needs besides its state: PD+DO, ISM+DO and INDI, which differ in the
    force observer's filter order (1, or 2 for INDI) and in whether the sliding term (31) is added."""

    mass_kg: Real
    gravity_m_s2: float
    k_p: Vec3
    k_v: Vec3
    observer: ForceObserverConst
    sliding: bool
    """add ``K_f sat(s_p / eps_p)`` (31): ISM+DO"""
    k_f: Vec3
    """[N]"""
    eps: Vec3
    """boundary layer [m/s]"""
    anti_windup: bool
    dt_s: float


PositionConst = PidConst | AibcConst | DoConst
"""The constants of one of POSITION_CONTROLLERS; their type picks the step (:func:`position_step`)."""


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
    """The constants of position controller ``kind`` (a name of POSITION_CONTROLLERS) for steps of ``dt_s``."""
    if kind not in POSITION_CONTROLLERS:
        raise ValueError(f"unknown position controller {kind!r}; expected one of {POSITION_CONTROLLERS}")
    return _BUILDERS[kind](gains, mass_kg, gravity_m_s2, dt_s)


def pid_const(gains: PositionGains, mass_kg: Real, gravity_m_s2: float, dt_s: float) -> PidConst:
    g = gains
    return PidConst(mass_kg, gravity_m_s2, g.k_p(), g.k_v(), g.k_i(), g.anti_windup, g.integral_limit_m_s2, dt_s)


def aibc_const(gains: PositionGains, mass_kg: Real, gravity_m_s2: float, dt_s: float) -> AibcConst:
    g = gains
    coeffs = [aibc_coefficients_per_vehicle(w) for w in g.omega_c_rad_s]
    c1 = tuple(c[0] for c in coeffs)
    c2 = tuple(c[1] for c in coeffs)
    lam = tuple(c[2] for c in coeffs)
    # the velocity has one difference and one filter less than the acceleration
    vel_matching = matching_const(g.observer_match_delay_s, g.observer_match_cutoff_hz,
                                  max(g.observer_match_order - 1, 0), dt_s)
    return AibcConst(
        mass_kg=mass_kg,
        gravity_m_s2=gravity_m_s2,
        k_p=tuple(1.0 + lam[i] + c1[i] * c2[i] for i in range(3)),  # type: ignore[arg-type]
        k_v=tuple(c1[i] + c2[i] for i in range(3)),  # type: ignore[arg-type]
        k_i=tuple(c2[i] * lam[i] for i in range(3)),  # type: ignore[arg-type]
        anti_windup=g.anti_windup,
        integral_limit_m_s2=g.integral_limit_m_s2,
        velocity_feedback=g.aibc_estimate == "velocity_feedback",
        gamma_per_s=g.aibc_gamma_per_s,
        observer=MomentumConst(mass_kg, g.aibc_gamma_per_s, vel_matching),
        dt_s=dt_s,
    )


def do_const(observer_order: int, sliding: bool) -> Callable[[PositionGains, Real, float, float], DoConst]:
    """The builder of a disturbance-observer controller: the observer's filter order (2: INDI's
    second-order filter at ``indi_filter_rad_s``) and whether (31) is added."""

    def build(gains: PositionGains, mass_kg: Real, gravity_m_s2: float, dt_s: float) -> DoConst:
        g = gains
        matching = matching_const(g.observer_match_delay_s, g.observer_match_cutoff_hz, g.observer_match_order, dt_s)
        bandwidth = g.indi_filter_rad_s if observer_order == 2 else g.observer_gain_rad_s
        eps = g.boundary_layer_m_s
        return DoConst(
            mass_kg=mass_kg,
            gravity_m_s2=gravity_m_s2,
            k_p=g.k_p(),
            k_v=g.k_v(),
            observer=force_observer_const(mass_kg, bandwidth, observer_order, matching, dt_s),
            sliding=sliding,
            k_f=mul(scale(mass_kg, g.sliding_gain_rad_s), eps),  # K_f = k_s m0 eps
            eps=eps,
            anti_windup=g.anti_windup,
            dt_s=dt_s,
        )

    return build


_BUILDERS: dict[str, Callable[[PositionGains, Real, float, float], PositionConst]] = {
    "pid": pid_const,
    "aibc": aibc_const,
    "pd_do": do_const(1, sliding=False),
    "ism_do": do_const(1, sliding=True),
    "indi": do_const(2, sliding=False),
}


@jitable
def position_init() -> PositionState:
    return PositionState(ZERO3, ZERO3, ZERO3, ZERO3, False, force_observer_init(), momentum_init())


@jitable
def pid_step(c: PidConst, st: PositionState, pos_err_m: Vec3, vel_err_m_s: Vec3, accel_ref_m_s2: Vec3,
             specific_force_ned_m_s2: Vec3, has_specific_force: bool,
             force_applied_prev_n: Vec3) -> tuple[PositionState, Vec3]:
    """PID: ``f = f0 - m0 K_i xi``  (29) with the integral; the specific force is not used."""
    m0 = c.mass_kg
    f = nominal_force(m0, c.gravity_m_s2, accel_ref_m_s2, pos_err_m, vel_err_m_s, c.k_p, c.k_v)
    xi, integral = _integrate(c, st.xi, pos_err_m, c.k_i)
    estimate = scale(m0, integral)
    return PositionState(xi, st.z, st.s, estimate, st.started, st.observer, st.aibc_observer), sub(f, estimate)


@jitable
def aibc_step(c: AibcConst, st: PositionState, pos_err_m: Vec3, vel_err_m_s: Vec3, accel_ref_m_s2: Vec3,
              specific_force_ned_m_s2: Vec3, has_specific_force: bool,
              force_applied_prev_n: Vec3) -> tuple[PositionState, Vec3]:
    """AIBC: ``f = m0 (r_dd_d - g e3 - (1 + lam + c1 c2) r~ - (c1 + c2) v~ - c2 lam xi) - h``."""
    m0, g = c.mass_kg, c.gravity_m_s2
    f = nominal_force(m0, g, accel_ref_m_s2, pos_err_m, vel_err_m_s, c.k_p, c.k_v)
    xi, integral = _integrate(c, st.xi, pos_err_m, c.k_i)
    aibc_observer = st.aibc_observer
    if c.velocity_feedback:
        estimate = scale(m0, mul(c.gamma_per_s, vel_err_m_s))
    else:  # the velocity-error model: v~' = f / m0 + g e3 - r_dd_d + h / m0
        known = (-accel_ref_m_s2[0], -accel_ref_m_s2[1], g - accel_ref_m_s2[2])
        aibc_observer = momentum_step(c.observer, aibc_observer, vel_err_m_s, force_applied_prev_n, known, c.dt_s)
        estimate = aibc_observer.estimate_n
    st = PositionState(xi, st.z, st.s, estimate, st.started, st.observer, aibc_observer)
    return st, sub(sub(f, scale(m0, integral)), estimate)


@jitable
def do_step(c: DoConst, st: PositionState, pos_err_m: Vec3, vel_err_m_s: Vec3, accel_ref_m_s2: Vec3,
            specific_force_ned_m_s2: Vec3, has_specific_force: bool,
            force_applied_prev_n: Vec3) -> tuple[PositionState, Vec3]:
    """PD+DO and INDI ``f = f0 - h_f_hat``  (29), (30); ISM+DO adds ``- K_f sat(s_p / eps_p)``  (31)."""
    f = nominal_force(c.mass_kg, c.gravity_m_s2, accel_ref_m_s2, pos_err_m, vel_err_m_s, c.k_p, c.k_v)
    observer, estimate = st.observer, st.estimate_n
    if has_specific_force:
        observer = force_observer_step(c.observer, observer, specific_force_ned_m_s2, force_applied_prev_n, ZERO3)
        estimate = observer.estimate_n
    f = sub(f, estimate)
    z, s, started = st.z, st.s, st.started
    if c.sliding:
        z, s, started, term = _sliding_term(c, z, started, pos_err_m, vel_err_m_s)
        f = sub(f, term)
    return PositionState(st.xi, z, s, estimate, started, observer, st.aibc_observer), f


STEPS: dict[type, Callable[..., tuple[PositionState, Vec3]]] = {PidConst: pid_step, AibcConst: aibc_step,
                                                               DoConst: do_step}
"""Each const record's step function."""


@chosen_by_type(STEPS)
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
    """One position step of the controller whose constants ``c`` are: the new state and the force
    f [N, NED]. The step is the one of ``c``'s type (:data:`STEPS`); compiled, it is chosen once,
    when the caller is compiled (:func:`~.jit.chosen_by_type`).

    ``specific_force_ned_m_s2`` is ``r_dd - g e3`` (accelerometer rotated to NED, or differentiated
    position minus gravity; ignored unless ``has_specific_force``), ``force_applied_prev_n`` the
    previous step's force as the gains' ``force_source`` asks
    (:func:`~companion.control.outer_loop.observer_force`): the force observer's inputs (30).
    """
    return STEPS[type(c)](c, st, pos_err_m, vel_err_m_s, accel_ref_m_s2, specific_force_ned_m_s2,
                          has_specific_force, force_applied_prev_n)


@jitable
def _integrate(c: PidConst | AibcConst, xi: Vec3, pos_err_m: Vec3, k_i: Vec3) -> tuple[Vec3, Vec3]:
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
def _sliding_term(c: DoConst, z: Vec3, started: bool, pos_err_m: Vec3,
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
    observer's inputs (30). A thin wrapper around :func:`position_step` holding its state; the
    type of its constants (:func:`position_const`) picks the step function.
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
