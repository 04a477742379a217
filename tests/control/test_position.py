"""Position controllers: equal local gains, AIBC stability, hover force, disturbance rejection."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from companion.control.params import PositionGains
from companion.control.position import POSITION_CONTROLLERS, PositionController, aibc_coefficients
from helpers.point_mass import point_mass

G = 9.81


@given(st.floats(1.07, 5.0))
def test_aibc_coefficients_give_the_pid_polynomial(w):
    c1, c2, lam = aibc_coefficients(w)
    assert c1 > 0 and c2 > 0 and lam > 0
    np.testing.assert_allclose([c1 + c2, 1 + lam + c1 * c2, c2 * lam], [2 * w, w * w, w / 4], rtol=1e-9)


def test_derived_aibc_is_stable_and_the_literal_printed_law_is_not():
    """Closed loop x''' of the derived law: s^3 + (c1+c2) s^2 + (1+lam+c1 c2) s + c2 lam (+ gamma s^2
    from h = gamma v~). The printed law's characteristic polynomial, taking e' as the velocity
    error, is s^3 + (c1+c2) s^2 + (1-c1^2+lam) s - c1 lam: its constant term is negative, so
    it has a positive real root for any positive c1, lam (SPEC section 3)."""
    c1, c2, lam = aibc_coefficients(1.5)
    for gamma in (0.0, 4.0, 8.0):
        derived = np.roots([1, c1 + c2 + gamma, 1 + lam + c1 * c2, c2 * lam])
        assert np.all(derived.real < 0), gamma
    literal = np.roots([1, c1 + c2, 1 - c1 * c1 + lam, -c1 * lam])
    assert np.any(literal.real > 0)


@pytest.mark.parametrize("kind", POSITION_CONTROLLERS)
def test_hover_force_is_the_weight_upwards(kind):
    ctrl = PositionController(kind, PositionGains(), 0.63)
    hover = (0.0, 0.0, -0.63 * G)
    sf = (0.0, 0.0, -G)  # accelerometer at hover
    f = ctrl.update((0, 0, 0), (0, 0, 0), (0, 0, 0), sf, hover, 0.01)
    np.testing.assert_allclose(f, hover, atol=1e-12)


DEFAULT_GAINS = PositionGains()


def test_force_observer_converges_to_the_disturbance_and_removes_the_error():
    """PD+DO: h_hat' = Gamma (h - h_hat) so after 10 s (30 time constants) h_hat = h and the PD
    loop has nothing left to push against: error < 1 mm."""
    xs, ctrl = point_mass("pd_do", 2.0)
    assert math.isclose(ctrl.estimate_n[0], 2.0, rel_tol=1e-3)
    assert abs(xs[-1]) < 1e-3


def test_pid_integral_removes_the_error_slowly():
    """PID's slowest pole for w = 1.5 is ~0.14 rad/s, so after 19 s some error remains but it
    shrinks."""
    xs, _ = point_mass("pid", 2.0)
    assert abs(xs[-1]) < abs(xs[int(8 / 0.01)])


def test_aibc_estimate_converges_to_the_force_and_the_literal_one_stalls_at_zero():
    """The gain-matched AIBC's velocity-error observer (bandwidth gamma = 4) converges to the 2 N
    like any observer of a constant; read literally as h = gamma v~ the estimate is zero at rest
    and attributes nothing to the disturbance (the paper's Fig. 10 observation), leaving the
    slow integral to remove the error."""
    _, ctrl = point_mass("aibc", 2.0, seconds=20.0)
    assert ctrl.estimate_n[0] == pytest.approx(2.0, rel=1e-3)
    literal = dataclasses.replace(DEFAULT_GAINS, aibc_estimate="velocity_feedback")
    xs, ctrl = point_mass("aibc", 2.0, seconds=60.0, gains=literal)
    assert abs(ctrl.estimate_n[0]) < 0.01
    assert abs(xs[-1]) < 0.05  # the integral term gets there in the end


def test_aibc_with_its_observer_keeps_the_pid_poles_whatever_gamma():
    """Without a disturbance the observer's estimate is identically zero, so the AIBC loop is the
    PID's for any gamma (with the literal h = gamma v~ the velocity gain would become 3 + gamma)."""
    w = 1.5
    expected = reference_loop(w * w, 2 * w, w / 4, force_n=0.0, x0=0.3)
    for gamma in (2.0, 8.0):
        g = dataclasses.replace(DEFAULT_GAINS, aibc_gamma_per_s=(gamma, gamma, gamma))
        ctrl = PositionController("aibc", g, 0.63)
        x, v, xs = 0.3, 0.0, []
        applied = (0.0, 0.0, -0.63 * G)
        for _ in range(1200):
            f = ctrl.update((x, 0.0, 0.0), (v, 0.0, 0.0), (0, 0, 0), (0.0, 0.0, -G), applied, 0.01)
            applied = f
            v += f[0] / 0.63 * 0.01
            x += v * 0.01
            xs.append(x)
        np.testing.assert_allclose(xs, expected, atol=1e-9)


def test_ism_do_has_a_smaller_peak_error_than_pd_do():
    peak_pd = np.max(np.abs(point_mass("pd_do", 2.0)[0]))
    peak_ism = np.max(np.abs(point_mass("ism_do", 2.0)[0]))
    assert peak_ism < 0.9 * peak_pd


FIG6_GAINS = dataclasses.replace(DEFAULT_GAINS, omega_c_rad_s=(1.5,) * 3, sliding_gain_rad_s=(1.5,) * 3,
                                 boundary_layer_m_s=(1.0,) * 3, observer_gain_rad_s=(5.0, 3.0, 1.5))
"""the paper's Fig. 6 (E1): omega_c,x = 1.5 rad/s, K_sf,x = 1.5 m0 with eps = 1, Gamma_f,x = 5"""


def test_fig6_law_on_an_ideal_point_mass_peaks_at_106_mm_and_is_back_within_5_cm_at_1_15_s():
    """What (29)-(31) give with Fig. 6's parameters on a 0.5 kg point mass with an ideal actuator
    and noiseless acceleration, stepped at 1 kHz: the floor of E1's figures. ISM+DO peaks at 0.106 m
    and is back within 5 cm 1.15 s after the onset, PD+DO peaks at 0.185 m. E1's target "into 5 cm
    in <= 1.05 s" (issue 14) is faster than the law itself (docs/experiments.md, E1)."""
    dt = 0.001
    for kind, peak, settle in (("ism_do", 0.106, 1.15), ("pd_do", 0.185, 2.66)):
        xs, _ = point_mass(kind, 2.0, seconds=8.0, dt=dt, gains=FIG6_GAINS, m=0.5)
        t = np.arange(len(xs)) * dt
        err = np.abs(xs[t >= 1.0])
        last_out = np.nonzero(err > 0.05)[0][-1]
        assert err.max() == pytest.approx(peak, abs=0.002), kind
        assert (last_out + 1) * dt == pytest.approx(settle, abs=0.02), kind


def linear_loop(kind, seconds=12.0, dt=0.01, gains=DEFAULT_GAINS, m=0.63, force_n=0.3):
    """x of a point mass under ``kind`` (observer off: Gamma_f ~ 0) after a 0.3 N step force at
    t = 0, integrated with semi-implicit Euler steps; and the largest |s_p| on the way."""
    g = dataclasses.replace(gains, observer_gain_rad_s=(1e-12, 1e-12, 1e-12))
    ctrl = PositionController(kind, g, m)
    x = v = s_max = 0.0
    xs = []
    for _ in range(int(seconds / dt)):
        f = ctrl.update((x, 0.0, 0.0), (v, 0.0, 0.0), (0, 0, 0), (0.0, 0.0, -G), (0.0, 0.0, -m * G), dt)
        s_max = max(s_max, abs(ctrl.s[0]))
        v += (f[0] + force_n) / m * dt
        x += v * dt
        xs.append(x)
    return np.array(xs), s_max


def reference_loop(k_p, k_v, k_i, seconds=12.0, dt=0.01, m=0.63, force_n=0.3, x0=0.0):
    """The PID-form closed loop m x'' = -m (k_v x' + k_p x + k_i int x) + h, same integration."""
    x, v, xi = x0, 0.0, 0.0
    xs = []
    for _ in range(int(seconds / dt)):
        xi += x * dt
        a = -(k_v * v + k_p * x + k_i * xi) + force_n / m
        v += a * dt
        x += v * dt
        xs.append(x)
    return np.array(xs)


def test_aibc_closed_loop_has_the_pid_poles():
    """Section V: the AIBC is tuned to the PID's local closed-loop gains K_v = 2 w, K_p = w^2,
    K_i = w / 4. On a point mass (gamma = 0: no estimate) its response to a step force is the
    PID's, step for step."""
    w = 1.5
    pid = reference_loop(w * w, 2 * w, w / 4)
    np.testing.assert_allclose(linear_loop("pid")[0], pid, atol=1e-9)
    g = dataclasses.replace(DEFAULT_GAINS, aibc_gamma_per_s=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(linear_loop("aibc", gains=g)[0], pid, atol=1e-6)


def test_ism_do_closed_loop_is_the_pid_inside_the_layer():
    """Inside the boundary layer f1 = -m0 k_s s_p with s_p = v~ + K_v r~ + int K_p r~ (31): with
    the observer off, x'' = -(K_v + k_s) x' - (K_p + k_s K_v) x - k_s K_p int x + h/m. (0.3 N:
    s_p settles at h / (m0 k_s) = 0.32 m/s, inside the 1 m/s layer.)"""
    w, k_s = 1.5, DEFAULT_GAINS.sliding_gain_rad_s[0]
    expected = reference_loop(w * w + k_s * 2 * w, 2 * w + k_s, k_s * w * w)
    got, s_max = linear_loop("ism_do")
    assert s_max < DEFAULT_GAINS.boundary_layer_m_s[0]
    # the integral is updated after s_p is formed (the reference: before), a one-step shift
    assert np.max(np.abs(got - expected)) < 0.01 * np.max(np.abs(expected))


def test_each_family_builds_a_record_of_its_own_and_its_type_picks_the_step():
    """PD+DO, ISM+DO and INDI share DoConst (observer order 1, 1, 2; the sliding term for ISM+DO
    only); PID and AIBC have records of their own, and no record carries another family's fields."""
    from companion.control import position as P

    consts = {k: P.position_const(k, PositionGains(), 0.63, G, 0.01) for k in POSITION_CONTROLLERS}
    assert {k: type(c) for k, c in consts.items()} == {
        "pid": P.PidConst, "aibc": P.AibcConst, "pd_do": P.DoConst, "ism_do": P.DoConst, "indi": P.DoConst}
    assert [(consts[k].observer.order, consts[k].sliding) for k in ("pd_do", "ism_do", "indi")] == [
        (1, False), (1, True), (2, False)]
    assert "observer" not in P.PidConst._fields and "k_i" not in P.DoConst._fields
    st0 = P.position_init()
    args = ((0.1, -0.2, 0.3), (0.0, 0.1, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, -G), True, (0.0, 0.0, -0.63 * G))
    for c in consts.values():
        assert P.position_step(c, st0, *args) == P.STEPS[type(c)](c, st0, *args)

