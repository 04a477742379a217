"""Quaternion algebra: properties that must hold for every unit quaternion (hypothesis)."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from companion.control import quaternion as quat
from companion.control import vector as vec

finite = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = st.tuples(finite, finite, finite, finite).filter(lambda q: sum(c * c for c in q) > 1e-3).map(
    quat.normalize
)
rotation_vectors = st.tuples(finite, finite, finite).map(lambda v: vec.scale(3.0, v)).filter(
    lambda v: vec.norm(v) < math.pi - 1e-6
)
vectors = st.tuples(finite, finite, finite)


def mat(m):
    return np.array(m, dtype=float)


@given(quaternions, quaternions)
def test_product_of_unit_quaternions_stays_unit(a, b):
    assert abs(quat.norm(quat.mul(a, b)) - 1.0) < 1e-12


@given(quaternions, quaternions)
def test_rotation_matrix_of_product_is_product_of_matrices(a, b):
    lhs = mat(quat.to_rotmat(quat.mul(a, b)))
    rhs = mat(quat.to_rotmat(a)) @ mat(quat.to_rotmat(b))
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)


@given(quaternions)
def test_q_and_minus_q_give_the_same_rotation(q):
    neg = tuple(-c for c in q)
    np.testing.assert_allclose(mat(quat.to_rotmat(q)), mat(quat.to_rotmat(neg)), atol=1e-15)


@given(quaternions)
def test_rotation_matrix_is_orthonormal_with_det_one(q):
    r = mat(quat.to_rotmat(q))
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert abs(np.linalg.det(r) - 1.0) < 1e-12


@given(rotation_vectors)
def test_log_inverts_exp(v):
    np.testing.assert_allclose(quat.log(quat.exp(v)), v, atol=1e-9)


@given(quaternions)
def test_exp_inverts_log_up_to_sign(q):
    back = quat.exp(quat.log(q))
    assert abs(abs(sum(a * b for a, b in zip(back, q))) - 1.0) < 1e-9


@given(quaternions, vectors)
def test_rotate_matches_matrix_and_inverse_undoes_it(q, v):
    r = mat(quat.to_rotmat(q))
    np.testing.assert_allclose(quat.rotate(q, v), r @ np.array(v), atol=1e-12)
    np.testing.assert_allclose(quat.rotate_inverse(q, quat.rotate(q, v)), v, atol=1e-12)


@given(vectors, vectors)
def test_vee_inverts_skew_and_skew_is_cross(a, b):
    np.testing.assert_allclose(vec.vee(vec.skew(a)), a, atol=0)
    np.testing.assert_allclose(vec.matvec(vec.skew(a), b), vec.cross(a, b), atol=1e-15)


@given(quaternions)
def test_rotmat_round_trip(q):
    back = quat.from_rotmat(quat.to_rotmat(q))
    assert abs(abs(sum(a * b for a, b in zip(back, q))) - 1.0) < 1e-9


@settings(max_examples=50)
@given(quaternions, vectors)
def test_integration_stays_unit_and_matches_exp_for_constant_rate(q, w):
    q1 = q
    for _ in range(1000):
        q1 = quat.integrate(q1, w, 0.001)
    assert abs(quat.norm(q1) - 1.0) < 1e-12
    expected = quat.mul(q, quat.exp(w))  # 1 s at constant body rate w
    assert abs(abs(sum(a * b for a, b in zip(q1, expected))) - 1.0) < 1e-9


def test_scalar_first_hamilton_convention():
    # i * j = k in the Hamilton convention
    assert quat.mul((0, 1, 0, 0), (0, 0, 1, 0)) == (0, 0, 0, 1)
    # a +90 deg yaw about NED z (down) turns body x (forward) to east
    q = quat.from_yaw(math.pi / 2)
    np.testing.assert_allclose(quat.rotate(q, (1.0, 0.0, 0.0)), (0.0, 1.0, 0.0), atol=1e-15)


@given(st.floats(-3.0, 3.0), st.floats(-1.5, 1.5), st.floats(-3.0, 3.0))
def test_euler_round_trip(roll, pitch, yaw):
    back = quat.to_euler(quat.from_euler(roll, pitch, yaw))
    np.testing.assert_allclose(back, (roll, pitch, yaw), atol=1e-9)


def test_batch_components_give_the_same_numbers_as_floats():
    rng = np.random.default_rng(3)
    qs = rng.standard_normal((4, 50))
    qs /= np.linalg.norm(qs, axis=0)
    ws = rng.standard_normal((3, 50))
    batch = quat.integrate(tuple(qs), tuple(ws), 0.01)
    for i in range(50):
        one = quat.integrate(tuple(float(c) for c in qs[:, i]), tuple(float(c) for c in ws[:, i]), 0.01)
        np.testing.assert_allclose([c[i] for c in batch], one, rtol=0, atol=1e-15)


@given(quaternions, quaternions)
def test_relative_is_conjugate_product(a, b):
    np.testing.assert_allclose(quat.relative(a, b), quat.mul(quat.conj(a), b), atol=1e-15)
