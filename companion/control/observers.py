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
from dataclasses import dataclass, field
from typing import NamedTuple

from .jit import jitable
from .stepper import Stepper
from .vector import (
    ZERO3,
    Real,
    Vec3,
    lowpass_alpha,
    scale,
    sub,
)

__all__ = [
    "ForceObserver", "MomentumObserver", "MatchingFilter", "lowpass_step",
    "TorqueObserverState", "torque_observer_init", "torque_observer_step",
    "MATCHING_CAPACITY", "MatchingConst", "MatchingState", "matching_const", "matching_init", "matching_step",
    "ForceObserverConst", "ForceObserverState", "force_observer_const", "force_observer_init", "force_observer_step",
    "MomentumConst", "MomentumState", "momentum_init", "momentum_step",
    "IncrementalConst", "IncrementalState", "incremental_const", "incremental_init", "incremental_step",
    "lowpass_chain",
]

Stages4 = tuple[Vec3, Vec3, Vec3, Vec3]
ZERO_STAGES: Stages4 = (ZERO3, ZERO3, ZERO3, ZERO3)


@jitable
def lowpass_step(estimate: Vec3, measurement: Vec3, alpha: Vec3) -> Vec3:
    """One step of the first-order filter ``h_hat += alpha (h_meas - h_hat)`` (19)."""
    return (
        estimate[0] + alpha[0] * (measurement[0] - estimate[0]),
        estimate[1] + alpha[1] * (measurement[1] - estimate[1]),
        estimate[2] + alpha[2] * (measurement[2] - estimate[2]),
    )


@jitable
def lowpass_chain(stages: Stages4, u: Vec3, alpha: Vec3, order: int) -> tuple[Stages4, Vec3]:
    """``order`` (at most 4) equal first-order stages in series: new stages and the output."""
    s0, s1, s2, s3 = stages
    y = u
    if order > 0:
        s0 = lowpass_step(s0, y, alpha)
        y = s0
    if order > 1:
        s1 = lowpass_step(s1, y, alpha)
        y = s1
    if order > 2:
        s2 = lowpass_step(s2, y, alpha)
        y = s2
    if order > 3:
        s3 = lowpass_step(s3, y, alpha)
        y = s3
    return (s0, s1, s2, s3), y


def _alphas(bandwidth_rad_s: Vec3, dt_s: float) -> Vec3:
    b = bandwidth_rad_s
    return (lowpass_alpha(b[0], dt_s), lowpass_alpha(b[1], dt_s), lowpass_alpha(b[2], dt_s))


# --- torque observer (15), (19) ---------------------------------------------------------------


class TorqueObserverState(NamedTuple):
    estimate_nm: Vec3
    omega_prev: Vec3
    primed: bool
    """``omega_prev`` holds a rate (false before the first update)"""


@jitable
def torque_observer_init() -> TorqueObserverState:
    return TorqueObserverState(ZERO3, ZERO3, False)


@jitable
def torque_measure(inertia_kg_m2: Vec3, omega_rad_s: Vec3, omega_prev: Vec3, torque_applied_prev_nm: Vec3,
                   dt_s: float) -> Vec3:
    """``h_meas = J0 (w - w_prev) / dt - tau_applied,k-1 + w x J0 w``, the raw measurement of (15)."""
    j, w, prev, tau = inertia_kg_m2, omega_rad_s, omega_prev, torque_applied_prev_nm
    inv_dt = 1.0 / dt_s
    jw0, jw1, jw2 = j[0] * w[0], j[1] * w[1], j[2] * w[2]
    return (
        j[0] * (w[0] - prev[0]) * inv_dt - tau[0] + (w[1] * jw2 - w[2] * jw1),
        j[1] * (w[1] - prev[1]) * inv_dt - tau[1] + (w[2] * jw0 - w[0] * jw2),
        j[2] * (w[2] - prev[2]) * inv_dt - tau[2] + (w[0] * jw1 - w[1] * jw0),
    )


@jitable
def torque_observer_step(st: TorqueObserverState, inertia_kg_m2: Vec3, alpha: Vec3, omega_rad_s: Vec3,
                         torque_applied_prev_nm: Vec3, dt_s: float, model_torque_nm: Vec3) -> TorqueObserverState:
    """One step of (15), (19); ``model_torque_nm`` is a known torque (e.g. drag) to leave out."""
    if not st.primed:
        return TorqueObserverState(st.estimate_nm, omega_rad_s, True)
    h_meas = sub(torque_measure(inertia_kg_m2, omega_rad_s, st.omega_prev, torque_applied_prev_nm, dt_s),
                 model_torque_nm)
    return TorqueObserverState(lowpass_step(st.estimate_nm, h_meas, alpha), omega_rad_s, True)


# --- the matching filter: the acceleration's delay and low-pass, applied to the force -------------

MATCHING_CAPACITY = 16
"""Longest delay line of :class:`MatchingFilter`, in steps (150 ms at the 100 Hz position loop)."""


class MatchingConst(NamedTuple):
    steps: int
    """delay in steps"""
    order: int
    alpha: Vec3
    active: bool


class MatchingState(NamedTuple):
    line: tuple[Vec3, ...]
    """the last MATCHING_CAPACITY inputs, newest last (all the first input until that many arrived)"""
    stages: Stages4
    primed: bool


def matching_const(delay_s: float, cutoff_hz: float, order: int, dt_s: float) -> MatchingConst:
    steps = int(round(delay_s / dt_s))
    if steps >= MATCHING_CAPACITY:
        raise ValueError(f"matching delay {delay_s} s is {steps} steps of {dt_s} s; at most "
                         f"{MATCHING_CAPACITY - 1} are kept")
    if order > 4:
        raise ValueError(f"matching filter order {order}: at most 4")
    filtered = cutoff_hz > 0.0 and order > 0
    a = lowpass_alpha(2.0 * math.pi * cutoff_hz, dt_s) if filtered else 0.0
    return MatchingConst(steps, order if filtered else 0, (a, a, a), delay_s > 0.0 or cutoff_hz > 0.0)


@jitable
def _filled(u: Vec3) -> tuple[Vec3, ...]:
    """A delay line of MATCHING_CAPACITY copies of ``u`` (written out: compiled code has no ``tuple * n``)."""
    return (u, u, u, u, u, u, u, u, u, u, u, u, u, u, u, u)


@jitable
def matching_init() -> MatchingState:
    return MatchingState(_filled(ZERO3), ZERO_STAGES, False)


@jitable
def matching_step(c: MatchingConst, st: MatchingState, u: Vec3) -> tuple[MatchingState, Vec3]:
    """``u`` through the delay, then ``order`` first-order stages (which start at the first output)."""
    if not st.primed:
        line = _filled(u)
    else:
        line = st.line[1:] + (u,)
    y = line[MATCHING_CAPACITY - 1 - c.steps]
    stages = st.stages
    if not st.primed:
        stages = (y, y, y, y)
    stages, y = lowpass_chain(stages, y, c.alpha, c.order)
    return MatchingState(line, stages, True), y


@dataclass
class MatchingFilter(Stepper[MatchingConst]):
    """A pure delay and ``order`` equal first-order low-passes at ``cutoff_hz`` (0: none).

    Model of how the acceleration measurement was obtained (e.g. 60 Hz positions, 10 ms late,
    differenced twice through 5 Hz filters: about 30 ms and two 5 Hz poles), applied to the
    force input of (30). The first input fills the state, so nothing rings at start. A wrapper
    around :func:`matching_step`.
    """

    delay_s: float = 0.0
    cutoff_hz: float = 0.0
    order: int = 2
    state: MatchingState = field(default_factory=matching_init, repr=False)

    @property
    def active(self) -> bool:
        return self.delay_s > 0.0 or self.cutoff_hz > 0.0

    def _build(self, dt_s: float) -> MatchingConst:
        return matching_const(self.delay_s, self.cutoff_hz, self.order, dt_s)

    def update(self, u: Vec3, dt_s: float) -> Vec3:
        self.state, y = matching_step(self.const(dt_s), self.state, u)
        return y


# --- force observer (30) ------------------------------------------------------------------------


class ForceObserverConst(NamedTuple):
    mass_kg: Real
    alpha: Vec3
    order: int
    matching: MatchingConst


class ForceObserverState(NamedTuple):
    estimate_n: Vec3
    stages: Stages4
    matching: MatchingState


def force_observer_const(mass_kg: Real, bandwidth_rad_s: Vec3, order: int, matching: MatchingConst,
                         dt_s: float) -> ForceObserverConst:
    if not 1 <= order <= 4:
        raise ValueError(f"force observer order {order}: expected 1 to 4")
    return ForceObserverConst(mass_kg, _alphas(bandwidth_rad_s, dt_s), order, matching)


@jitable
def force_observer_init() -> ForceObserverState:
    return ForceObserverState(ZERO3, ZERO_STAGES, matching_init())


@jitable
def force_measure(mass_kg: Real, specific_force_ned_m_s2: Vec3, force_ned_n: Vec3) -> Vec3:
    """``m0 (r_dd - g e3) - f``: the raw disturbance measurement of (30) [N]."""
    return sub(scale(mass_kg, specific_force_ned_m_s2), force_ned_n)


@jitable
def force_observer_step(c: ForceObserverConst, st: ForceObserverState, specific_force_ned_m_s2: Vec3,
                        force_applied_ned_n: Vec3, model_force_n: Vec3) -> ForceObserverState:
    """``h_hat' = Gamma (m0 (r_dd - g e3) - f - h_hat)``  (30), through ``order`` equal stages."""
    matching = st.matching
    if c.matching.active:
        matching, force_applied_ned_n = matching_step(c.matching, matching, force_applied_ned_n)
    h_meas = sub(force_measure(c.mass_kg, specific_force_ned_m_s2, force_applied_ned_n), model_force_n)
    stages, y = lowpass_chain(st.stages, h_meas, c.alpha, c.order)
    return ForceObserverState(y, stages, matching)


@dataclass
class ForceObserver(Stepper[ForceObserverConst]):
    """Force disturbance estimate ``h_f_hat`` [N] in NED (30).

    ``h_meas = m0 (r_ddot - g e3) - f``, where ``r_ddot - g e3`` is the accelerometer's
    specific force rotated into NED (or differentiated position minus gravity) and ``f`` is the
    force the vehicle was asked for: the paper's commanded ``-T R(q_d) e3``, or ``-T R(q) e3``
    along the measured attitude (``PositionGains.force_source``). A wrapper around
    :func:`force_observer_step`.
    """

    mass_kg: float | Real
    bandwidth_rad_s: Vec3
    matching: MatchingFilter = field(default_factory=MatchingFilter)
    """the acceleration's delay and filter, applied to the force (see the module docstring)"""
    order: int = 1
    """equal first-order stages of the low-pass (1: (19); 2: INDI's second-order filter)"""
    state: ForceObserverState = field(default_factory=force_observer_init, repr=False)

    def _build(self, dt_s: float) -> ForceObserverConst:
        return force_observer_const(self.mass_kg, self.bandwidth_rad_s, self.order, self.matching.const(dt_s), dt_s)

    @property
    def estimate_n(self) -> Vec3:
        return self.state.estimate_n

    def measure(self, specific_force_ned_m_s2: Vec3, force_ned_n: Vec3) -> Vec3:
        """``m0 (r_dd - g e3) - f``: the raw disturbance measurement of (30) [N]."""
        return force_measure(self.mass_kg, specific_force_ned_m_s2, force_ned_n)

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
        self.state = st = force_observer_step(self.const(dt_s), self.state, specific_force_ned_m_s2,
                                              force_applied_ned_n, model_force_n)
        return st.estimate_n


# --- the momentum form of (30) --------------------------------------------------------------------


class MomentumConst(NamedTuple):
    mass_kg: Real
    gamma: Vec3
    matching: MatchingConst


class MomentumState(NamedTuple):
    estimate_n: Vec3
    p_hat: Vec3
    primed: bool
    matching: MatchingState


@jitable
def momentum_init() -> MomentumState:
    return MomentumState(ZERO3, ZERO3, False, matching_init())


@jitable
def momentum_step(c: MomentumConst, st: MomentumState, vel_m_s: Vec3, force_n: Vec3, known_accel_m_s2: Vec3,
                  dt_s: float) -> MomentumState:
    """``h_hat = Gamma (m0 v - p_hat)``, ``p_hat' = f + m0 a_known + h_hat`` over the step that ended."""
    m, g = c.mass_kg, c.gamma
    momentum = scale(m, vel_m_s)
    matching = st.matching
    if c.matching.active:
        matching, force_n = matching_step(c.matching, matching, force_n)
    if not st.primed:  # no step behind us yet: the model starts where the vehicle is
        return MomentumState(st.estimate_n, momentum, True, matching)
    a, h, p = known_accel_m_s2, st.estimate_n, st.p_hat
    p = (p[0] + dt_s * (force_n[0] + m * a[0] + h[0]),
         p[1] + dt_s * (force_n[1] + m * a[1] + h[1]),
         p[2] + dt_s * (force_n[2] + m * a[2] + h[2]))
    estimate = (g[0] * (momentum[0] - p[0]), g[1] * (momentum[1] - p[1]), g[2] * (momentum[2] - p[2]))
    return MomentumState(estimate, p, True, matching)


@dataclass
class MomentumObserver(Stepper[MomentumConst]):
    """Force disturbance estimate [N] from a velocity, without differentiating it.

    ``h_hat = Gamma (m0 v - p_hat)``, ``p_hat' = f + m0 a_known + h_hat``, so that
    ``h_hat' = Gamma (m0 v' - f - m0 a_known - h_hat)``: exactly (30) with ``r_dd = v'``, but the
    velocity is used as it is (the generalised-momentum observer). ``a_known`` is whatever
    acceleration the model knows besides ``f / m0`` (gravity ``g e3``; minus the reference's
    acceleration when ``v`` is a velocity error). The force passes through ``matching``, the
    velocity's own delay and filter (see the module docstring). A wrapper around
    :func:`momentum_step`.
    """

    mass_kg: float | Real
    bandwidth_rad_s: Vec3
    matching: MatchingFilter = field(default_factory=MatchingFilter)
    state: MomentumState = field(default_factory=momentum_init, repr=False)

    @property
    def estimate_n(self) -> Vec3:
        return self.state.estimate_n

    def _build(self, dt_s: float) -> MomentumConst:
        return MomentumConst(self.mass_kg, self.bandwidth_rad_s, self.matching.const(dt_s))

    def update(self, vel_m_s: Vec3, force_n: Vec3, known_accel_m_s2: Vec3, dt_s: float) -> Vec3:
        """Advance over the step that just ended: ``vel_m_s`` now, ``force_n`` and
        ``known_accel_m_s2`` as they acted during that step. Returns the estimate [N]."""
        self.state = momentum_step(self.const(dt_s), self.state, vel_m_s, force_n, known_accel_m_s2, dt_s)
        return self.state.estimate_n


# --- INDI's incremental measurement ---------------------------------------------------------------


class IncrementalConst(NamedTuple):
    inertia_kg_m2: Vec3
    alpha: Vec3
    """the second-order filter's stage gain"""
    actuator_alpha: Vec3
    """the rotors' first-order lag over a step"""


class IncrementalState(NamedTuple):
    estimate_nm: Vec3
    omega_prev: Vec3
    primed: bool
    actuator: Vec3
    stages: Stages4


def incremental_const(inertia_kg_m2: Vec3, filter_rad_s: float, actuator_time_constant_s: float,
                      dt_s: float) -> IncrementalConst:
    tc = actuator_time_constant_s
    a_act = 1.0 - math.exp(-dt_s / tc) if tc > 0.0 else 1.0
    a = lowpass_alpha(filter_rad_s, dt_s)
    return IncrementalConst(inertia_kg_m2, (a, a, a), (a_act, a_act, a_act))


@jitable
def incremental_init() -> IncrementalState:
    return IncrementalState(ZERO3, ZERO3, False, ZERO3, ZERO_STAGES)


@jitable
def incremental_step(c: IncrementalConst, st: IncrementalState, omega_rad_s: Vec3, torque_applied_prev_nm: Vec3,
                     dt_s: float) -> IncrementalState:
    actuator = lowpass_step(st.actuator, torque_applied_prev_nm, c.actuator_alpha)
    if not st.primed:
        return IncrementalState(st.estimate_nm, omega_rad_s, True, actuator, st.stages)
    j, inv, prev = c.inertia_kg_m2, 1.0 / dt_s, st.omega_prev
    j_w_dot = (j[0] * (omega_rad_s[0] - prev[0]) * inv, j[1] * (omega_rad_s[1] - prev[1]) * inv,
               j[2] * (omega_rad_s[2] - prev[2]) * inv)
    alpha = c.alpha
    s0, s1, s2, s3 = st.stages
    s0 = lowpass_step(s0, j_w_dot, alpha)
    s1 = lowpass_step(s1, s0, alpha)
    s2 = lowpass_step(s2, actuator, alpha)
    s3 = lowpass_step(s3, s2, alpha)
    return IncrementalState(sub(s1, s3), omega_rad_s, True, actuator, (s0, s1, s2, s3))
