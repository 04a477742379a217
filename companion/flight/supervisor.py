"""The flight's judge: pure functions of what was seen and the clock, returning decisions.

No sockets, no tasks, no clock reads: the runner (:mod:`companion.flight.runner`) samples the
link into a :class:`Watch` every 20 ms, asks :func:`judge`, and carries out the :class:`Verdict`
(pause the setpoints, command hold, end the flight). While a mission step waits,
:func:`judge_wait` says whether it may go on. Everything here is tested without a vehicle
(tests/companion/test_supervisor.py).

The rules, and why:

- **link lost**: nothing at all heard for ``link_lost_s`` (wall, counted only while this process
  was awake to hear it: :mod:`companion.flight.silence`) -> the flight ends (exit 3); the vehicle's
  own failsafe protects it.
- **stale**: position or attitude older than ``telemetry_timeout_s`` of vehicle time *and* silent
  on the wire for at least that long in wall time at the vehicle's rate (never less than
  ``min_silence_s``): sped up, a short pause of a simulated vehicle must not read as seconds of
  outage -> setpoints pause; they resume when telemetry is fresh again.
- **behind**: datagrams keep arriving but wait in our own queue (this process starved of CPU) ->
  treated as stale; measured on our side of the socket, so a pausing vehicle cannot fake it.
- **hold**: stale for ``stale_hold_s`` of vehicle time and really silent (at least
  ``min_hold_silence_s`` of wall time) -> command hold once, in the background.
- **safety volume**: the vehicle outside the mission's volume while we fly it -> the mission
  stops: hold, then land.
- a step's wait ends with an abort when the operator interrupts, when the autopilot leaves the
  mode that flies our setpoints (a pilot or a failsafe took over), or, while taking off, when it
  disarms or starts landing by itself (a failsafe): waiting out the timeout then would be waiting
  for something that cannot happen.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

__all__ = ["Limits", "Watch", "Watchdog", "Verdict", "judge", "outage_recent", "StepWatch", "judge_wait",
           "FAILSAFE_MODES", "recovery", "may_command_hold", "LANDING_MODES", "HOLDING_MODES", "TakeOverView",
           "take_over_refusal", "STABLE_SPEED_M_S", "STABLE_CLIMB_M_S"]


@dataclass(frozen=True)
class Limits:
    telemetry_timeout_s: float
    """vehicle seconds"""
    stale_hold_s: float
    """vehicle seconds"""
    link_lost_s: float
    """wall seconds"""
    min_silence_s: float = 0.15
    """wall seconds of silence below which telemetry is never called stale (sped-up simulations)"""
    min_hold_silence_s: float = 0.5
    """wall seconds of silence below which hold is never commanded: sped up, a host stall freezes
    a simulated vehicle for a few hundred ms, which reads as seconds of vehicle time"""


@dataclass(frozen=True)
class Watch:
    """What the watchdog saw at one check."""

    wall_s: float
    connected: bool
    """an autopilot has been heard (the link-lost rule applies from then on)"""
    silent_link_s: float
    """wall seconds with nothing at all heard (awake-counted)"""
    silent_nav_s: float
    """wall seconds with no position or attitude heard (awake-counted)"""
    telemetry_age_s: float
    """vehicle seconds since the older of position and attitude"""
    behind_s: float
    """vehicle seconds the newest parsed datagram waited in our own queue"""
    rate: float
    """vehicle seconds per wall second"""
    engaged: bool
    """the controller is streaming setpoints"""


@dataclass(frozen=True)
class Watchdog:
    """The judge's memory between checks."""

    stale: bool = False
    hold_requested: bool = False
    outages: int = 0
    stale_for_s: float = 0.0
    longest_outage_s: float = 0.0
    stale_until_wall_s: float = -math.inf
    breached: bool = False


@dataclass(frozen=True)
class Verdict:
    state: Watchdog
    link_lost: str | None = None
    """end the flight: the link is gone"""
    hold: str | None = None
    """command hold now (best effort, in the background), for this reason"""
    log: tuple[str, ...] = ()


def judge(s: Watchdog, w: Watch, lim: Limits) -> Verdict:
    if w.connected and w.silent_link_s > lim.link_lost_s:
        return Verdict(s, link_lost=f"vehicle link lost: no telemetry for {w.silent_link_s:.1f} s "
                                    f"(bound {lim.link_lost_s:g} s)")
    if not w.engaged:
        return Verdict(dataclasses.replace(s, stale=False))
    rate = max(w.rate, 1e-3)
    age = w.telemetry_age_s
    stale = age > lim.telemetry_timeout_s and w.silent_nav_s > max(lim.telemetry_timeout_s / rate, lim.min_silence_s)
    behind = w.behind_s > lim.telemetry_timeout_s
    if behind:
        stale, age = True, max(age, w.behind_s)
    log: list[str] = []
    new = s
    if stale and not s.stale:
        new = dataclasses.replace(new, outages=s.outages + 1)
        log.append(f"telemetry {'queued here' if behind else 'stale'} ({age:.2f} s): setpoints paused")
    elif s.stale and not stale:
        new = dataclasses.replace(new, stale_until_wall_s=w.wall_s)
        log.append(f"telemetry back after {s.stale_for_s:.2f} s")
    hold = None
    if stale:
        new = dataclasses.replace(new, stale_for_s=age, longest_outage_s=max(s.longest_outage_s, age))
        # hold only for real silence: not for a backlog in our own queue (it clears in one pass of
        # the reader) nor for a stall of this host (the silence is awake-counted)
        if (age > lim.stale_hold_s and not s.hold_requested
                and w.silent_nav_s > max(lim.stale_hold_s / rate, lim.min_hold_silence_s)):
            new = dataclasses.replace(new, hold_requested=True)
            hold = f"telemetry stale for {age:.2f} s: commanding hold"
            log.append(hold)
    return Verdict(dataclasses.replace(new, stale=stale), hold=hold, log=tuple(log))


def judge_breach(s: Watchdog, breach: str | None) -> tuple[Watchdog, str | None]:
    """The safety volume, judged on every control tick (vehicle time, so a lockstep flight stops at
    the same place on any host): the first breach seen on fresh telemetry ends the mission, once.
    ``breach`` is the volume's reason (None: inside); the verdict is the mission's abort reason."""
    if breach is None or s.breached or s.stale:
        return s, None
    return dataclasses.replace(s, breached=True), f"outside the safety volume: {breach}"


def outage_recent(s: Watchdog, wall_s: float, within_s: float = 2.0) -> bool:
    """While telemetry is stale and for ``within_s`` wall seconds after it came back: a mode change
    seen then is the autopilot's reaction to the outage, not a pilot's decision."""
    return s.stale or wall_s - s.stale_until_wall_s < within_s


FAILSAFE_MODES = frozenset({"LAND", "RTL", "PRECLAND", "SMART_RTL", "BRAKE"})
"""modes an autopilot enters by itself when something failed; a take-off cannot complete in them"""


@dataclass(frozen=True)
class StepWatch:
    """What a mission step's wait sees at one check."""

    interrupted: bool
    expect_offboard: bool
    """the mission has switched the autopilot to fly our setpoints"""
    offboard: bool
    mode: str
    armed: bool
    taking_off: bool
    """the step waits for the autopilot's own take-off"""
    armed_seen: bool = False
    """the vehicle was seen armed since the wait began (heartbeats lag commands)"""
    mode_at_start: str = ""
    """the mode when the wait began: only a change *to* a failsafe mode counts"""
    outage: bool = False
    """telemetry was stale recently (outage_recent)"""
    stale_for_s: float = 0.0


def judge_wait(w: StepWatch) -> str | None:
    """Why a waiting step must end now (an abort), or None to go on waiting. ``"interrupted"`` is
    the operator's request."""
    if w.interrupted:
        return "interrupted"
    if w.expect_offboard and not w.offboard:
        during = f" after a {w.stale_for_s:.1f} s telemetry outage" if w.outage else ""
        return f"the autopilot left offboard (mode {w.mode}){during}"
    if w.taking_off and w.armed_seen and not w.armed:
        return "the vehicle disarmed during the take-off"
    if w.taking_off and w.mode in FAILSAFE_MODES and w.mode != w.mode_at_start:
        return f"the autopilot switched to {w.mode} during the take-off (a failsafe?)"
    return None


LANDING_MODES = frozenset({"LAND", "RTL", "PRECLAND", "SMART_RTL"})
HOLDING_MODES = frozenset({"HOLD", "LOITER", "BRAKE", "POSHOLD"})


def recovery(expect_offboard: bool, offboard: bool, outage: bool, mode: str, autopilot: str,
             on_ground: bool = False) -> str:
    """After an abort or an interrupt, what the companion does with the vehicle:

    - ``"hold_then_land"``: it is ours (we fly it offboard, or it is still in the autopilot's own
      take-off/hold before offboard): hold, then land;
    - ``"leave"``: the autopilot left offboard by itself — a pilot or ground station took over, or
      its own failsafe is landing it (a failsafe is never cancelled: PX4 v1.16 without RC descends
      in what its heartbeat calls POSCTL) or has landed it (``on_ground``, EXTENDED_SYS_STATE: the
      failsafe's landing ends in HOLD, armed until the autopilot disarms it; nothing to land);
    - ``"land"``: it left offboard during a telemetry outage and now merely holds in the air: land it.
    """
    if not expect_offboard or offboard:
        return "hold_then_land"
    if not outage or mode in LANDING_MODES or (autopilot == "px4" and mode == "POSCTL") or on_ground:
        return "leave"
    return "land" if mode in HOLDING_MODES else "leave"


def may_command_hold(expect_offboard: bool, offboard: bool, mode_heard_since: bool = True) -> bool:
    """A hold queued during an outage is sent only while the vehicle still flies our setpoints: once
    the autopilot left offboard by itself (its failsafe started), a late hold would cancel it. The
    mode must have been heard since the hold was asked for (``mode_heard_since``): the one known
    before is as old as the outage, and the autopilot's offboard-loss failsafe may have started
    meanwhile unseen (a retry that got through as the link came back cancelled PX4's descent)."""
    return not expect_offboard or (offboard and mode_heard_since)


STABLE_SPEED_M_S = 0.5
"""horizontal speed above which a vehicle is not taken over: more than a hold's drift in a gust"""
STABLE_CLIMB_M_S = 0.15
"""vertical speed above which a vehicle is not taken over: below the slowest landing descent (the
bundled vehicle's MPC_LAND_SPEED floor 0.2 m/s, PX4's MPC_LAND_CRWL 0.3 m/s), above a hold's
altitude wander"""
TAKING_OFF_MODES = frozenset({"TAKEOFF"})


@dataclass(frozen=True)
class TakeOverView:
    """What ``--take-over`` sees of the vehicle before it streams or switches anything."""

    armed: bool
    in_air: bool
    """the autopilot says it flies (MAV_LANDED_STATE_IN_AIR); a take-off or landing is not"""
    on_ground: bool
    """the autopilot says it is on the ground (MAV_LANDED_STATE_ON_GROUND)"""
    landed_known: bool
    """the autopilot reports its landed state at all (EXTENDED_SYS_STATE)"""
    mode: str
    autopilot: str
    failsafe: bool
    """the heartbeat's system status says a failsafe is active (MAV_STATE_CRITICAL or EMERGENCY)"""
    has_navigation: bool
    vel_ned_m_s: tuple[float, float, float]


def take_over_refusal(v: TakeOverView) -> str | None:
    """Why ``--take-over`` must not take this armed or flying vehicle, or None to take it. Taking
    over switches the autopilot to the mode that flies our setpoints, which ends whatever it is
    doing: an autopilot's failsafe in progress (PX4 v1.16's offboard-loss descent, a landing, a
    return) is never fought, so only a vehicle in the air, holding still and in no failsafe or
    landing mode is taken; one armed on the ground is not flown from there (its take-off steps
    would be skipped and the controller would hold it on the ground)."""
    if v.failsafe:
        return f"the autopilot reports a failsafe in progress (mode {v.mode}): it is left to finish it"
    if v.mode in LANDING_MODES or v.mode in FAILSAFE_MODES:
        return f"the autopilot is in {v.mode} (a landing, a return or a failsafe): it is left to finish it"
    if v.autopilot == "px4" and v.mode == "POSCTL":
        return ("PX4 is in POSCTL: a pilot flies it, or its offboard-loss failsafe descends (v1.16 without RC "
                "shows POSCTL): it is left as it is")
    if v.mode in TAKING_OFF_MODES:
        return f"the vehicle is taking off ({v.mode}): start again once it holds"
    if v.on_ground or (v.armed and v.landed_known and not v.in_air):
        where = "on the ground" if v.on_ground else "taking off or landing (MAV_LANDED_STATE)"
        return f"the vehicle is armed {where}: only a vehicle in the air is taken over"
    if not v.has_navigation:
        return "no position from the vehicle: it cannot be taken over from where it is"
    vn, ve, vd = v.vel_ned_m_s
    speed = math.hypot(vn, ve)
    if speed > STABLE_SPEED_M_S or abs(vd) > STABLE_CLIMB_M_S:
        return (f"the vehicle is not holding still ({speed:.2f} m/s horizontally, {-vd:+.2f} m/s up; bounds "
                f"{STABLE_SPEED_M_S:g} and {STABLE_CLIMB_M_S:g}): take it over once it holds")
    return None
