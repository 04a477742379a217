"""Estimator resets found in the telemetry (companion/link/resets.py) and re-anchored in the state,
without sockets: what a jump is, from the physics of the vehicle, and what it may command."""

from __future__ import annotations

import math

import pytest

from companion.control import quaternion as quat
from companion.control.params import PositionGains, ReferenceParams, TrajectoryParams, VehicleParams
from companion.flight.guard import SetpointGuard
from companion.flight.offboard import MAX_POSITION_ERROR_M, OffboardController, bounded_position
from companion.flight.thrust_scale import ThrustScaleEstimator
from companion.link.resets import ANNOUNCE_WINDOW_S, ResetBound, ResetDetector, unexplained_step
from companion.link.state import VehicleState

DT = 1.0 / 60.0
BUNDLED = ResetBound.for_vehicle(18.6, 0.63)


def fly(det: ResetDetector, n: int, t0: float = 0.0, pos=(0.0, 0.0, -1.5), vel=(0.0, 0.0, 0.0), accel=(0.0, 0.0, 0.0),
        jump_at: int | None = None, jump=(4.0, 0.0, 0.0)):
    """``n`` samples of a vehicle accelerating at ``accel`` (exact positions and velocities), the
    estimate moved by ``jump`` from sample ``jump_at`` on; returns the resets found."""
    found = []
    for k in range(n):
        t = t0 + k * DT
        p = tuple(p0 + v0 * (t - t0) + 0.5 * a * (t - t0) ** 2 for p0, v0, a in zip(pos, vel, accel))
        v = tuple(v0 + a * (t - t0) for v0, a in zip(vel, accel))
        if jump_at is not None and k >= jump_at:
            p = tuple(a + b for a, b in zip(p, jump))
        r = det.observe(t, p, v)
        if r is not None:
            found.append(r)
    return found


def test_the_bound_is_the_vehicles_physics():
    """Full thrust (18.6 N on 0.63 kg) plus gravity, with half again for wind and pushes: 59 m/s^2;
    over one 60 Hz sample that and 1 m/s of velocity error explain 2.5 cm, never 4 m."""
    assert BUNDLED.max_accel_m_s2 == pytest.approx(1.5 * (18.6 / 0.63 + 9.81))
    assert 0.02 < BUNDLED.explained_m(DT) < 0.03


def test_real_flight_is_never_a_reset():
    """A vehicle braking or accelerating at 4 g (beyond what it can) from 10 m/s: its position
    follows its velocity, so nothing is found."""
    for accel in ((39.0, 0.0, 0.0), (0.0, -30.0, 20.0)):
        det = ResetDetector(BUNDLED)
        assert fly(det, 600, vel=(10.0, -5.0, 2.0), accel=accel) == []
        assert det.offset_ned_m == (0.0, 0.0, 0.0)


def test_an_unannounced_jump_is_found_on_its_first_sample_and_re_anchored():
    det = ResetDetector(BUNDLED)
    found = fly(det, 120, vel=(1.0, 0.5, 0.0), jump_at=60, jump=(4.0, -1.0, 0.5))
    assert len(found) == 1 and not found[0].announced
    assert found[0].t_s == pytest.approx(60 * DT)
    assert math.dist(found[0].shift_ned_m, (4.0, -1.0, 0.5)) < 1e-9
    assert math.dist(det.offset_ned_m, (4.0, -1.0, 0.5)) < 1e-9


def test_a_small_step_is_flown_announced_or_not_and_a_large_one_is_labelled_either_way():
    """10 cm is under the 25 cm floor: a correction like any other, even beside a counter change
    (PX4's counter also counts heading and velocity resets; SIH changes it beside 0.09-0.19 m GPS
    corrections). A 4 m jump is a reset, labelled announced whether the counter changes after it
    or just before."""
    quiet = ResetDetector(BUNDLED)
    assert fly(quiet, 120, jump_at=60, jump=(0.1, 0.0, 0.0)) == []
    told = ResetDetector(BUNDLED)
    told.announce(7, 0.0)
    told.announce(8, 60 * DT - 0.02)
    assert fly(told, 120, jump_at=60, jump=(0.1, 0.0, 0.0)) == [] and told.offset_ned_m == (0.0, 0.0, 0.0)
    assert told.announcements == 1
    told_after = ResetDetector(BUNDLED)
    told_after.announce(7, 0.0)
    fly(told_after, 61, jump_at=60)  # the jump, then the counter (separate streams)
    told_after.announce(8, 60 * DT + 0.02)
    assert [r.announced for r in told_after.resets] == [True]
    told_before = ResetDetector(BUNDLED)
    told_before.announce(255, 0.0)
    told_before.announce(0, 60 * DT - 0.02)  # uint8 wrap: a change is a change
    found = fly(told_before, 120, jump_at=60)
    assert len(found) == 1 and found[0].announced and found[0].shift_ned_m[0] == pytest.approx(4.0)


def test_an_announcement_relabels_a_jump_already_taken_and_never_applies_it_twice():
    det = ResetDetector(BUNDLED)
    det.announce(0, 0.0)
    fly(det, 120, jump_at=60)
    assert det.announce(1, 60 * DT + 0.03) is None
    assert [r.announced for r in det.resets] == [True]
    assert det.offset_ned_m[0] == pytest.approx(4.0)


def test_an_announcement_without_a_jump_is_counted_not_applied():
    """PX4's counter also counts heading and velocity resets."""
    det = ResetDetector(BUNDLED)
    det.announce(3, 0.0)
    det.announce(4, 1.0)
    assert fly(det, 120, t0=1.0 + 2 * ANNOUNCE_WINDOW_S) == []
    assert det.announcements == 1 and det.resets == []


def test_three_resets_in_ten_seconds_are_not_flown_on():
    det = ResetDetector(BUNDLED)
    for k in range(3):
        fly(det, 60, t0=3.0 * k, jump_at=30)
        assert det.unstable(3.0 * k + 1.0) is (k == 2)
    assert not det.unstable(30.0)


def test_the_state_gives_a_position_in_the_frame_the_flight_began_in():
    st = VehicleState()
    st.resets = ResetDetector(BUNDLED)
    for k in range(60):
        assert st.set_position((0.0, 0.0, -1.5) if k < 30 else (4.0, 0.0, -1.5), (0.0, 0.0, 0.0), k * DT, 0.0)
        assert st.pos_ned_m == pytest.approx((0.0, 0.0, -1.5), abs=1e-12)
    assert st.pos_estimate_ned_m == (4.0, 0.0, -1.5)


def test_trapezoid_is_exact_for_constant_acceleration():
    assert unexplained_step(0.0, (0, 0, 0), (1.0, 0, 0), 0.5, (0.5 + 0.5 * 2.0 * 0.25, 0, 0), (2.0, 0, 0)) == \
        pytest.approx((0.0, 0.0, 0.0))


def test_what_a_jump_can_command_is_bounded():
    """A 4 m error that reaches the controller (a jump not found) asks for what 1 m does. ISM+DO on
    the bundled vehicle, first tick: a 4 m step unbounded asks for 42.5 deg (the 42 deg the old
    companion flew); bounded, atan(K_p 1 m / g) = atan(1.5^2 / 9.81) = 12.9 deg."""
    assert bounded_position((4.0, 0.0, -1.5), (0.0, 0.0, -1.5), 1.0) == pytest.approx((1.0, 0.0, -1.5))
    assert bounded_position((0.3, 0.0, -1.5), (0.0, 0.0, -1.5), 1.0) == (0.3, 0.0, -1.5)

    def tilt_deg(max_error_m: float) -> float:
        v = VehicleParams()
        c = OffboardController("ism_do", v, PositionGains(), ReferenceParams(), TrajectoryParams(),
                               ThrustScaleEstimator(18.6), SetpointGuard(math.radians(60), math.radians(250)),
                               max_error_m=max_error_m)
        st = VehicleState()
        st.set_position((0.0, 0.0, -1.5), (0.0, 0.0, 0.0), 1.0, 0.0)
        st.set_attitude((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, 0.0)
        c.start(st)
        st.pos_ned_m = (4.0, 0.0, -1.5)  # the jump, not re-anchored
        tick = c.step(st, 1.01, 0.01)
        return math.degrees(quat.tilt_angle(tick.setpoint.q))

    assert tilt_deg(math.inf) > 40.0
    assert tilt_deg(1.0) < math.degrees(math.atan(1.5**2 * 1.0 / 9.81)) + 0.5
    assert tilt_deg(MAX_POSITION_ERROR_M) == tilt_deg(math.inf)  # 4 m is below the cap: flown as it is
