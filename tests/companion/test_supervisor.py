"""The flight's judge without sockets: what the watchdog and the steps decide from what was seen."""

import math

from companion.flight import supervisor as sv
from companion.flight.pacing import TickGrid
from companion.flight.runner import wall_timeout_s

LIM = sv.Limits(telemetry_timeout_s=0.3, stale_hold_s=1.0, link_lost_s=3.0)


def watch(**kw):
    base = dict(wall_s=100.0, connected=True, silent_link_s=0.0, silent_nav_s=0.0, telemetry_age_s=0.01,
                behind_s=0.0, rate=1.0, engaged=True)
    return sv.Watch(**(base | kw))


def test_a_healthy_link_changes_nothing():
    v = sv.judge(sv.Watchdog(), watch(), LIM)
    assert v.state == sv.Watchdog() and v.link_lost is None and v.hold is None


def test_silence_past_the_link_lost_bound_ends_the_flight_but_not_before():
    assert sv.judge(sv.Watchdog(), watch(silent_link_s=2.9), LIM).link_lost is None
    v = sv.judge(sv.Watchdog(), watch(silent_link_s=3.1), LIM)
    assert v.link_lost and "3.1 s" in v.link_lost


def test_old_telemetry_pauses_only_when_the_wire_is_really_silent():
    """Sped up 10x, 0.5 s of vehicle time is 50 ms of wall: below min_silence_s it is a pause of a
    simulated vehicle, not an outage."""
    quiet = sv.judge(sv.Watchdog(), watch(telemetry_age_s=0.5, silent_nav_s=0.05, rate=10.0), LIM)
    assert not quiet.state.stale
    stale = sv.judge(sv.Watchdog(), watch(telemetry_age_s=0.5, silent_nav_s=0.4), LIM)
    assert stale.state.stale and stale.state.outages == 1 and "setpoints paused" in stale.log[0]
    back = sv.judge(stale.state, watch(wall_s=101.0), LIM)
    assert not back.state.stale and back.state.stale_until_wall_s == 101.0
    assert sv.outage_recent(back.state, 102.5) and not sv.outage_recent(back.state, 103.5)


def test_hold_is_commanded_once_after_a_real_silence():
    s = sv.Watchdog()
    s = sv.judge(s, watch(telemetry_age_s=0.5, silent_nav_s=0.5), LIM).state
    v = sv.judge(s, watch(telemetry_age_s=1.2, silent_nav_s=1.2), LIM)
    assert v.hold and v.state.hold_requested
    assert sv.judge(v.state, watch(telemetry_age_s=1.5, silent_nav_s=1.5), LIM).hold is None


def test_a_backlog_in_our_own_queue_pauses_but_never_holds():
    v = sv.judge(sv.Watchdog(), watch(behind_s=2.0), LIM)
    assert v.state.stale and v.hold is None and "queued here" in v.log[0]


def test_leaving_the_safety_volume_ends_the_mission_once():
    state, why = sv.judge_breach(sv.Watchdog(), "12.0 m from home, limit 10 m")
    assert why == "outside the safety volume: 12.0 m from home, limit 10 m" and state.breached
    assert sv.judge_breach(state, "13 m") == (state, None)
    assert sv.judge_breach(sv.Watchdog(), None) == (sv.Watchdog(), None)


def test_a_breach_is_not_judged_on_stale_telemetry():
    stale = sv.Watchdog(stale=True)
    assert sv.judge_breach(stale, "12.0 m from home, limit 10 m") == (stale, None)


def step(**kw):
    base = dict(interrupted=False, expect_offboard=False, offboard=False, mode="HOLD", armed=True,
                taking_off=False)
    return sv.StepWatch(**(base | kw))


def test_a_take_off_wait_ends_when_the_vehicle_disarms_or_a_failsafe_lands_it():
    assert sv.judge_wait(step(taking_off=True, armed=False)) is None  # the arming heartbeat has not come yet
    assert "disarmed" in sv.judge_wait(step(taking_off=True, armed=False, armed_seen=True))
    assert "LAND" in sv.judge_wait(step(taking_off=True, mode="LAND", mode_at_start="TAKEOFF"))
    assert sv.judge_wait(step(taking_off=True, mode="LAND", mode_at_start="LAND")) is None  # not a change
    assert sv.judge_wait(step(taking_off=True, mode="TAKEOFF")) is None


def test_the_autopilot_leaving_offboard_or_an_interrupt_ends_a_wait():
    assert sv.judge_wait(step(interrupted=True)) == "interrupted"
    why = sv.judge_wait(step(expect_offboard=True, offboard=False, mode="HOLD", outage=True, stale_for_s=1.5))
    assert "left offboard (mode HOLD) after a 1.5 s telemetry outage" in why


def test_recovery_never_fights_a_pilot_nor_cancels_a_failsafe_landing():
    assert sv.recovery(True, True, False, "OFFBOARD", "px4") == "hold_then_land"  # ours
    assert sv.recovery(False, False, False, "TAKEOFF", "px4") == "hold_then_land"  # before offboard
    assert sv.recovery(True, False, False, "HOLD", "px4") == "leave"  # a pilot took it
    assert sv.recovery(True, False, True, "LAND", "px4") == "leave"  # its failsafe lands it
    assert sv.recovery(True, False, True, "POSCTL", "px4") == "leave"  # PX4 v1.16's descent without RC
    assert sv.recovery(True, False, True, "BRAKE", "ardupilot") == "land"  # it only holds
    assert sv.recovery(True, False, True, "HOLD", "px4") == "land"  # holds in the air after the outage
    assert sv.recovery(True, False, True, "HOLD", "px4", on_ground=True) == "leave"  # its failsafe landed it
    assert not sv.may_command_hold(expect_offboard=True, offboard=False)
    assert sv.may_command_hold(expect_offboard=True, offboard=True)
    assert not sv.may_command_hold(expect_offboard=True, offboard=True, mode_heard_since=False)  # stale mode


def test_a_mission_timeout_fires_on_the_wall_clock_when_stamps_stop():
    """Timeouts count believed stamps; the wall bound is what an attacker who freezes them cannot
    hold up: a 60 s timeout on a real vehicle (rate 1) ends after at most 122 s of wall time."""
    assert wall_timeout_s(60.0, 1.0) == 122.0
    assert wall_timeout_s(60.0, 4.0) == 122.0  # never shorter than the vehicle time at 1x
    assert wall_timeout_s(60.0, 0.1) == 2.0 * 60.0 / 0.25 + 2.0


def test_the_tick_grid_follows_the_stamps_and_falls_back_at_the_rate():
    g = TickGrid(0.01)
    g.start(line_now=10.05, newest=10.0)
    assert g.t_next == 10.0
    assert math.isclose(g.advance(newest=10.0), 10.01)
    assert math.isclose(g.advance(newest=10.0), 10.01)  # never more than a tick past the newest stamp
    assert math.isclose(g.due_stamp(), 10.01 - 0.001)
    g.last_tick_wall = 5.0
    # no sooner than (almost) a period after the last tick
    assert math.isclose(g.fallback_wall(line_wall=4.0, rate=2.0), 5.0 + 0.9 * 0.01 / 2.0)
    g.ticked(now_wall=6.0, line_now=10.2, newest=10.005)
    assert g.late_ticks == 1 and math.isclose(g.t_next, 10.015)
