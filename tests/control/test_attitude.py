"""Attitude laws of section III against closed-form expectations on an ideal rigid body."""

import math

import numpy as np
import pytest

from companion.control import quaternion as quat
from companion.control import vector as vec
from companion.control.attitude import (
    ATTITUDE_CONTROLLERS,
    AttitudeController,
    AttitudeError,
    feedback_vector,
    feedback_vector_rate,
)
from companion.control.params import AttitudeGains, VehicleParams, attitude_stability_margin

J = VehicleParams().inertia_kg_m2
DT = 0.001


def rigid_body(ctrl, q0, seconds, torque_dist=(0.0, 0.0, 0.0), q_d=quat.IDENTITY, omega_d=(0.0, 0.0, 0.0),
               inertia=J):
    """Ideal actuators: J w' = tau + h - w x J w, q' = 1/2 q (0, w). Returns angle history [rad]."""
    q, w = q0, (0.0, 0.0, 0.0)
    applied = (0.0, 0.0, 0.0)
    angles = []
    for _ in range(int(seconds / DT)):
        tau = ctrl.update(q, w, q_d, omega_d, applied, DT)
        applied = tau
        acc = vec.sub(vec.add(tau, torque_dist), vec.cross(w, vec.mul(inertia, w)))
        w = vec.add(w, vec.scale(DT, vec.div(acc, inertia)))
        q = quat.integrate(q, w, DT)
        angles.append(quat.angle_between(q_d, q))
    return np.array(angles), q, w


def test_feedback_rate_is_the_time_derivative_of_the_feedback_vector():
    """The analytic e' (from the error kinematics) equals a central difference of e(t)."""
    q = quat.normalize((0.8, 0.3, -0.4, 0.2))
    q_d = quat.normalize((0.9, -0.1, 0.2, 0.3))
    w, w_d = (0.7, -1.1, 0.4), (0.2, 0.5, -0.3)
    h = 1e-6

    def e_at(t):
        qt = quat.integrate(q, w, t)
        qdt = quat.integrate(q_d, w_d, t)
        return feedback_vector(quat.mul(quat.conj(qdt), qt))

    numeric = vec.scale(1 / (2 * h), vec.sub(e_at(h), e_at(-h)))
    err = AttitudeError.of(q, w, q_d, w_d)
    np.testing.assert_allclose(err.e_dot, numeric, atol=1e-7)
    np.testing.assert_allclose(feedback_vector_rate(err.q_err, err.omega_err), numeric, atol=1e-7)


@pytest.mark.parametrize("kind", ATTITUDE_CONTROLLERS)
def test_q_and_minus_q_give_the_same_torque(kind):
    """No unwinding: the torque depends on the rotation, not on the quaternion's sign."""
    q = quat.normalize((-0.2, 0.7, 0.1, -0.6))
    neg = tuple(-c for c in q)
    q_d = quat.normalize((0.9, 0.1, 0.0, 0.3))
    a = AttitudeController(kind, AttitudeGains(), J).update(q, (0.1, 0.2, 0.3), q_d, (0, 0, 0), (0, 0, 0), DT)
    b = AttitudeController(kind, AttitudeGains(), J).update(neg, (0.1, 0.2, 0.3), q_d, (0, 0, 0), (0, 0, 0), DT)
    np.testing.assert_allclose(a, b, atol=1e-15)


@pytest.mark.parametrize("kind", ATTITUDE_CONTROLLERS)
@pytest.mark.parametrize("flip", [False, True])
def test_recovers_from_upside_down_with_either_quaternion_sign(kind, flip):
    """GIVEN 170 deg off WHEN controlled THEN within 0.5 deg in 2 s, and -q0 gives the same flight."""
    q0 = quat.from_axis_angle(vec.scale(1 / math.sqrt(2), (1.0, 1.0, 0.0)), math.radians(170))
    if flip:
        q0 = tuple(-c for c in q0)
    ctrl = AttitudeController(kind, AttitudeGains(), J)
    angles, _, _ = rigid_body(ctrl, q0, 2.0)
    assert angles[-1] < math.radians(0.5)
    assert angles.max() <= math.radians(170) + 1e-9  # never unwinds the long way round


def test_pd_small_step_follows_the_critically_damped_closed_form():
    """Desired dynamics (8) linearised (e ~ angle): th'' + 2w th' + w^2 th = 0, critically damped,
    so th(t) = th0 (1 + w t) e^(-w t) with w = omega_c = 12 rad/s. Tolerance: 1% of th0 (the
    linearisation error of e = sin(th) at 3 deg is 0.05%; Euler at 1 kHz adds ~0.6%)."""
    th0 = math.radians(3)
    ctrl = AttitudeController("pd", AttitudeGains(), J)
    angles, _, _ = rigid_body(ctrl, quat.from_axis_angle((1.0, 0.0, 0.0), th0), 1.0)
    t = np.arange(1, len(angles) + 1) * DT
    w = 12.0
    expected = th0 * (1 + w * t) * np.exp(-w * t)
    assert np.max(np.abs(angles - expected)) < 0.01 * th0


def test_pd_leaves_the_steady_error_the_do_removes():
    """A constant 0.02 N m roll torque: PD settles where c J e = tau, i.e. at
    tau / (J w^2) = 0.02 / (3.5e-3 * 144) = 0.0397 rad; with the observer the estimate converges
    to the torque and the error to zero."""
    h = (0.02, 0.0, 0.0)
    pd = AttitudeController("pd", AttitudeGains(), J)
    angles, _, _ = rigid_body(pd, quat.IDENTITY, 3.0, torque_dist=h)
    # e = 2 eta eps = sin(angle), so the equilibrium angle is asin(tau / (J w^2))
    assert math.isclose(angles[-1], math.asin(0.02 / (J[0] * 144.0)), rel_tol=0.01)

    for kind in ("pd_do", "ism_do"):
        ctrl = AttitudeController(kind, AttitudeGains(), J)
        angles, _, _ = rigid_body(ctrl, quat.IDENTITY, 3.0, torque_dist=h)
        assert angles[-1] < 2e-4, kind
        assert math.isclose(ctrl.disturbance_estimate_nm[0], 0.02, rel_tol=0.01), kind


def test_ism_starts_on_the_sliding_surface_and_resets_when_saturated():
    gains = AttitudeGains()
    ctrl = AttitudeController("ism_do", gains, J)
    q = quat.from_axis_angle((0.0, 1.0, 0.0), 0.2)
    ctrl.update(q, (0.3, 0.0, 0.0), quat.IDENTITY, (0, 0, 0), (0, 0, 0), DT)
    np.testing.assert_allclose(ctrl.s, (0.0, 0.0, 0.0), atol=1e-15)  # z(0) = -s0(0)
    # a rate jump far outside the layer: s saturates, z resets to -s0, s restarts from 0
    ctrl.update(q, (5.0, 0.0, 0.0), quat.IDENTITY, (0, 0, 0), (0, 0, 0), DT)
    assert abs(ctrl.s[0]) > gains.boundary_layer_rad_s[0]
    ctrl.update(q, (5.0, 0.0, 0.0), quat.IDENTITY, (0, 0, 0), (0, 0, 0), DT)
    assert abs(ctrl.s[0]) < 1e-2


def track_yaw_ramp(feed_forward, rate=2.0, seconds=1.0):
    ctrl = AttitudeController("ism_do", AttitudeGains(), J)
    q, w = quat.IDENTITY, (0.0, 0.0, 0.0)
    applied = (0.0, 0.0, 0.0)
    q_d = quat.IDENTITY
    w_d = (0.0, 0.0, rate)
    for _ in range(int(seconds / DT)):
        q_d = quat.integrate(q_d, w_d, DT)
        tau = ctrl.update(q, w, q_d, w_d if feed_forward else (0.0, 0.0, 0.0), applied, DT)
        applied = tau
        acc = vec.sub(tau, vec.cross(w, vec.mul(J, w)))
        w = vec.add(w, vec.scale(DT, vec.div(acc, J)))
        q = quat.integrate(q, w, DT)
    return quat.angle_between(q, q_d)


def test_rate_feedforward_tracks_a_rotating_reference():
    """q_d turning at 2 rad/s about z. With omega_d fed forward the only error left is the one
    sample by which the reference leads the measured attitude: 2 rad/s * 1 ms = 0.115 deg.
    Without it, the rate error itself fights the motion and the loop lags much further."""
    with_ff = track_yaw_ramp(True)
    assert with_ff < 1.2 * 2.0 * DT
    assert track_yaw_ramp(False) > 10 * with_ff


def test_default_gains_satisfy_stability_condition_25():
    assert attitude_stability_margin(AttitudeGains(), VehicleParams()) > 1.0
    weak = AttitudeGains(observer_gain_rad_s=(1.0, 1.0, 1.0))
    assert attitude_stability_margin(weak, VehicleParams()) < 1.0


def track_rate_sine(feed_forward_accel, amplitude=3.0, freq_rad_s=6.0, seconds=2.0):
    """q_d rolling with omega_d = A sin(nu t) (and yawing at 1 rad/s, so R~ is not the identity
    and (R~^T)' omega_d matters), omega_d' given to (13) or not: the worst angle error [rad]."""
    ctrl = AttitudeController("pd", AttitudeGains(), J)
    q, w, q_d = quat.IDENTITY, (0.0, 0.0, 1.0), quat.IDENTITY
    worst = 0.0
    for k in range(int(seconds / DT)):
        t = k * DT
        w_d = (amplitude * math.sin(freq_rad_s * t), 0.0, 1.0)
        w_d_dot = (amplitude * freq_rad_s * math.cos(freq_rad_s * t), 0.0, 0.0)
        tau = ctrl.update(q, w, q_d, w_d, (0.0, 0.0, 0.0), DT, w_d_dot if feed_forward_accel else (0.0, 0.0, 0.0))
        acc = vec.sub(tau, vec.cross(w, vec.mul(J, w)))
        w = vec.add(w, vec.scale(DT, vec.div(acc, J)))
        q = quat.integrate(q, w, DT)
        q_d = quat.integrate(q_d, w_d, DT)
        worst = max(worst, quat.angle_between(q, q_d))
    return worst


def test_rate_derivative_feedforward_of_13_tracks_a_swinging_reference():
    """With omega_d' in (13) the nominal model follows the reference exactly: what is left is the
    Euler integration's one-sample lead, A * 1 ms (0.17 deg). Without it, the error dynamics (8)
    are driven by omega_d' = A nu: the angle lags by about A nu / c = 18 / 144 = 0.125 rad."""
    with_ff = track_rate_sine(True)
    assert with_ff < 2.0 * 3.0 * DT
    without = track_rate_sine(False)
    assert without > 0.5 * 3.0 * 6.0 / 144.0


def test_nominal_law_13_imposes_the_error_dynamics_8_on_the_nominal_model():
    """With J = J0 and no disturbance, tau_0 of (13) makes the error obey (8) exactly:
    omega~' = -K_v e' - c e, whatever the reference does. A reference spinning at 4 rad/s about
    a tilted axis and a start 0.6 rad off and at rest keep omega~ (~4 rad/s) and R~^T omega_d
    large, so every term of (13) matters (a wrong (R~^T)' omega_d or Coriolis term leaves a
    residual of the order of 2 |omega_d| |omega~| ~ 30 rad/s^2). The residual of the one-step
    difference is O(dt) here: below 0.5 rad/s^2 at dt = 1e-4 s."""
    dt = 1e-4
    gains = AttitudeGains()
    k_v, c = 2 * gains.omega_c_rad_s, gains.omega_c_rad_s**2
    ctrl = AttitudeController("pd", gains, J)
    w_d = vec.scale(4.0, vec.scale(1 / math.sqrt(1.09), (0.3, 0.0, 1.0)))
    q, w, q_d = quat.from_axis_angle((1.0, 0.0, 0.0), 0.6), (0.0, 0.0, 0.0), quat.IDENTITY
    prev = None
    worst = 0.0
    for _ in range(3000):
        err = AttitudeError.of(q, w, q_d, w_d)
        if prev is not None:
            p_err = prev
            resid = vec.add(vec.scale(1 / dt, vec.sub(err.omega_err, p_err.omega_err)),
                            vec.add(vec.scale(k_v, p_err.e_dot), vec.scale(c, p_err.e)))
            worst = max(worst, vec.norm(resid))
        prev = err
        tau = ctrl.update(q, w, q_d, w_d, (0.0, 0.0, 0.0), dt)
        acc = vec.div(vec.sub(tau, vec.cross(w, vec.mul(J, w))), J)
        w = vec.add(w, vec.scale(dt, acc))
        q = quat.integrate(q, w, dt)
        q_d = quat.integrate(q_d, w_d, dt)
    assert worst < 0.5
