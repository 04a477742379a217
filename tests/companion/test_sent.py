"""What the flight reports of the setpoints it sent (companion/flight/sent.py)."""

import math

from companion.flight.sent import MAX_PERIODS, SentSetpoints


def test_the_rate_is_counted_over_vehicle_time_and_the_jitter_over_wall_time():
    s = SentSetpoints()
    assert s.rate_hz() is None and s.timing() == {}
    for k in range(101):  # 100 Hz of vehicle time, the wall spacing 10 ms but every tenth 12 ms
        s.sent(5.0 + 0.01 * k, 100.0 + 0.01 * k + 0.002 * (k // 10))
    assert math.isclose(s.rate_hz(), 100.0)
    t = s.timing()
    assert math.isclose(t["median_period_ms"], 10.0, abs_tol=1e-6)
    assert math.isclose(t["p99_abs_jitter_ms"], 2.0, abs_tol=1e-6)  # the 12 ms ones


def test_a_long_flight_keeps_a_bounded_record():
    s = SentSetpoints()
    for k in range(MAX_PERIODS + 10):
        s.sent(0.01 * k, 0.01 * k)
    assert s.count == MAX_PERIODS + 10 and len(s.periods_s) <= MAX_PERIODS
