"""The companion's pure parts: vehicle clock, thrust-scale estimate, setpoint guard."""

import math

from companion.link.clock import VehicleClock
from companion.control import quaternion as quat
from companion.flight.guard import SetpointGuard
from companion.flight.thrust_scale import ThrustScaleEstimator


def test_clock_learns_the_speedup_and_schedules_ticks():
    c = VehicleClock()
    for k in range(300):  # 3 s of wall time at 100 Hz, vehicle running 4x, 10.0 s boot offset
        w = 100.0 + 0.01 * k
        c.observe(10.0 + 4.0 * 0.01 * k, w)
    assert math.isclose(c.rate, 4.0, rel_tol=1e-9)
    assert math.isclose(c.now(103.0), 10.0 + 4.0 * 3.0, rel_tol=1e-9)
    assert math.isclose(c.wall_at(22.0), 103.0, rel_tol=1e-9)
    assert math.isclose(c.age(21.0, 103.0), 1.0, rel_tol=1e-6)


def test_clock_ignores_reordered_samples_and_starts_over_when_reset():
    c = VehicleClock()
    for k in range(100):
        c.observe(5.0 + 0.01 * k, 0.01 * k)
    c.observe(5.5, 1.0)  # late, older sample: ignored
    assert math.isclose(c.now(0.99), 5.99, abs_tol=1e-9)
    c.observe(0.1, 2.0)  # a stamp far back moves nothing: only the stamp gate may rebase the clock
    assert math.isclose(c.now(2.0), 7.0, abs_tol=1e-6)
    c.reset()  # the gate saw a restarted vehicle: clock back near zero
    c.observe(0.1, 2.0)
    assert math.isclose(c.now(2.0), 0.1)


def test_thrust_scale_estimate_converges_to_the_true_scale():
    """The observer sees (k - 1) T b when the true scale is 18.56 N and we assume 15 N; the
    estimate must find 18.56 N (within 1%) in level hover and in a 45 deg hover where a 6 N
    horizontal force also acts (which the vertical-only measurement must ignore)."""
    true_max = 18.56
    for tilt in (0.0, math.radians(45.0)):
        est = ThrustScaleEstimator(15.0, adapt=True)
        q = quat.from_euler(0.0, tilt, 0.0)
        for _ in range(6000):  # 60 s at 100 Hz
            t_cmd = 6.18 / math.cos(tilt)
            k = true_max / est.thrust_max_n
            b = quat.rotate(q, (0.0, 0.0, -1.0))
            h = tuple((k - 1.0) * t_cmd * b[i] + (6.0 if i == 0 and tilt else 0.0) for i in range(3))
            est.update(h, q, t_cmd, 0.01)
        assert math.isclose(est.estimated_thrust_max_n, true_max, rel_tol=0.01), tilt
        assert math.isclose(est.thrust_max_n, true_max, rel_tol=0.01), tilt


def test_thrust_scale_without_adaptation_only_reports():
    est = ThrustScaleEstimator(15.0, adapt=False)
    for _ in range(3000):
        est.update((0.0, 0.0, -(18.56 / 15.0 - 1.0) * 6.18), quat.IDENTITY, 6.18, 0.01)
    assert est.thrust_max_n == 15.0
    assert math.isclose(est.estimated_thrust_max_n, 18.56, rel_tol=0.01)


def test_guard_rejects_what_must_not_fly():
    g = SetpointGuard(math.radians(60.0), math.radians(250.0))
    level = (1.0, 0.0, 0.0, 0.0)
    assert g.check(level, (0.0, 0.0, 0.0), 0.5) is None
    assert "non-finite" in g.check((math.nan, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.5)
    assert "norm" in g.check((0.9, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.5)
    assert "thrust" in g.check(level, (0.0, 0.0, 0.0), 1.2)
    assert "rate" in g.check(level, (5.0, 0.0, 0.0), 0.5)
    assert "tilt" in g.check(quat.from_euler(math.radians(70.0), 0.0, 0.0), (0.0, 0.0, 0.0), 0.5)
    assert g.check(quat.from_euler(math.radians(59.0), 0.0, 0.0), (0.0, 0.0, 0.0), 0.5) is None


def test_clock_is_not_fooled_by_transport_delay_jitter():
    """Packets arrive 0.5..4 ms late (uniform, seeded). Anchored on the least-delayed packets, the
    clock's ticks land within 0.6 ms of the true schedule, where anchoring on the newest packet
    would scatter them over the full 3.5 ms of delay spread."""
    import random

    rng = random.Random(5)
    c = VehicleClock()
    worst = 0.0
    for k in range(2000):  # 8 s of telemetry at 250 Hz, vehicle at 2x
        true_wall = 50.0 + k * 0.004
        c.observe(100.0 + 2.0 * (true_wall - 50.0), true_wall + rng.uniform(0.0005, 0.004))
        if k > 500:
            # when will the vehicle reach the time it had at true_wall + 10 ms?
            target = 100.0 + 2.0 * (true_wall + 0.010 - 50.0)
            worst = max(worst, abs(c.wall_at(target) - (true_wall + 0.010) - 0.0005))
    assert math.isclose(c.rate, 2.0, rel_tol=2e-3)
    assert worst < 0.0006, worst


def test_clock_reanchors_when_a_paused_vehicle_resumes_behind_its_old_line():
    """A simulated vehicle at 4x stalls for 0.2 s of wall time (its clock stops) and resumes
    0.8 vehicle-seconds behind the old line. Without re-anchoring, the old anchor (least delayed
    of the last second) would keep the clock 0.8 s ahead for up to a second, every sample would
    look 0.8 s old, and the control loop would tick 0.8 s early."""
    c = VehicleClock()
    for k in range(300):  # 3 s at 100 Hz, 4x
        c.observe(4.0 * 0.01 * k, 0.01 * k)
    assert math.isclose(c.now(2.99), 4.0 * 2.99, abs_tol=1e-9)
    t_v = 4.0 * 2.99
    for k in range(1, 50):  # resumes at wall 3.19, same rate
        w = 3.19 + 0.01 * k
        t_v += 0.04
        c.observe(t_v, w)
        assert abs(c.age(t_v, w)) < 1e-9  # a fresh sample is fresh at once
    assert math.isclose(c.rate, 4.0, rel_tol=1e-9)


def test_clock_gap_from_a_link_outage_keeps_the_line():
    """After a link outage the vehicle's clock has run on: re-anchoring on the first sample back
    keeps the line (within that sample's delay, here 3 ms)."""
    c = VehicleClock()
    for k in range(300):
        c.observe(10.0 + 0.01 * k, 0.01 * k)
    c.observe(10.0 + 4.0, 4.0 + 0.003)  # 1 s outage, then a sample 3 ms late
    assert abs(c.now(4.1) - (10.0 + 4.1)) < 0.004


def test_clock_reanchors_on_a_repeated_stamp_from_a_vehicle_that_waited():
    """A simulated vehicle at 4x waits for this process (stalled 0.3 s of wall time) with its
    clock stopped at 12.0 s, repeating its last telemetry. The repeat re-anchors the line: the
    stamp is fresh again rather than 1.2 vehicle-seconds old, and the rate is kept."""
    c = VehicleClock()
    for k in range(301):
        c.observe(4.0 * 0.01 * k, 0.01 * k)  # up to vehicle 12.0 s at wall 3.0 s
    assert math.isclose(c.age(12.0, 3.3), 1.2, abs_tol=1e-9)  # extrapolated: looks 1.2 s old
    c.observe(12.0, 3.3)  # the repeat, after 0.3 s of silence
    assert abs(c.age(12.0, 3.3)) < 1e-9
    c.observe(12.0, 3.31)  # repeats within 50 ms change nothing
    assert math.isclose(c.age(12.0, 3.31), 0.04, abs_tol=1e-9)
    c.observe(12.04, 3.31)  # the vehicle runs on from there
    assert math.isclose(c.rate, 4.0, rel_tol=1e-9) and abs(c.age(12.04, 3.31)) < 1e-9


def test_silence_counts_only_while_awake():
    """A watchdog checking every 20 ms: a real outage counts at full speed; a 1 s stall of this
    host (no check ran, nothing could arrive) counts as one 40 ms step."""
    from companion.flight.silence import AwakeSilence

    s = AwakeSilence(max_step_s=0.04)
    assert math.isclose(s.check(100.0, 100.005), 0.005)  # a packet 5 ms ago
    t = 100.005
    for _ in range(50):  # 1 s of checks with nothing arriving
        t += 0.02
        s.check(100.0, t)
    assert math.isclose(s.silent_s, 1.005, abs_tol=1e-9)
    s.check(t + 0.001, t + 0.002)  # a packet: silence restarts
    assert math.isclose(s.silent_s, 0.001, abs_tol=1e-9)
    t += 0.002
    assert math.isclose(s.check(t - 0.001, t + 1.0), 0.041)  # stalled 1 s: one 40 ms step
    assert math.isclose(s.check(t - 0.001, t + 1.02), 0.061)  # then it counts again
