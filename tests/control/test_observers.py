"""Disturbance observers (15), (30) against closed-form expectations."""

import math

import numpy as np
import pytest

from companion.control import vector as vec
from companion.control.observers import ForceObserver, MatchingFilter, torque_observer_init, torque_observer_step
from companion.control.vector import lowpass_alpha
from companion.control.params import VehicleParams

J = VehicleParams().inertia_kg_m2


def test_matching_filter_is_a_delay_followed_by_equal_first_order_lags():
    """A unit step through 30 ms of delay and two 5 Hz lags, at 100 Hz: nothing for 3 steps, then
    the step response of two equal exact-discretised poles, 1 - (1 + n a) (1 - a)^n."""
    f = MatchingFilter(delay_s=0.03, cutoff_hz=5.0, order=2)
    out = [f.update((0.0, 0.0, 0.0), 0.01)]
    out += [f.update((1.0, 0.0, 0.0), 0.01)[0] for _ in range(40)]
    assert out[1:4] == [0.0, 0.0, 0.0]
    a = 1.0 - math.exp(-2.0 * math.pi * 5.0 * 0.01)
    for n in range(1, 37):
        expected = 1.0 - (1.0 + n * a) * (1.0 - a) ** n
        assert out[3 + n] == pytest.approx(expected, abs=1e-12), n


def test_matched_force_observer_sees_no_disturbance_where_the_unmatched_one_sees_the_delay():
    """Nominal model, no disturbance: the acceleration arrives through the matching filter's own
    delay and lags. Subtracting the force through the same filter, the estimate stays at zero;
    subtracting the present force, a 1 N/s force ramp reads as ramp x delay: 0.03 s plus, per
    exact-discretised lag, dt (1 - a) / a (1 / omega - dt / 2 for small dt)."""
    chain = MatchingFilter(delay_s=0.03, cutoff_hz=5.0)
    matched = ForceObserver(1.0, (7.0, 7.0, 7.0), matching=MatchingFilter(delay_s=0.03, cutoff_hz=5.0))
    plain = ForceObserver(1.0, (7.0, 7.0, 7.0))
    dt = 0.01
    for k in range(300):
        f = (k * dt * 1.0, 0.0, 0.0)  # 1 N/s ramp on a 1 kg mass
        acc = chain.update(f, dt)  # measured r_dd (the specific force here: no gravity in x)
        e_m = matched.update(acc, f, dt)
        e_p = plain.update(acc, f, dt)
    a = 1.0 - math.exp(-2.0 * math.pi * 5.0 * dt)
    assert abs(e_m[0]) < 1e-9
    assert e_p[0] == pytest.approx(-(0.03 + 2.0 * dt * (1.0 - a) / a), rel=0.01)


def test_torque_observer_sees_nothing_in_torque_free_tumbling():
    """Euler's equations without torque, J w' = -w x J w, integrated finely: the measurement of
    (15), J0 w' - tau + w x J0 w, is zero but for the integration error. A Coriolis term of the
    wrong sign would read 2 w x J w (about 4e-3 N m here)."""
    obs = torque_observer_init()
    w = (3.0, 0.5, 2.0)
    dt, sub_steps = 0.001, 50
    alpha = (lowpass_alpha(8.0, dt),) * 3
    worst = 0.0
    for _ in range(500):
        for _ in range(sub_steps):
            h = dt / sub_steps
            w = vec.add(w, vec.scale(h, vec.div(vec.neg(vec.cross(w, vec.mul(J, w))), J)))
        obs = torque_observer_step(obs, J, alpha, w, (0.0, 0.0, 0.0), dt, (0.0, 0.0, 0.0))
        est = obs.estimate_nm
        worst = max(worst, float(np.linalg.norm(est)))
    coriolis = float(np.linalg.norm(vec.cross(w, vec.mul(J, w))))
    assert coriolis > 1e-3
    assert worst < 0.05 * coriolis
