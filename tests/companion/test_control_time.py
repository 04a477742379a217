"""The controller's time follows the telemetry's stamps: it never integrates through vehicle time
that was not seen to pass (a paused simulated vehicle, a telemetry gap)."""

import math

from companion.control.params import PositionGains, ReferenceParams, TrajectoryParams, VehicleParams
from companion.flight.control_time import ControllerTime, default_lead_s
from companion.flight.offboard import OffboardController
from companion.flight.guard import SetpointGuard
from companion.link.state import VehicleState
from companion.flight.thrust_scale import ThrustScaleEstimator

PERIOD = 0.01
LEAD = default_lead_s(PERIOD)


def test_on_a_healthy_link_the_line_decides_one_tick_at_a_time():
    ct = ControllerTime(PERIOD, LEAD)
    steps = [ct.advance(10.0 + PERIOD * k, 10.0 + PERIOD * k - 0.007) for k in range(200)]
    assert all(len(s) == 1 and math.isclose(s[0], PERIOD, rel_tol=1e-9) for s in steps)
    assert ct.held_ticks == 0 and ct.sub_steps == 0
    assert math.isclose(ct.t_s, 10.0 + PERIOD * 199)


def test_a_frozen_vehicle_holds_the_controller_and_its_resumption_is_replayed_exactly():
    """The stamps stop at 12.0 s while the line runs on 0.3 s: the controller goes no further than
    12.0 + lead and then holds. When the vehicle resumes, the controller advances by exactly the
    vehicle time the stamps moved, in tick-sized sub-steps."""
    ct = ControllerTime(PERIOD, LEAD)
    t = 11.5
    while t < 12.0 - 1e-9:
        t += PERIOD
        ct.advance(t, t - 0.005)
    frozen = t - 0.005
    advanced = 0.0
    for k in range(1, 31):
        advanced += sum(ct.advance(t + PERIOD * k, frozen))
    assert ct.t_s <= frozen + LEAD + 1e-9
    assert advanced <= LEAD - 0.005 + 1e-9
    assert ct.held_ticks >= 27
    # the vehicle resumes where it stood: its stamps move 80 ms while the line is far ahead
    before = ct.t_s
    steps = ct.advance(t + 0.31, frozen + 0.08)
    assert math.isclose(sum(steps), frozen + 0.08 + LEAD - before, rel_tol=1e-9)
    assert all(dt <= 1.5 * PERIOD for dt in steps) and len(steps) >= 6


def test_a_long_gap_is_replayed_only_up_to_the_catch_up_bound():
    ct = ControllerTime(PERIOD, LEAD, max_catch_up_s=0.25)
    ct.advance(5.0, 4.995)
    steps = ct.advance(6.0, 5.995)  # 1 s of telemetry missing, then back
    assert math.isclose(sum(steps), 0.25) and len(steps) == 25
    assert math.isclose(ct.dropped_s, 0.75)
    assert math.isclose(ct.t_s, 6.0)


def test_reordered_older_stamps_never_move_the_controller_back():
    ct = ControllerTime(PERIOD, LEAD)
    ct.advance(5.0, 4.995)
    assert ct.advance(5.01, 4.90) == []  # an old packet arrived last: hold
    assert math.isclose(ct.t_s, 5.0)


def _controller() -> OffboardController:
    # "measured" force: this scripted vehicle follows the reference whatever is commanded, so an
    # observer of the commanded force would learn that mismatch and this test would measure it
    gains = PositionGains(force_source="measured")
    return OffboardController("ism_do", VehicleParams(), gains, ReferenceParams(), TrajectoryParams(),
                              ThrustScaleEstimator(18.5, adapt=False), SetpointGuard(), period_s=PERIOD)


def _hover_state(t: float) -> VehicleState:
    st = VehicleState()
    st.set_position((0.0, 0.0, -2.0), (0.0, 0.0, 0.0), t, 0.0)
    st.set_attitude((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), t, 0.0)
    return st


def test_the_reference_does_not_run_ahead_of_a_vehicle_that_stood_still():
    """A 10 m goto at 2 m/s: the line runs 0.5 s while the vehicle's stamps stand still. The
    reference may move only while the controller is within the lead of the newest stamp (at most
    2 m/s * lead = 4 cm), not 0.5 s * 2 m/s (which is what stepping on the line alone did);
    every tick re-sends the last setpoint."""
    c = _controller()
    st = _hover_state(20.0)
    c.start(st)
    c.set_target((10.0, 0.0, -2.0))
    for k in range(100):  # 1 s of normal flight: the reference gets up to speed
        t = 20.0 + PERIOD * k
        st.t_pos = st.t_att = t - 0.005
        tick, moved = c.update(st, t)
        assert moved
    x0 = tick.reference.pos_ned_m[0]
    speed = tick.reference.vel_ned_m_s[0]
    assert 1.0 < speed <= 2.0 + 1e-9
    frozen_at = st.t
    for k in range(1, 51):
        tick, moved = c.update(st, frozen_at + 0.005 + PERIOD * k)
    assert not moved and tick is c.last
    assert tick.reference.pos_ned_m[0] - x0 <= 2.0 * (LEAD - 0.005) + 1e-6


def test_propagation_carries_a_sample_forward_exactly_under_constant_acceleration():
    """p(t) = p0 + v0 t + a t^2 / 2 with a = f + g e3: hovering (f = -g e3) stays put; a
    vehicle braking at 4 m/s^2 from 2 m/s is carried 30 ms forward exactly."""
    from companion.flight.offboard import propagate

    g = 9.81
    assert propagate((1.0, 2.0, -3.0), (0.0, 0.0, 0.0), (0.0, 0.0, -g), g, 0.03) == (
        (1.0, 2.0, -3.0), (0.0, 0.0, 0.0))
    pos, vel = propagate((0.0, 0.0, -2.0), (2.0, 0.0, 0.0), (-4.0, 0.0, -g), g, 0.03)
    assert math.isclose(pos[0], 2.0 * 0.03 - 0.5 * 4.0 * 0.03**2, rel_tol=1e-12)
    assert math.isclose(vel[0], 2.0 - 4.0 * 0.03, rel_tol=1e-12)
    assert math.isclose(pos[2], -2.0, abs_tol=1e-12) and abs(vel[2]) < 1e-12
    # without an IMU: constant velocity
    assert propagate((0.0, 0.0, 0.0), (1.0, -1.0, 0.5), None, g, 0.02)[0] == (0.02, -0.02, 0.01)


def test_the_controller_sees_no_error_from_latency_alone():
    """The vehicle flies exactly on a 2 m/s reference, but each sample is 30 ms old when used:
    carried forward to the controller's time it matches the reference, so the force has no
    position-error part (without it the controller saw 6 cm and learned to fly ahead)."""
    c = _controller()
    st = _hover_state(20.0)
    c.start(st)
    c.set_target((100.0, 0.0, -2.0))
    for k in range(300):  # 3 s: reference at its 2 m/s cruise
        t = 20.0 + PERIOD * k
        tick, _ = c.update(st, t)
        ref = c.filter
        # the vehicle was exactly on the reference 30 ms ago (constant speed: ref - v * 0.03)
        vx = ref.vel_ned_m_s[0]
        st.set_position((ref.pos_ned_m[0] - vx * 0.03, 0.0, -2.0), (vx, 0.0, 0.0), t - 0.03, 0.0)
        st.set_attitude((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), t - 0.005, 0.0)
    assert math.isclose(c.filter.vel_ned_m_s[0], 2.0, rel_tol=1e-6)
    assert abs(tick.force_n[0]) < 0.02  # N; uncarried, the 6 cm and its integral asked for 0.8 N
