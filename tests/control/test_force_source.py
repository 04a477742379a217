"""The force observer's force input (30): the paper's commanded force or the measured thrust.

A point mass whose inner loop delivers every commanded attitude with a constant 2 deg tilt error
(a PD attitude loop under a constant torque, say) and no external force. Subtracting the
*commanded* force, the observer sees that error as a disturbance ``m g tan(2 deg)`` and PD+DO
removes it; subtracting the thrust along the *measured* attitude, it sees the true external
force (zero) and the PD loop holds the offset ``g tan(2 deg) / K_p``.
"""

import math

import numpy as np
import pytest

from companion.control import quaternion as quat
from companion.control.outer_loop import PositionLoop, PositionMeasurement, observer_force, thrust_force
from companion.control.params import PositionGains, VehicleParams
from companion.control.trajectory import PositionReference

G = 9.81
TILT_ERROR_RAD = math.radians(2.0)
BIAS = quat.from_axis_angle((0.0, 1.0, 0.0), TILT_ERROR_RAD)  # nose up: thrust tilts towards -x


def fly(force_source, seconds=25.0, dt=0.01, kind="pd_do"):
    vehicle = VehicleParams()
    loop = PositionLoop.create(kind, vehicle, PositionGains(force_source=force_source))
    m = vehicle.mass_kg
    pos, vel = (0.0, 0.0, -1.0), (0.0, 0.0, 0.0)
    q_actual, thrust = quat.IDENTITY, vehicle.weight_n
    loop.thrust_n = thrust
    ref = PositionReference((0.0, 0.0, -1.0))
    for _ in range(int(seconds / dt)):
        f = thrust_force(thrust, q_actual)
        sf = (f[0] / m, f[1] / m, f[2] / m)
        sp = loop.update(PositionMeasurement(pos, vel, q_actual, sf), ref, dt)
        acc = (sf[0], sf[1], sf[2] + G)
        vel = tuple(v + a * dt for v, a in zip(vel, acc))
        pos = tuple(p + v * dt for p, v in zip(pos, vel))
        q_actual, thrust = quat.mul(sp.q_d, BIAS), sp.thrust_n
    return np.array(pos), loop.controller.estimate_n


def test_commanded_force_absorbs_the_inner_loop_error_and_pd_do_removes_it():
    pos, est = fly("commanded")
    assert abs(pos[0]) < 0.005
    # the estimate holds the missing horizontal thrust, m g tan(2 deg) = 0.216 N
    assert est[0] == pytest.approx(-0.63 * G * math.tan(TILT_ERROR_RAD), rel=0.05)


def test_measured_force_estimates_the_true_external_force_and_leaves_the_offset():
    pos, est = fly("measured")
    k_p = 1.5**2
    assert abs(est[0]) < 0.01  # no external force acts
    # PD alone against the tilt error: K_p x = g tan(2 deg) (the sign: thrust leans to -x)
    assert pos[0] == pytest.approx(-G * math.tan(TILT_ERROR_RAD) / k_p, rel=0.1)


def test_observer_force_falls_back_to_the_measured_attitude_before_any_command():
    q = quat.from_axis_angle((1.0, 0.0, 0.0), 0.3)
    np.testing.assert_allclose(observer_force("commanded", 6.0, q, None), thrust_force(6.0, q))
    np.testing.assert_allclose(observer_force("measured", 6.0, q, quat.IDENTITY), thrust_force(6.0, q))
    np.testing.assert_allclose(observer_force("commanded", 6.0, q, quat.IDENTITY), (0.0, 0.0, -6.0), atol=1e-12)


def test_an_unknown_force_source_fails_when_the_gains_are_built():
    with pytest.raises(ValueError, match="force_source"):
        PositionGains(force_source="commnded")
