"""The descent without position, on readings built by hand (no plant): the bias it learns, the speed
it integrates, the thrust it asks and when it counts itself down."""

from __future__ import annotations

import math

import pytest

from companion.control import quaternion as quat
from companion.control.vector import ZERO3
from sitl.autopilot.blind import (BLIND_DESCENT_M_S, BlindDescent, blind_start, blind_step, blind_thrust_n,
                                  counted_down, learn_bias)
from sitl.autopilot.sensed import Sensed
from sitl.plant.sensors import ImuSample, MocapSample

G = 9.81
DT = 1e-3


def reading(specific_force_z: float, q=quat.IDENTITY, vel_z: float = 0.0, height_m: float = 0.0) -> Sensed:
    tracked = MocapSample(0.0, (0.0, 0.0, -height_m), (0.0, 0.0, vel_z), ZERO3, q)
    return Sensed(0.0, tracked, q, ImuSample(ZERO3, (0.0, 0.0, specific_force_z)), 0.0, None)


@pytest.mark.parametrize("tilt_deg", [0.0, 20.0])
def test_the_bias_learnt_at_rest_is_the_accelerometers_offset_along_the_vertical(tilt_deg):
    """At rest the specific force is -g e3 in NED; an accelerometer reading 0.3 m/s^2 too much along
    its z axis reads 0.3 cos(tilt) too much vertically. After 10 time constants (20 s) the filter
    holds that to e^-10."""
    q = quat.from_euler(math.radians(tilt_deg), 0.0, 0.0)
    body = quat.rotate_inverse(q, (0.0, 0.0, -G))
    s = Sensed(0.0, MocapSample(0.0, ZERO3, ZERO3, ZERO3, q), q,
               ImuSample(ZERO3, (body[0], body[1], body[2] + 0.3)), 0.0, None)
    b = 0.0
    for _ in range(round(20.0 / DT)):
        b = learn_bias(b, s, G, DT)
    assert b == pytest.approx(0.3 * math.cos(math.radians(tilt_deg)), abs=0.3 * math.exp(-10) + 1e-9)


def test_the_descent_starts_from_the_tracked_speed_and_height_and_integrates_the_corrected_accelerometer():
    d = blind_start(reading(-G, vel_z=0.4, height_m=3.0), ground_z_m=0.0)
    assert d == BlindDescent(0.4, 3.0, 0.0)
    # the accelerometer reads 0.5 m/s^2 too much (a bias of 0.5 learnt): no acceleration, none integrated
    for _ in range(1000):
        d = blind_step(d, reading(-G + 0.5), 0.5, G, DT)
    assert d.vz_m_s == pytest.approx(0.4, abs=1e-9) and d.descended_m == pytest.approx(0.4, abs=1e-6)
    # with the bias unknown, it would believe its descent 0.5 m/s faster every second (NED: + down)
    d = blind_step(BlindDescent(0.4, 3.0, 0.0), reading(-G + 0.5), 0.0, G, 1.0)
    assert d.vz_m_s == pytest.approx(0.9)


def test_it_counts_itself_down_after_30_percent_and_half_a_metre_more_than_its_height():
    h = 3.0
    d = BlindDescent(BLIND_DESCENT_M_S, h, 0.0)
    steps = 0
    while not counted_down(d):
        d = blind_step(d, reading(-G), 0.0, G, DT)
        steps += 1
    assert steps * DT == pytest.approx((1.3 * h + 0.5) / BLIND_DESCENT_M_S, abs=2 * DT)


def test_the_thrust_holds_the_descent_speed_within_30_percent_of_the_weight_and_the_maximum():
    m, weight, t_max = 0.63, 0.63 * G, 2.0 * 0.63 * G
    assert blind_thrust_n(BlindDescent(BLIND_DESCENT_M_S, 1.0, 0.0), m, G, weight, t_max) == pytest.approx(weight)
    assert blind_thrust_n(BlindDescent(BLIND_DESCENT_M_S + 0.1, 1.0, 0.0), m, G, weight, t_max) > weight  # too fast
    assert blind_thrust_n(BlindDescent(-20.0, 1.0, 0.0), m, G, weight, t_max) == pytest.approx(0.3 * weight)
    assert blind_thrust_n(BlindDescent(20.0, 1.0, 0.0), m, G, weight, t_max) == pytest.approx(t_max)
