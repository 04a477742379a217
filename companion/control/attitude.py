"""Quaternion attitude tracking: PD, PD+DO and boundary-layer ISM+DO (paper section III).

The three controllers share the geometric error and the nominal law; they differ only in the
robust term ``tau_1`` of (23)::

    PD       tau = tau_0
    PD+DO    tau = tau_0 - h_tau_hat
    ISM+DO   tau = tau_0 - h_tau_hat - K_w sat(s / eps)
    INDI     tau = tau_f + J0 (nu - w'_f)        nu = tau_0 / J0 without the gyroscopic model

INDI (incremental nonlinear dynamic inversion, Smeur, Chu & de Croon 2016) is the state of the
art the paper's approach is compared with in practice; it shares the error and the desired
angular acceleration ``nu`` of (13), and replaces the model by the measured angular
acceleration (:func:`~.observers.incremental_step`).

Error function ``H = eps~^T eps~`` gives the feedback vector ``e = 2 eta~ eps~``, stable at both
``eta~ = +-1``: ``q`` and ``-q`` give the same torque, so there is no unwinding and no sign logic.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from . import quaternion as quat
from .jit import jitable
from .names import controllers_for
from .observers import (
    IncrementalConst,
    IncrementalState,
    TorqueObserverState,
    incremental_const,
    incremental_init,
    incremental_step,
    torque_observer_init,
    torque_observer_step,
)
from .stepper import Stepper
from .params import AttitudeGains
from .quaternion import Quat
from .vector import (
    ZERO3,
    Real,
    Vec3,
    absolute,
    add,
    cross,
    is_scalar,
    lowpass_alpha,
    mul,
    sat,
    sub,
    where,
)

__all__ = [
    "ATTITUDE_CONTROLLERS",
    "AttitudeError",
    "attitude_error",
    "feedback_vector",
    "feedback_vector_rate",
    "rate_error",
    "nominal_torque",
    "AttitudeConst",
    "AttitudeState",
    "attitude_const",
    "attitude_init",
    "attitude_step",
    "attitude_disturbance_estimate",
    "AttitudeController",
]

ATTITUDE_CONTROLLERS = controllers_for("attitude")
PD, PD_DO, ISM_DO, INDI = (ATTITUDE_CONTROLLERS.index(n) for n in ("pd", "pd_do", "ism_do", "indi"))
"""``AttitudeConst.kind``: the index in ATTITUDE_CONTROLLERS (the registry, companion/control/names.py)."""


@jitable
def attitude_error(q: Quat, q_d: Quat) -> Quat:
    """``q~ = q_d^* ⊗ q``: rotation from the desired frame D to the body frame B (5)."""
    return quat.relative(q_d, q)


@jitable
def feedback_vector(q_err: Quat) -> Vec3:
    """``e = 2 eta~ eps~``, the gradient form of ``H = eps~^T eps~`` (section III.A)."""
    k = 2.0 * q_err[0]
    return (k * q_err[1], k * q_err[2], k * q_err[3])


@jitable
def rate_error(q_err: Quat, omega_rad_s: Vec3, omega_d_rad_s: Vec3) -> tuple[Vec3, Vec3]:
    """``(omega~, R~^T omega_d)`` with ``omega~ = omega - R~^T omega_d`` (6); ``omega_d`` in D."""
    omega_d_body = quat.rotate_inverse(q_err, omega_d_rad_s)
    return sub(omega_rad_s, omega_d_body), omega_d_body


@jitable
def feedback_vector_rate(q_err: Quat, omega_err_rad_s: Vec3) -> Vec3:
    """``d/dt e`` from the error kinematics ``q~' = 1/2 q~ ⊗ (0, omega~)`` (no differentiation)."""
    eta = q_err[0]
    eps: Vec3 = (q_err[1], q_err[2], q_err[3])
    # e' = 2 (eta' eps + eta eps'), eta' = -1/2 eps.w, eps' = 1/2 (eta w + eps x w)
    w0, w1, w2 = omega_err_rad_s
    along = eps[0] * w0 + eps[1] * w1 + eps[2] * w2
    return (
        -eps[0] * along + eta * (eta * w0 + (eps[1] * w2 - eps[2] * w1)),
        -eps[1] * along + eta * (eta * w1 + (eps[2] * w0 - eps[0] * w2)),
        -eps[2] * along + eta * (eta * w2 + (eps[0] * w1 - eps[1] * w0)),
    )


class AttitudeError(NamedTuple):
    """Everything the laws need about the tracking error at one instant."""

    q_err: Quat
    e: Vec3
    """feedback vector 2 eta~ eps~"""
    e_dot: Vec3
    omega_err: Vec3
    omega_d_body: Vec3
    """R~^T omega_d: the desired rate expressed in B"""

    @staticmethod
    def of(q: Quat, omega_rad_s: Vec3, q_d: Quat, omega_d_rad_s: Vec3) -> AttitudeError:
        return attitude_error_of(q, omega_rad_s, q_d, omega_d_rad_s)


@jitable
def attitude_error_of(q: Quat, omega_rad_s: Vec3, q_d: Quat, omega_d_rad_s: Vec3) -> AttitudeError:
    q_err = attitude_error(q, q_d)
    omega_err, omega_d_body = rate_error(q_err, omega_rad_s, omega_d_rad_s)
    return AttitudeError(q_err, feedback_vector(q_err), feedback_vector_rate(q_err, omega_err), omega_err,
                         omega_d_body)


@jitable
def nominal_torque(
    err: AttitudeError,
    omega_rad_s: Vec3,
    omega_d_dot_rad_s2: Vec3,
    inertia_kg_m2: Vec3,
    k_v: Real,
    c: Real,
) -> Vec3:
    """``tau_0 = J0 (R~^T omega_d' + (R~^T)' omega_d - K_v e' - c e) + omega x J0 omega``  (13).

    ``(R~^T)' omega_d = -omega~ x (R~^T omega_d)`` because ``R~' = R~ S(omega~)``.
    """
    a, b = err.omega_d_body, err.omega_err
    # feed-forward: R~^T omega_d' + (R~^T omega_d) x omega~
    ff0 = a[1] * b[2] - a[2] * b[1]
    ff1 = a[2] * b[0] - a[0] * b[2]
    ff2 = a[0] * b[1] - a[1] * b[0]
    wd = quat.rotate_inverse(err.q_err, omega_d_dot_rad_s2)
    ff0, ff1, ff2 = ff0 + wd[0], ff1 + wd[1], ff2 + wd[2]
    e, e_dot, j, w = err.e, err.e_dot, inertia_kg_m2, omega_rad_s
    jw0, jw1, jw2 = j[0] * w[0], j[1] * w[1], j[2] * w[2]
    return (
        j[0] * (ff0 - k_v * e_dot[0] - c * e[0]) + (w[1] * jw2 - w[2] * jw1),
        j[1] * (ff1 - k_v * e_dot[1] - c * e[1]) + (w[2] * jw0 - w[0] * jw2),
        j[2] * (ff2 - k_v * e_dot[2] - c * e[2]) + (w[0] * jw1 - w[1] * jw0),
    )


class AttitudeConst(NamedTuple):
    """What :func:`attitude_step` needs besides its state: gains derived for one step length."""

    kind: int
    inertia_kg_m2: Vec3
    """J0, the controller's nominal inertia"""
    k_v: Real
    c: Real
    eps: Vec3
    k_w: Vec3
    anti_windup: bool
    observer_alpha: Vec3
    incremental: IncrementalConst
    dt_s: float


class AttitudeState(NamedTuple):
    z: Vec3
    """ISM integral state of (10)-(11)"""
    s: Vec3
    """last sliding variable, for logs"""
    started: bool
    observer: TorqueObserverState
    incremental: IncrementalState
    omega: Vec3
    """last rate (INDI's estimate adds back its gyroscopic part)"""


def attitude_const(kind: str, gains: AttitudeGains, inertia_kg_m2: Vec3, dt_s: float) -> AttitudeConst:
    if kind not in ATTITUDE_CONTROLLERS:
        raise ValueError(f"unknown attitude controller {kind!r}; expected one of {ATTITUDE_CONTROLLERS}")
    eps = gains.boundary_layer_rad_s
    b = gains.observer_gain_rad_s
    return AttitudeConst(
        kind=ATTITUDE_CONTROLLERS.index(kind),
        inertia_kg_m2=inertia_kg_m2,
        k_v=2.0 * gains.omega_c_rad_s,
        c=gains.omega_c_rad_s ** 2,
        eps=eps,
        # K = k_s J0 (inside the layer), K_w = K eps
        k_w=mul(mul(gains.sliding_gain_rad_s, inertia_kg_m2), eps),
        anti_windup=gains.anti_windup,
        observer_alpha=(lowpass_alpha(b[0], dt_s), lowpass_alpha(b[1], dt_s), lowpass_alpha(b[2], dt_s)),
        incremental=incremental_const(inertia_kg_m2, gains.indi_filter_rad_s, gains.indi_actuator_time_constant_s,
                                      dt_s),
        dt_s=dt_s,
    )


@jitable
def attitude_init() -> AttitudeState:
    return AttitudeState(ZERO3, ZERO3, False, torque_observer_init(), incremental_init(), ZERO3)


@jitable
def attitude_step(
    c: AttitudeConst,
    st: AttitudeState,
    q: Quat,
    omega_rad_s: Vec3,
    q_d: Quat,
    omega_d_rad_s: Vec3,
    torque_applied_prev_nm: Vec3,
    omega_d_dot_rad_s2: Vec3,
) -> tuple[AttitudeState, Vec3]:
    """One attitude step: the new state and the requested body torque [N m].

    ``torque_applied_prev_nm`` is what the rotors actually applied in the previous step (from
    :func:`allocation.allocate`): the observers must see saturation, not mistake it for a disturbance.
    """
    err = attitude_error_of(q, omega_rad_s, q_d, omega_d_rad_s)
    tau = nominal_torque(err, omega_rad_s, omega_d_dot_rad_s2, c.inertia_kg_m2, c.k_v, c.c)
    if c.kind == INDI:
        # J0 nu = tau_0 - w x J0 w; tau = tau_f + J0 nu - J0 w'_f
        w, j = omega_rad_s, c.inertia_kg_m2
        incremental = incremental_step(c.incremental, st.incremental, omega_rad_s, torque_applied_prev_nm, c.dt_s)
        tau = sub(sub(tau, cross(w, mul(j, w))), incremental.estimate_nm)
        return AttitudeState(st.z, st.s, st.started, st.observer, incremental, omega_rad_s), tau
    observer = st.observer
    if c.kind == PD_DO or c.kind == ISM_DO:
        observer = torque_observer_step(observer, c.inertia_kg_m2, c.observer_alpha, omega_rad_s,
                                        torque_applied_prev_nm, c.dt_s, ZERO3)
        tau = sub(tau, observer.estimate_nm)
    z, s, started = st.z, st.s, st.started
    if c.kind == ISM_DO:
        z, s, started, term = _sliding_term(c, z, started, err)
        tau = sub(tau, term)
    return AttitudeState(z, s, started, observer, st.incremental, omega_rad_s), tau


@jitable
def _sliding_term(c: AttitudeConst, z: Vec3, started: bool, err: AttitudeError) -> tuple[Vec3, Vec3, bool, Vec3]:
    """``K_w sat(s / eps)`` with ``s = s0 + z``, ``s0 = omega~ + K_v e``, ``z' = c e`` (10), (11), (23).

    Anti-windup ([29]): where ``|s / eps| > 1`` the element is reset to ``z = -s0`` and not
    integrated, so the integral cannot wind up while the term saturates. Returns the new ``z``,
    ``s``, the started flag and the term.
    """
    k_v, cc, eps = c.k_v, c.c, c.eps
    w, e = err.omega_err, err.e
    s0 = (w[0] + k_v * e[0], w[1] + k_v * e[1], w[2] + k_v * e[2])
    if not started:
        z = (-s0[0], -s0[1], -s0[2])  # z(0) = -s0(0): sliding from the first instant
    s = (s0[0] + z[0], s0[1] + z[1], s0[2] + z[2])
    z = _integrate_with_reset(z, s, s0, (cc * e[0], cc * e[1], cc * e[2]), eps, c.dt_s, c.anti_windup)
    return z, s, True, mul(c.k_w, sat(s, eps))


@jitable
def attitude_disturbance_estimate(c: AttitudeConst, st: AttitudeState) -> Vec3:
    """What the controller attributes to disturbance [N m]: the DO's estimate, or for INDI what it
    cancels less the gyroscopic torque it includes."""
    if c.kind == INDI:
        w, j = st.omega, c.inertia_kg_m2
        return add(st.incremental.estimate_nm, cross(w, mul(j, w)))
    return st.observer.estimate_nm


@dataclass
class AttitudeController(Stepper[AttitudeConst]):
    """PD, PD+DO, ISM+DO or INDI attitude tracking, chosen by ``kind`` (one of ATTITUDE_CONTROLLERS).

    Call :meth:`update` once per attitude step with the latest gyro rate and the torque that
    the rotors actually applied in the previous step (from :func:`allocation.allocate`). A thin
    wrapper around :func:`attitude_step` holding its state.
    """

    kind: str
    gains: AttitudeGains
    inertia_kg_m2: Vec3
    """J0, the controller's nominal inertia"""
    state: AttitudeState = field(default_factory=attitude_init, repr=False)

    def __post_init__(self) -> None:
        self.const(1e-3)  # checks the kind

    def _build(self, dt_s: float) -> AttitudeConst:
        return attitude_const(self.kind, self.gains, self.inertia_kg_m2, dt_s)

    @property
    def z(self) -> Vec3:
        return self.state.z

    @property
    def s(self) -> Vec3:
        return self.state.s

    def reset_integral(self) -> None:
        """Restart the sliding mode from the current error (z = -s0) at the next update: for a
        change of reference type, when the old integral no longer means anything."""
        self.state = self.state._replace(z=ZERO3, s=ZERO3, started=False)

    @property
    def disturbance_estimate_nm(self) -> Vec3:
        assert self._const is not None
        return attitude_disturbance_estimate(self._const, self.state)

    def update(
        self,
        q: Quat,
        omega_rad_s: Vec3,
        q_d: Quat,
        omega_d_rad_s: Vec3,
        torque_applied_prev_nm: Vec3,
        dt_s: float,
        omega_d_dot_rad_s2: Vec3 = ZERO3,
    ) -> Vec3:
        """Requested body torque [N m] for this step."""
        self.state, tau = attitude_step(self.const(dt_s), self.state, q, omega_rad_s, q_d, omega_d_rad_s,
                                        torque_applied_prev_nm, omega_d_dot_rad_s2)
        return tau


@jitable
def _integrate_with_reset(z: Vec3, s: Vec3, s0: Vec3, z_dot: Vec3, eps: Vec3, dt_s: float, anti_windup: bool) -> Vec3:
    """``z + z_dot dt``, except that an element whose ``|s| > eps`` is reset to ``-s0`` ([29]).

    Shared by the attitude (11) and position (31) integral sliding modes.
    """
    if not anti_windup:
        return (z[0] + z_dot[0] * dt_s, z[1] + z_dot[1] * dt_s, z[2] + z_dot[2] * dt_s)
    if is_scalar(s[0]):  # one vehicle: plain comparisons instead of where()
        return (
            -s0[0] if abs(s[0]) > eps[0] else z[0] + z_dot[0] * dt_s,  # type: ignore[operator]
            -s0[1] if abs(s[1]) > eps[1] else z[1] + z_dot[1] * dt_s,  # type: ignore[operator]
            -s0[2] if abs(s[2]) > eps[2] else z[2] + z_dot[2] * dt_s,  # type: ignore[operator]
        )
    return (
        where(absolute(s[0]) > eps[0], -s0[0], z[0] + z_dot[0] * dt_s),
        where(absolute(s[1]) > eps[1], -s0[1], z[1] + z_dot[1] * dt_s),
        where(absolute(s[2]) > eps[2], -s0[2], z[2] + z_dot[2] * dt_s),
    )
