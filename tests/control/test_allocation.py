"""Allocation (4) in FRD: the signs are proven from geometry, then by flying the plant."""

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from companion.control import quaternion as quat
from companion.control.allocation import (
    allocate,
    rotor_speeds_sq_for,
    wrench_from_rotor_speeds_sq,
)
from companion.control.params import VehicleParams
from sitl.plant.airframe import AirframeParams
from sitl.plant.dynamics import Plant

V = VehicleParams()
# rotor positions (FRD), numbered counter-clockwise seen from above starting at +x:
# front, left, back, right; spin seen from above: 1, 3 clockwise (+z_B), 2, 4 counter-clockwise
POSITIONS = np.array([[1, 0, 0], [0, -1, 0], [-1, 0, 0], [0, 1, 0]], dtype=float) * V.arm_length_m
SPIN_AXIS_Z = np.array([+1, -1, +1, -1], dtype=float)


# the "x" layout: rotor 1 front-left, 2 back-left, 3 back-right, 4 front-right (PX4's and
# ArduPilot's quad X motors 3, 2, 4, 1), same spins
X = VehicleParams(layout="x")
X_POSITIONS = np.array([[1, -1, 0], [-1, -1, 0], [-1, 1, 0], [1, 1, 0]], dtype=float) * X.arm_length_m / math.sqrt(2)


def geometric_wrench(w_sq, positions=POSITIONS):
    """Sum of r_i x F_i plus rotor reaction torques, written out from first principles."""
    torque = np.zeros(3)
    thrust = 0.0
    for i in range(4):
        f = V.k_thrust_n_s2 * w_sq[i]
        torque += np.cross(positions[i], [0.0, 0.0, -f])  # thrust along -z_B
        torque[2] += -SPIN_AXIS_Z[i] * V.k_torque_nm_s2 * w_sq[i]  # reaction opposes spin
        thrust += f
    return torque, thrust


speeds_sq = st.tuples(*[st.floats(1e4, 8e5)] * 4)


@given(speeds_sq)
def test_wrench_matches_geometry(w_sq):
    torque, thrust = wrench_from_rotor_speeds_sq(w_sq, V)
    g_torque, g_thrust = geometric_wrench(w_sq)
    np.testing.assert_allclose(torque, g_torque, rtol=1e-12, atol=1e-15)
    assert math.isclose(thrust, g_thrust, rel_tol=1e-12)


@given(speeds_sq)
def test_the_x_layout_matches_its_geometry(w_sq):
    torque, thrust = wrench_from_rotor_speeds_sq(w_sq, X)
    g_torque, g_thrust = geometric_wrench(w_sq, X_POSITIONS)
    np.testing.assert_allclose(torque, g_torque, rtol=1e-12, atol=1e-15)
    assert math.isclose(thrust, g_thrust, rel_tol=1e-12)


def test_the_front_right_rotor_of_an_x_rolls_left_and_pitches_up():
    (tx, ty, _), _ = wrench_from_rotor_speeds_sq((0.0, 0.0, 0.0, 1e5), X)
    assert tx < 0 < ty and math.isclose(-tx, ty)


@given(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-0.05, 0.05), st.floats(2.0, 15.0),
       st.sampled_from([V, X]))
def test_inverse_is_exact(tx, ty, tz, thrust, vehicle):
    w_sq = rotor_speeds_sq_for((tx, ty, tz), thrust, vehicle)
    torque, t = wrench_from_rotor_speeds_sq(w_sq, vehicle)
    np.testing.assert_allclose(torque, (tx, ty, tz), atol=1e-12)
    assert math.isclose(t, thrust, rel_tol=1e-12)


def test_saturation_reports_the_applied_wrench_not_the_request():
    request = (2.0, 0.0, 0.0)  # far more roll torque than the rotors can give
    clipped, torque, thrust = allocate(request, 6.0, V)
    assert all(V.rotor_speed_min_rad_s**2 - 1e-6 <= w <= V.rotor_speed_max_rad_s**2 + 1e-6 for w in clipped)
    assert 0.0 < torque[0] < request[0]
    t_check, thrust_check = wrench_from_rotor_speeds_sq(clipped, V)
    np.testing.assert_allclose(torque, t_check)
    assert thrust == thrust_check


def fly_open_loop(torque, seconds=0.3):
    """Hover thrust plus a torque, no controller, no drag: which way does the vehicle turn?"""
    af = AirframeParams(drag_linear_n_s_m=(0, 0, 0), drag_quadratic_n_s2_m2=0.0, rotor_time_constant_s=1e-4)
    plant = Plant.at_rest(V, af, (0.0, 0.0, -5.0))
    w_sq = rotor_speeds_sq_for(torque, V.weight_n, V)
    cmd = tuple(math.sqrt(w) for w in w_sq)
    for _ in range(int(seconds / 0.001)):
        plant.step(cmd, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.001)
    return plant.state


def expected_angle(torque, axis, seconds=0.3):
    """Constant torque from rest: angle = 1/2 (tau / J) t^2 (small angle, no gyroscopic term)."""
    return 0.5 * torque / V.inertia_kg_m2[axis] * seconds**2


def test_positive_roll_torque_rolls_right():
    """GIVEN hover WHEN tau_x > 0 THEN roll > 0: the right (+y) arm goes down (NED +z)."""
    s = fly_open_loop((0.002, 0.0, 0.0))
    roll, pitch, yaw = quat.to_euler(s.q)
    assert math.isclose(roll, expected_angle(0.002, 0), rel_tol=0.01)
    assert abs(pitch) < 1e-9 and abs(yaw) < 1e-9
    right_arm = quat.rotate(s.q, (0.0, 1.0, 0.0))
    assert right_arm[2] > 0.02
    assert s.vel_ned_m_s[1] > 0.0  # thrust tilted to the right pushes east


def test_positive_pitch_torque_raises_the_nose():
    s = fly_open_loop((0.0, 0.002, 0.0))
    roll, pitch, yaw = quat.to_euler(s.q)
    assert math.isclose(pitch, expected_angle(0.002, 1), rel_tol=0.01)
    assert abs(roll) < 1e-9
    nose = quat.rotate(s.q, (1.0, 0.0, 0.0))
    assert nose[2] < -0.02  # up is -z in NED
    assert s.vel_ned_m_s[0] < 0.0  # thrust tilted backwards


def test_positive_yaw_torque_turns_clockwise_seen_from_above():
    s = fly_open_loop((0.0, 0.0, 0.001))
    roll, pitch, yaw = quat.to_euler(s.q)
    assert math.isclose(yaw, expected_angle(0.001, 2), rel_tol=0.01)
    assert abs(roll) < 1e-9 and abs(pitch) < 1e-9
    nose = quat.rotate(s.q, (1.0, 0.0, 0.0))
    assert nose[1] > 0.0  # the nose swings east from north
