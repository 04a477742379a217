"""The bundled vehicle's pacing as a pure object: clocks in, decisions out, no socket and no plant."""

import math

import pytest

from sitl.autopilot.pacing import AWAKE_STEP_WALL_S, REPEAT_WALL_S, Wait, WorldPacing

DT = 0.004


def pacing(speedup=1.0, lockstep=0.0, wait=0.0, max_wait=1.0, catchup=0.05):
    p = WorldPacing(speedup, DT, lockstep, wait, max_wait, catchup)
    p.start(100.0, 0.0)
    return p


def test_real_time_steps_to_the_wall_clock_times_the_speed_up():
    p = pacing(speedup=4.0)
    step = p.plan(100.01, 0.0, follows_stream=False)
    assert not step.locked and step.target_t == pytest.approx(0.04)
    # a pass that started 3 ms after its step was due is recorded as 3 ms late
    p.plan(100.0 + DT / 4.0 + 0.003, 0.0, follows_stream=False)
    assert p.lateness_s[-1] == pytest.approx(0.003)


def test_a_stall_longer_than_the_catch_up_pauses_the_world_and_counts_the_time_skipped():
    """0.5 s of wall time lost at 2x: 1 s behind, beyond 0.05 s x 2 -> one step, not 250 back to back."""
    p = pacing(speedup=2.0)
    step = p.plan(100.5, 0.0, follows_stream=False)
    assert step.target_t == pytest.approx(DT)
    assert p.stats["overruns"] == 1 and p.stats["skipped_ms"] == round((1.0 - DT) * 1e3)
    # re-anchored: the next step is due one step of wall time from now, not in the past
    assert p.plan(100.5, DT, follows_stream=False).target_t == pytest.approx(DT)


def test_lockstep_runs_at_once_to_one_period_past_the_setpoint_stamp_and_no_further():
    p = pacing(speedup=1.0, lockstep=0.01)
    p.setpoint(2.0)
    step = p.plan(100.0, 1.995, follows_stream=True)  # the wall clock says 0 s: lockstep overrides it
    assert step.locked and step.target_t == pytest.approx(2.01)
    assert not p.late(2.01 - DT, True) and p.late(2.01 - 0.5 * DT, True)
    assert p.sleep_s(100.0, 2.01, locked=True) == 0.0  # paced by setpoints: no sleeping


def test_a_lockstep_stop_sends_the_state_once_then_repeats_it_every_20_ms_until_the_setpoint():
    p = pacing(lockstep=0.01)
    p.setpoint(1.0)
    t = 1.01
    assert p.wait(200.0, t, True) is Wait.BEGIN
    assert p.wait(200.0 + 0.5 * REPEAT_WALL_S, t, True) is Wait.HOLD
    assert p.wait(200.0 + REPEAT_WALL_S, t, True) is Wait.REPEAT
    assert p.wait(200.0 + 1.5 * REPEAT_WALL_S, t, True) is Wait.HOLD
    p.setpoint(1.01)
    assert p.wait(200.05, t, True) is Wait.RUN
    assert p.stats["setpoint_waits"] == 1 and p.stats["waited_ms"] == 50
    assert p.longest_wait_s == pytest.approx(0.05)


def test_a_stream_silent_for_max_wait_of_awake_time_is_given_up_until_a_newer_setpoint():
    p = pacing(lockstep=0.01, max_wait=0.1)
    p.setpoint(1.0)
    now, answers = 300.0, []
    while (w := p.wait(now, 1.01, True)) is not Wait.RUN:
        answers.append(w)
        now += 0.01
    assert now - 300.0 == pytest.approx(0.11) and p.stats["lockstep_gave_up"] == 1
    assert not p.locked(True) and not p.late(5.0, True)  # time runs on, to the failsafes
    p.setpoint(5.0)
    assert p.locked(True) and p.late(5.01, True)


def test_a_stall_of_the_whole_machine_counts_one_check_not_its_length():
    """A 5 s stall of both processes between two checks adds 20 ms of awake time: the stream is late,
    not gone."""
    p = pacing(lockstep=0.01, max_wait=1.0)
    p.setpoint(1.0)
    assert p.wait(400.0, 1.01, True) is Wait.BEGIN
    assert p.wait(405.0, 1.01, True) is Wait.REPEAT
    assert p._awake_s == pytest.approx(AWAKE_STEP_WALL_S) and p.stats["lockstep_gave_up"] == 0


def test_waiting_for_late_setpoints_holds_without_sending_at_once():
    p = pacing(wait=0.2)
    p.setpoint(1.0)
    assert not p.late(1.2, True) and p.late(1.2 + DT, True)
    assert p.wait(500.0, 1.3, True) is Wait.HOLD
    assert not p.plan(500.0, 1.3, True).locked


@pytest.mark.parametrize("lockstep, wait", [(0.01, 0.0), (0.0, 0.2)])
def test_a_vehicle_not_following_a_stream_never_waits(lockstep, wait):
    p = pacing(lockstep=lockstep, wait=wait)
    p.setpoint(1.0)
    assert not p.late(math.inf, False) and p.wait(600.0, 50.0, False) is Wait.RUN
    assert not p.plan(600.0, 50.0, False).locked


def test_the_report_says_the_speed_reached_and_the_headroom():
    p = pacing(speedup=2.0)
    assert p.sleep_s(100.0, 0.0, locked=False) == pytest.approx(DT / 2.0)
    report = p.report(102.0, 4.0)
    assert report["speedup"] == 2.0 and report["idle_fraction"] == pytest.approx(DT / 4.0, abs=1e-3)
