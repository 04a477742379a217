"""The stamp gate: no telemetry stamp of another time base, jumping forward, going backwards or
repeating may move the vehicle clock or stall it; a sample older than the one held never
replaces it; a vehicle that really restarts is followed once its old time base has gone silent;
a ``time_boot_ms`` that wraps after 49.7 days is a wrap, not a jump."""

import math
import time

from companion.link.clock import VehicleClock
from companion.link.stamps import StampGate
from companion.link.state import VehicleState
from companion.flight.control_time import ControllerTime, default_lead_s
from companion.mavlink.boot_time import BOOT_MS_PERIOD_S, boot_ms, unwrap_boot_s

PERIOD = 0.01


class Feed:
    """A link's view without sockets: the gate, the clock and the state, fed as the link does."""

    def __init__(self) -> None:
        self.gate, self.clock, self.state = StampGate(), VehicleClock(), VehicleState()
        self.time = ControllerTime(PERIOD, default_lead_s(PERIOD))

    def attitude(self, stamp: float, wall: float, q=(1.0, 0.0, 0.0, 0.0), wraps: bool = False) -> bool:
        before = self.gate.rebases
        a = self.gate.admit(stamp, wall, self.clock.rate if self.clock.ready else 1.0, wraps)
        if self.gate.rebases != before:
            self.clock.reset()
            self.state.restart_time()
        if a is None or not self.state.set_attitude(q, (0.0, 0.0, 0.0), a.t_s, wall):
            return False
        if a.feeds_clock:
            self.clock.observe(a.t_s, wall)
        return True

    def imu(self, stamp: float, wall: float, f=(0.0, 0.0, -9.81)) -> bool:
        before = self.gate.rebases
        a = self.gate.admit(stamp, wall, self.clock.rate if self.clock.ready else 1.0)
        if self.gate.rebases != before:
            self.clock.reset()
            self.state.restart_time()
        if a is None or not self.state.set_imu(f, a.t_s, wall):
            return False
        if a.feeds_clock:
            self.clock.observe(a.t_s, wall)
        return True

    def fly(self, t0: float, wall0: float, seconds: float, rate: float = 1.0) -> tuple[float, float]:
        """Genuine attitude at 100 Hz of wall time, the vehicle running at ``rate``; the controller
        ticks with it. Returns the last (stamp, wall)."""
        n = int(round(seconds / PERIOD))
        for k in range(1, n + 1):
            w = wall0 + PERIOD * k
            t = t0 + rate * PERIOD * k
            self.attitude(t, w)
            self.time.advance(self.clock.now(w), self.state.t)
        return t0 + rate * PERIOD * n, wall0 + PERIOD * n


def test_unix_time_imu_stamps_never_move_the_clock_and_the_controller_goes_on():
    """The field defect: ten HIGHRES_IMU frames stamped in UNIX time mid-flight."""
    f = Feed()
    t, w = f.fly(100.0, 5000.0, 2.0)
    unix_s = time.time()
    for k in range(10):
        f.imu(unix_s + 0.001 * k, w + 0.0005 * k)
    assert f.gate.counts["stamp_unix_time"] == 10
    assert f.state.t < 1000.0 and math.isclose(f.clock.now(w), t, abs_tol=0.02)
    before = f.time.t_s
    t2, w2 = f.fly(t, w, 1.0)
    assert math.isclose(f.time.t_s - before, 1.0, abs_tol=0.03)  # advanced with the vehicle, not stuck
    assert math.isclose(f.clock.now(w2), t2, abs_tol=0.02)


def test_unix_time_imu_data_is_used_at_the_newest_believed_stamp_when_that_is_all_there_is():
    f = Feed()
    t, w = f.fly(50.0, 10.0, 0.5)
    assert f.imu(time.time(), w + 0.001, (0.1, 0.2, -9.7))
    assert f.state.specific_force_body_m_s2 == (0.1, 0.2, -9.7) and f.state.t_imu == t


def test_a_jump_forward_is_refused_and_moves_nothing():
    f = Feed()
    t, w = f.fly(100.0, 0.0, 2.0)
    for jump in (1.0, 60.0, 4.0e6):  # 1 s to 46 days ahead, 5 ms after the last genuine sample
        assert not f.attitude(t + jump, w + 0.005, q=(0.9659, 0.2588, 0.0, 0.0))
    assert f.gate.counts["stamp_jump_forward"] == 3
    assert f.state.q == (1.0, 0.0, 0.0, 0.0) and f.state.t == t
    assert math.isclose(f.clock.now(w + 0.005), t + 0.005, abs_tol=0.01)


def test_forward_steps_the_vehicle_could_have_lived_are_believed():
    """A simulated vehicle at 10x after our own 0.3 s stall: its samples arrive in a burst."""
    f = Feed()
    t, w = f.fly(0.0, 0.0, 3.0, rate=10.0)
    assert math.isclose(f.clock.rate, 10.0, rel_tol=1e-6)
    assert f.attitude(t + 3.0, w + 0.3)  # 0.3 s of wall at 10x: 3 s of vehicle time, believed
    assert f.gate.counts["stamp_jump_forward"] == 0


def test_going_backwards_is_refused_and_an_older_sample_never_replaces_a_newer_one():
    f = Feed()
    t, w = f.fly(100.0, 0.0, 1.0)
    assert not f.attitude(t - 30.0, w + 0.002, q=(0.9659, 0.2588, 0.0, 0.0))  # far back: refused
    assert f.gate.counts["stamp_backwards"] == 1
    f.attitude(t - 0.05, w + 0.003, q=(0.9659, 0.2588, 0.0, 0.0))  # a little older: valid, not stored
    assert f.state.q == (1.0, 0.0, 0.0, 0.0) and f.state.t_att == t
    assert f.state.older_samples == 1
    assert math.isclose(f.clock.now(w + 0.003), t + 0.003, abs_tol=0.01)


def test_a_repeated_stamp_with_other_data_replaces_nothing_and_does_not_stall_the_clock():
    f = Feed()
    t, w = f.fly(100.0, 0.0, 1.0)
    for k in range(20):  # the newest stamp, again and again, with a tilted attitude
        f.attitude(t, w + 0.001 * k, q=(0.9659, 0.2588, 0.0, 0.0))
    assert f.state.q == (1.0, 0.0, 0.0, 0.0)
    before = f.time.t_s
    f.fly(t, w + 0.02, 0.5)  # genuine samples go on: the controller's time moves with them
    assert math.isclose(f.time.t_s - before, 0.52, abs_tol=0.03)


def test_a_few_frames_of_another_base_mixed_into_a_live_stream_never_rebase():
    f = Feed()
    t, w = f.fly(100.0, 0.0, 1.0)
    for k in range(200):  # 2 s of a live stream, with a consistent forged base interleaved
        w += PERIOD
        t += PERIOD
        f.attitude(t, w)
        f.attitude(5000.0 + PERIOD * k, w + 0.001)
    assert f.gate.rebases == 0 and f.state.t_att == t


def test_a_vehicle_that_restarted_is_followed_once_its_old_base_fell_silent():
    f = Feed()
    t, w = f.fly(300.0, 0.0, 1.0)
    w += 0.5  # reboot
    accepted = [f.attitude(0.5 + PERIOD * k, w + PERIOD * k) for k in range(200)]
    assert f.gate.rebases == 1
    first = accepted.index(True)
    assert PERIOD * first <= 1.0 + 0.05  # within the silence bound of the old base's last sample
    assert all(accepted[first:])
    assert f.state.t_att < 3.0 and math.isclose(f.clock.now(w + 2.0), 0.5 + 2.0, abs_tol=0.05)


def test_nan_negative_and_inf_stamps_are_refused():
    f = Feed()
    f.fly(10.0, 0.0, 0.5)
    for bad in (math.nan, -1.0, math.inf):
        assert not f.attitude(bad, 0.6)
    assert f.gate.counts["stamp_invalid"] == 3


# --- time_boot_ms wraps at 2^32 ms (49.7 days); time_usec does not -----------------------------

def boot_field_s(t: float) -> float:
    """What a ``time_boot_ms`` field says at vehicle time ``t`` [s]."""
    return boot_ms(t) * 1e-3


def fly_wrapping(f: Feed, t0: float, wall0: float, seconds: float) -> tuple[float, float, list[bool]]:
    """Attitude in ``time_boot_ms`` and IMU in ``time_usec`` at 100 Hz each, as PX4 sends them;
    returns the last true (stamp, wall) and whether each sample was taken."""
    taken = []
    n = int(round(seconds / PERIOD))
    for k in range(1, n + 1):
        w, t = wall0 + PERIOD * k, t0 + PERIOD * k
        taken.append(f.attitude(boot_field_s(t), w, wraps=True))
        taken.append(f.imu(t + 0.002, w + 0.001))
        f.time.advance(f.clock.now(w), f.state.t)
    return t0 + PERIOD * n, wall0 + PERIOD * n, taken


def test_unwrapping_picks_the_instant_nearest_the_time_held():
    assert BOOT_MS_PERIOD_S == 4294967.296
    assert boot_ms(BOOT_MS_PERIOD_S - 0.001) == 2**32 - 1 and boot_ms(BOOT_MS_PERIOD_S + 0.004) == 4
    assert math.isclose(unwrap_boot_s(0.004, BOOT_MS_PERIOD_S - 0.001), BOOT_MS_PERIOD_S + 0.004, abs_tol=1e-6)
    assert unwrap_boot_s(BOOT_MS_PERIOD_S - 0.001, BOOT_MS_PERIOD_S + 0.004) == BOOT_MS_PERIOD_S - 0.001
    assert unwrap_boot_s(70.0, 100.0) == 70.0  # behind stays behind: never a negative number of wraps
    assert unwrap_boot_s(5.0, 0.0) == 5.0
    assert math.isclose(unwrap_boot_s(3.0, 3 * BOOT_MS_PERIOD_S), 3 * BOOT_MS_PERIOD_S + 3.0, rel_tol=1e-15)


def test_a_wrap_in_flight_is_followed_and_vehicle_time_stays_that_of_time_usec():
    """49.7 days up: attitude stamps go from 4294967.29 s to 0.00 s while the IMU's run on."""
    f = Feed()
    t, w, taken = fly_wrapping(f, BOOT_MS_PERIOD_S - 2.0, 1000.0, 4.0)
    assert all(taken), taken.index(False)
    assert f.gate.counts["stamp_wrapped"] == 1 and f.gate.wraps == 1
    assert f.gate.counts["stamp_backwards"] == f.gate.counts["stamp_jump_forward"] == 0
    assert math.isclose(f.state.t_att, t, abs_tol=1e-6)  # unwrapped: the true time since boot
    assert math.isclose(f.state.t_imu, t + 0.002, abs_tol=1e-6)  # the time_usec stream, consistent with it
    assert math.isclose(f.clock.now(w), t, abs_tol=0.02)
    assert f.time.dropped_s == 0.0 and math.isclose(f.time.t_s, t, abs_tol=0.03)  # no pause, no jump


def test_a_hostile_stamp_near_zero_far_from_the_wrap_is_going_backwards():
    f = Feed()
    t, w, _ = fly_wrapping(f, 100.0, 0.0, 1.0)
    assert not f.attitude(0.005, w + 0.002, q=(0.9659, 0.2588, 0.0, 0.0), wraps=True)
    assert f.gate.counts["stamp_backwards"] == 1 and f.gate.counts["stamp_wrapped"] == 0
    assert f.state.q == (1.0, 0.0, 0.0, 0.0) and f.state.t_att == t


def test_a_hostile_stamp_past_the_wrap_before_the_vehicle_can_have_reached_it_is_a_jump_forward():
    """30 s before the wrap a stamp of 0.005 s would put the vehicle 30 s on in 2 ms: refused, and
    the genuine stream goes on across the real wrap."""
    f = Feed()
    t, w, _ = fly_wrapping(f, BOOT_MS_PERIOD_S - 31.0, 0.0, 1.0)
    for k in range(10):
        assert not f.attitude(0.005 + 0.001 * k, w + 0.002, q=(0.9659, 0.2588, 0.0, 0.0), wraps=True)
    assert f.gate.counts["stamp_jump_forward"] == 10 and f.gate.wraps == 0 and f.state.t_att == t
    t, w, taken = fly_wrapping(f, t, w, 31.0)
    assert all(taken) and f.gate.wraps == 1 and f.gate.rebases == 0
    assert math.isclose(f.state.t_att, BOOT_MS_PERIOD_S + 1.0, abs_tol=1e-6)


def test_a_sample_from_before_the_wrap_arriving_after_it_is_an_older_sample():
    f = Feed()
    t, w, _ = fly_wrapping(f, BOOT_MS_PERIOD_S - 0.5, 0.0, 1.0)  # 0.5 s past the wrap
    assert f.attitude(boot_field_s(t - 0.6), w + 0.002, q=(0.9659, 0.2588, 0.0, 0.0), wraps=True)
    assert f.state.older_samples == 1 and f.state.q == (1.0, 0.0, 0.0, 0.0) and f.gate.wraps == 1


def test_a_vehicle_up_longer_than_a_wrap_is_placed_by_its_time_usec_at_connection():
    """Connected on day 60: the first attitude says 10.3 days (one wrap ago), the IMU 60 days. The
    IMU fixes which wrap it is, once, at connection; later a forged time_usec a wrap ahead is a jump."""
    f = Feed()
    day60 = 60 * 86400.0
    assert f.attitude(boot_field_s(day60), 0.0, wraps=True)
    assert f.imu(day60 + 0.002, 0.001)
    assert f.gate.counts["stamp_epoch_learned"] == 1
    t, w, taken = fly_wrapping(f, day60, 0.0, 3.0)
    assert all(taken) and math.isclose(f.state.t_att, t, abs_tol=1e-6)
    assert not f.imu(t + BOOT_MS_PERIOD_S, w + 0.002)
    assert f.gate.counts["stamp_jump_forward"] == 1 and f.gate.counts["stamp_epoch_learned"] == 1


def test_a_restart_after_half_a_wrap_of_uptime_is_followed_on_the_raw_stamps():
    """A vehicle up 30 days restarts: its new stamps unwrap nearer the next wrap, but its new base
    is what it sends (the IMU's time_usec agrees), not 49.7 days on."""
    f = Feed()
    t, w, _ = fly_wrapping(f, 30 * 86400.0, 0.0, 1.0)
    w += 0.5  # reboot
    t, w, taken = fly_wrapping(f, 0.5, w, 3.0)
    assert f.gate.rebases == 1 and all(taken[-100:])
    assert math.isclose(f.state.t_att, t, abs_tol=1e-6) and math.isclose(f.state.t_imu, t + 0.002, abs_tol=1e-6)


def test_a_fast_vehicle_stalled_before_the_clock_has_its_rate_is_still_followed():
    """A simulated vehicle at 10x, and our own 0.2 s stall 0.3 s after connecting, before the clock's
    first fit (0.5 s of samples): the burst after it (2 s of vehicle time) is what the vehicle lived,
    and the gate's bound follows the rate its own believed stamps show, not the clock's initial 1x.
    On a loaded host PX4 on the plant (free-running at ~10x) had every stamp refused from then on,
    and the companion flew blind until a rebase 90 s later."""
    f = Feed()
    t, w = f.fly(10.0, 0.0, 0.3, rate=10.0)
    assert f.attitude(t + 2.0, w + 0.2)  # the stall's burst
    t2, _ = f.fly(t + 2.0, w + 0.2, 1.0, rate=10.0)
    assert f.gate.counts["stamp_jump_forward"] == 0 and f.state.t == t2
