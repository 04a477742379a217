"""Reference generation (32)-(34) and the waypoint filter."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from companion.control import quaternion as quat
from companion.control import vector as vec
from companion.control.params import ReferenceParams, TrajectoryParams
from companion.control.reference import RateReference, attitude_from_force, limit_force, thrust_quaternion
from companion.control.trajectory import ReferenceFilter

comp = st.floats(-20.0, 20.0, allow_nan=False)


@given(comp, comp, st.floats(-20.0, -0.01))
def test_thrust_quaternion_turns_hover_thrust_onto_the_force(fx, fy, fz):
    f = (fx, fy, fz)
    q = thrust_quaternion(f)
    thrust_dir = quat.rotate(q, (0.0, 0.0, -1.0))
    np.testing.assert_allclose(thrust_dir, vec.scale(1 / vec.norm(f), f), atol=1e-9)
    assert abs(quat.norm(q) - 1) < 1e-12


@given(comp, comp, st.floats(-20.0, -0.01), st.floats(-math.pi, math.pi))
def test_yaw_is_the_angle_about_inertial_z(fx, fy, fz, yaw):
    q, thrust = attitude_from_force((fx, fy, fz), yaw)
    assert math.isclose(thrust, vec.norm((fx, fy, fz)))
    np.testing.assert_allclose(quat.rotate(q, (0, 0, -1.0)), vec.scale(1 / thrust, (fx, fy, fz)), atol=1e-9)
    # the body x axis, projected to the horizontal plane through q_f, points along yaw:
    # undoing the tilt q_f leaves exactly q_psi
    q_f = thrust_quaternion((fx, fy, fz))
    q_psi = quat.mul(quat.conj(q_f), q)
    assert quat.angle_between(q_psi, quat.from_yaw(yaw)) < 1e-9


def test_straight_down_and_zero_force_are_made_safe():
    """f = +e3 (thrust towards the ground) makes (32) singular: the limit keeps a minimum
    upward component, so the attitude is level and the thrust the minimum, never NaN."""
    for f in [(0.0, 0.0, 5.0), (0.0, 0.0, 0.0), (1e-12, 0.0, 3.0)]:
        limited = limit_force(f, min_up_n=0.6, tilt_max_rad=math.radians(70))
        q, thrust = attitude_from_force(limited, 0.0)
        assert all(math.isfinite(c) for c in q)
        assert math.isclose(thrust, 0.6, rel_tol=1e-6)
        assert quat.tilt_angle(q) < 1e-6


@given(comp, comp, st.floats(-20.0, 20.0))
def test_force_limit_respects_tilt_and_keeps_direction(fx, fy, fz):
    tilt_max = math.radians(50)
    f = limit_force((fx, fy, fz), 0.5, tilt_max)
    q, _ = attitude_from_force(f, 0.0)
    assert quat.tilt_angle(q) <= tilt_max + 1e-9
    assert -f[2] >= 0.5 - 1e-12
    if math.hypot(fx, fy) > 1e-9:
        # horizontal direction is kept
        assert fx * f[1] - fy * f[0] == pytest.approx(0.0, abs=1e-9 * (abs(fx) + abs(fy) + 1))


def test_rate_reference_recovers_a_constant_rotation():
    """(34) on a reference turning at a constant body rate returns that rate (after the filter)."""
    rr = RateReference(ReferenceParams())
    w = (0.3, -0.5, 1.2)
    q = quat.IDENTITY
    for _ in range(100):
        q = quat.integrate(q, w, 0.01)
        out = rr.update(q, 0.01)
    np.testing.assert_allclose(out, w, atol=1e-9)


def test_rate_reference_never_exceeds_the_limit():
    rr = RateReference(ReferenceParams(rate_filter_time_constant_s=0.0))
    limit = math.radians(250)
    rr.update(quat.IDENTITY, 0.01)
    out = rr.update(quat.from_axis_angle((1.0, 0.0, 0.0), math.radians(170)), 0.01)
    assert math.isclose(vec.norm(out), limit, rel_tol=1e-12)
    assert out[0] > 0  # direction kept


def test_reference_filter_respects_speed_and_acceleration_limits():
    p = TrajectoryParams(max_speed_m_s=2.0, max_accel_m_s2=8.0)
    rf = ReferenceFilter(p, (0.0, 0.0, -1.0))
    speeds, accels = [], []
    for _ in range(1000):
        r = rf.update((10.0, 5.0, -3.0), math.radians(90), 0.01)
        speeds.append(vec.norm(r.vel_ned_m_s))
        accels.append(vec.norm(r.accel_ned_m_s2))
    assert max(speeds) <= 2.0 + 1e-9
    assert max(accels) <= 8.0 + 1e-9
    np.testing.assert_allclose(r.pos_ned_m, (10.0, 5.0, -3.0), atol=1e-3)
    assert math.isclose(r.yaw_rad, math.radians(90), abs_tol=1e-6)


def test_rate_reference_gives_the_angular_acceleration_of_a_speeding_rotation():
    """A reference about a fixed axis with angle 1/2 alpha t^2: omega_d' = alpha (unfiltered it is
    exact up to the one-step backward difference of (34), so within 1e-6 after the first steps)."""
    rr = RateReference(ReferenceParams(rate_filter_time_constant_s=0.0))
    alpha, dt, axis = 3.0, 0.01, (0.6, 0.0, 0.8)
    for k in range(50):
        rr.update(quat.from_axis_angle(axis, 0.5 * alpha * (k * dt) ** 2), dt)
    np.testing.assert_allclose(rr.omega_d_dot, vec.scale(alpha, axis), atol=1e-6)


def test_attitude_reference_and_rate_command_are_one_motion_within_the_limit():
    """A 120 deg jump of q_d: the attitude sent moves towards it no faster than the limit, and
    omega_d is exactly its motion (q_ref,k = q_ref,k-1 exp(omega_d t_s)), so an attitude loop
    that tracks both is never asked to turn faster than the limit (``filter_attitude``)."""
    rr = RateReference(ReferenceParams(filter_attitude=True))
    dt, limit = 0.01, math.radians(250)
    rr.update(quat.IDENTITY, dt)
    target = quat.from_axis_angle((0.0, 0.6, 0.8), math.radians(120))
    prev = rr.q_ref
    for _ in range(200):
        w = rr.update(target, dt)
        assert vec.norm(w) <= limit + 1e-9
        assert quat.angle_between(quat.mul(prev, quat.exp(vec.scale(dt, w))), rr.q_ref) < 1e-12
        prev = rr.q_ref
    assert quat.angle_between(rr.q_ref, target) < 1e-6


def test_reference_filter_keeps_its_jerk_limit_when_the_speed_saturates():
    """Reaching the speed limit, the acceleration is brought to zero at the jerk limit instead of
    being cut in one step (which jumped the attitude reference by 33 deg in E4)."""
    p = TrajectoryParams(max_speed_m_s=2.0, max_accel_m_s2=6.0, max_jerk_m_s3=20.0, bandwidth_rad_s=3.0)
    rf = ReferenceFilter(p, (0.0, 0.0, -1.5))
    dt = 0.01
    a_prev = (0.0, 0.0, 0.0)
    worst = 0.0
    for _ in range(600):
        r = rf.update((4.0, 0.0, -1.5), 0.0, dt)
        worst = max(worst, vec.norm(vec.sub(r.accel_ned_m_s2, a_prev)) / dt)
        a_prev = r.accel_ned_m_s2
        assert vec.norm(r.vel_ned_m_s) <= 2.0 + 1e-9
    assert worst <= 20.0 * 1.05


def _highest_and_last(p: TrajectoryParams, start_ned_m: tuple, legs: list[tuple[tuple, float]],
                      dt: float) -> tuple[float, tuple]:
    """The filter from ``start_ned_m`` through ``legs`` (target, seconds), stepped every ``dt``: the
    highest point its reference reached (smallest z, NED) and where it ended."""
    f = ReferenceFilter(p, start_ned_m)
    top = start_ned_m[2]
    for target, seconds in legs:
        for _ in range(round(seconds / dt)):
            top = min(top, f.update(target, 0.0, dt).pos_ned_m[2])
    return top, f.pos_ned_m


def test_reference_filter_stepped_at_10_hz_does_not_creep_out_of_a_ceiling():
    """At 10 Hz with a 5 rad/s bandwidth (w dt = 0.5) one step at a time, the speed limit made the
    vertical velocity limit-cycle on a horizontal leg and the reference crept 3 cm up from 1.0 m
    (hypothesis found a mission at its 1.0 m ceiling flying out of it, tests/fuzz). Now the filter
    integrates in 20 ms sub-steps: from 1.0 m up towards (0, 4, -0.5) at 0.1 m/s it never rises
    above where it started, and lands on what 100 Hz gives within 5 mm."""
    p = TrajectoryParams(max_speed_m_s=0.1, max_accel_m_s2=5.0, max_jerk_m_s3=25.0, bandwidth_rad_s=5.0)
    legs = [((0.0, 0.0, -0.5), 0.1), ((0.0, 4.0, -0.5), 10.0)]  # the fuzzed mission's 0.1 s hold at 0.5 m first
    top, at_10hz = _highest_and_last(p, (0.0, 0.0, -1.0), legs, 0.1)
    _, at_100hz = _highest_and_last(p, (0.0, 0.0, -1.0), legs, 0.01)
    assert top >= -1.0 - 1e-9, top
    assert np.allclose(at_10hz, at_100hz, atol=0.005), (at_10hz, at_100hz)


def test_reference_filter_with_a_jerk_limit_high_for_its_speed_does_not_chatter_up_through_a_ceiling():
    """A 0.1 m/s limit with a 500 m/s^3 jerk limit: in 20 ms sub-steps one step's jerk could swing
    the velocity by 0.2 m/s, twice the limit, and on a 10 m horizontal leg from 0.69 m down to
    0.5 m the velocity chattered and the reference climbed to 1.06 m (hypothesis found it leaving a
    1.0 m ceiling, tests/fuzz). The sub-step now keeps ``j h^2 <= v_max / 2``: stepped at 10 Hz the
    reference never rises above where it started and arrives where a 1 kHz filter does."""
    p = TrajectoryParams(max_speed_m_s=0.1, max_accel_m_s2=20.0, max_jerk_m_s3=500.0, bandwidth_rad_s=2.0)
    legs = [((0.0, 10.0, -0.5), 120.0)]  # arrives after ~110 s
    top, at_10hz = _highest_and_last(p, (0.0, 0.0, -0.6875), legs, 0.1)
    _, at_1khz = _highest_and_last(p, (0.0, 0.0, -0.6875), legs, 0.001)
    assert top >= -0.6875 - 1e-6, top
    assert np.allclose(at_10hz, at_1khz, atol=0.005), (at_10hz, at_1khz)
