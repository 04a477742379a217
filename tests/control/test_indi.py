"""INDI, the fifth controller (Smeur, Chu & de Croon 2016; Tal & Karaman 2018), on ideal models."""

import math

import numpy as np
import pytest

from companion.control import quaternion as quat
from companion.control import vector as vec
from companion.control.attitude import AttitudeController
from companion.control.observers import lowpass_step
from companion.control.params import AttitudeGains, VehicleParams
from helpers.point_mass import point_mass

J = VehicleParams().inertia_kg_m2
DT = 0.001
G = 9.81


def fly_attitude(kind, torque_nm=0.02, seconds=2.0, rotor_tc=0.02):
    """Rigid body (J = J0) whose rotors follow the requested torque through a first-order lag
    (INDI's actuator model, exactly), a step torque disturbance at 0.5 s. Returns the angle
    history, the true torque disturbance and the controller's measured lumped torque."""
    ctrl = AttitudeController(kind, AttitudeGains(), J)
    q, w, applied, act = quat.IDENTITY, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    a = 1.0 - math.exp(-DT / rotor_tc)
    angles, truth, seen = [], [], []
    for k in range(int(seconds / DT)):
        h = (torque_nm, 0.0, 0.0) if k >= 500 else (0.0, 0.0, 0.0)
        tau = ctrl.update(q, w, quat.IDENTITY, (0.0, 0.0, 0.0), applied, DT)
        applied = tau
        act = lowpass_step(act, tau, (a, a, a))
        acc = vec.div(vec.sub(vec.add(act, h), vec.cross(w, vec.mul(J, w))), J)
        w = vec.add(w, vec.scale(DT, acc))
        q = quat.integrate(q, w, DT)
        angles.append(quat.angle_between(q, quat.IDENTITY))
        truth.append(h[0])
        seen.append(ctrl.disturbance_estimate_nm[0])
    return np.array(angles), np.array(truth), np.array(seen)


def test_indi_measures_the_torque_through_its_second_order_filter():
    """With the actuator model right and no noise, J0 w' - A(tau) is the disturbance exactly
    (plus the gyroscopic torque, which the estimate adds back), so INDI's measured torque is the
    true step through two equal first-order stages at 50 rad/s, sample for sample."""
    _, truth, seen = fly_attitude("indi")
    a = 1.0 - math.exp(-50.0 * DT)
    s1 = s2 = 0.0
    expected = []
    for h in truth:
        s1 += a * (h - s1)
        s2 += a * (s1 - s2)
        expected.append(s2)
    # the measurement of step k sees the disturbance that acted over step k - 1
    np.testing.assert_allclose(seen[1:], np.array(expected)[:-1], atol=1e-12)


def test_indi_rejects_a_torque_step_faster_than_the_paper_observer():
    """INDI's 50 rad/s filter against PD+DO's Gamma_a = 8: a 0.02 N m step tilts the body less
    and is gone as fast (both to ~1e-6 rad by 1.5 s after the step)."""
    indi, _, _ = fly_attitude("indi")
    pd_do, _, _ = fly_attitude("pd_do")
    assert indi.max() < pd_do.max()
    assert indi[-1] < 1e-5 and pd_do[-1] < 1e-5


def test_indi_outer_loop_holds_position_against_a_force():
    """f = f_f + m0 (a_ref - a_f): the filtered force and acceleration cancel the 2 N, the error
    returns to zero (no integral needed) and the estimate is the force."""
    xs, ctrl = point_mass("indi", 2.0, seconds=15.0)
    assert abs(xs[-1]) < 1e-3
    assert ctrl.estimate_n[0] == pytest.approx(2.0, rel=1e-3)
    assert 0.0 < xs.max() < point_mass("pd_do", 2.0, seconds=15.0)[0].max() * 1.5
