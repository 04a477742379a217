"""What each kind of mission step does in flight: one function per action, found by name.

Each takes the running flight (:class:`Flight`: its link, controller and waits)
and the step, and returns when the step is done; it raises to end the mission (the runner holds,
lands and disarms). The step's own data is checked before anything arms (:mod:`companion.mission`).
"""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from typing import Protocol

from companion.link import LinkError, VehicleLink
from companion.mission import Step

from .errors import MissionAbort
from .offboard import OffboardController
from .prepare import ParamChanges

__all__ = ["Flight", "STEPS", "run_step"]


class Flight(Protocol):
    """What a step may use of the running flight (:class:`companion.flight.runner.Flight`)."""

    link: VehicleLink
    engaged: bool
    expect_offboard: bool
    skipped: list[str]
    params: ParamChanges
    taking_over: bool
    """``--take-over`` of a vehicle found armed or flying"""
    ours: bool
    """the companion answers for the vehicle (it armed it, or the autopilot accepted our take-over)"""
    @property
    def sent(self) -> int:
        """setpoints sent so far"""

    @property
    def last_sent_t(self) -> float:
        """vehicle time [s] of the newest setpoint sent"""

    @property
    def controller(self) -> OffboardController: ...

    def log(self, text: str) -> None: ...

    async def until(self, cond: Callable[[], bool], timeout_v: float, what: str,
                    taking_off: bool = False) -> None: ...

    async def sleep_v(self, seconds: float) -> None: ...

    async def arm(self, timeout_s: float) -> None: ...

    def take_over_refusal(self) -> str | None: ...

TAKEOFF_TOLERANCE_M = 0.15
TAKEOFF_ALT_PARAM = "MIS_TAKEOFF_ALT"
"""PX4's take-off altitude above home [m]; the link's take-off also writes it (MAVSDK does, inside
``set_takeoff_altitude``), so the step records it first and the link's write changes nothing more"""


async def takeoff(f: Flight, s: Step) -> None:
    """The autopilot's own take-off; done when within 15 cm of the altitude and out of TAKEOFF.
    Ends at once if the vehicle disarms or a failsafe starts landing it (supervisor.judge_wait)."""
    st = f.link.state
    if not st.armed:
        await f.arm(s.timeout_s)
    ground = st.pos_ned_m[2]
    if st.autopilot == "px4":  # PX4 takes the altitude from MIS_TAKEOFF_ALT: written, then put back
        await f.params.set(TAKEOFF_ALT_PARAM, s.altitude_m, "take-off altitude")
    await f.link.takeoff(s.altitude_m)
    target = ground - s.altitude_m
    await f.until(lambda: abs(st.pos_ned_m[2] - target) < TAKEOFF_TOLERANCE_M and st.mode != "TAKEOFF",
                  s.timeout_s, f"take-off to {s.altitude_m:g} m", taking_off=True)


PRE_STREAM_S = 1.2
"""vehicle seconds of setpoints before the switch (PX4 wants > 2 Hz for > 1 s)"""
PRE_STREAM_SETPOINTS = 10
MODE_RETRY_S = 3.0
"""vehicle seconds an accepted switch may take to show in the heartbeat before it is asked again"""


async def offboard(f: Flight, s: Step) -> None:
    """Stream setpoints (PX4 wants > 2 Hz for > 1 s before the switch), then switch. The controller
    restarts from the vehicle's state right before the switch (integrators and observers empty,
    reference where the vehicle is): until then the autopilot flew its own hold, and what the
    controller learnt meanwhile was the autopilot's doing, not a disturbance (bumpless).

    The stream is counted, not slept: a busy host whose vehicle runs ahead of it may have sent no
    setpoint in 1.2 s of vehicle time. The switch is asked again while the heartbeat does not show
    it: PX4 v1.16 answers DO_SET_MODE twice, and one answer may accept what the other rejects."""
    c, st = f.controller, f.link.state
    c.start(st)
    f.engaged = True
    before, first_t = f.sent, math.nan

    def streamed() -> bool:
        nonlocal first_t
        if f.sent > before and math.isnan(first_t):
            first_t = f.last_sent_t
        return f.sent - before >= PRE_STREAM_SETPOINTS and st.t - first_t >= PRE_STREAM_S

    await f.until(streamed, s.timeout_s, "a setpoint stream before the switch to offboard")
    if f.taking_over:  # checked again right before the switch: a failsafe may have begun meanwhile
        why = f.take_over_refusal()
        if why is not None:
            raise MissionAbort(f"not taken over: {why}")
    c.start(st)
    start = st.t
    while not st.offboard:
        asked = st.t
        await f.link.start_offboard()
        f.ours = True
        remaining = s.timeout_s - (st.t - start)
        await f.until(lambda asked=asked: st.offboard or st.t - asked >= MODE_RETRY_S or st.t - start >= s.timeout_s,
                      max(remaining, 0.1), "offboard mode")
        if not st.offboard and st.t - start >= s.timeout_s:
            raise MissionAbort(f"timeout: offboard mode not within {s.timeout_s:g} s")
    f.expect_offboard = True


async def hold(f: Flight, s: Step) -> None:
    c = f.controller
    if s.position_ned_m is not None:
        c.set_target(s.position_ned_m, math.radians(s.yaw_deg) if s.yaw_deg is not None else None)
    elif s.yaw_deg is not None:
        c.set_target(c.target, math.radians(s.yaw_deg))
    await f.sleep_v(s.duration_s)


async def goto(f: Flight, s: Step) -> None:
    c, st = f.controller, f.link.state
    for wp in s.waypoints:
        c.set_target(wp, speed_m_s=s.speed_m_s)
        await f.until(lambda wp=wp: c.reference_at_target and math.dist(st.pos_ned_m, wp) < s.tolerance_m,
                      s.timeout_s, f"waypoint {wp}")
        if s.hold_s > 0:
            await f.sleep_v(s.hold_s)


async def set_param(f: Flight, s: Step) -> None:
    """Through the flight's parameter record: put back when the flight ends unless ``keep``."""
    try:
        found = await f.params.set(s.param, s.value, f"step {s.name}", keep=s.keep)
    except LinkError as exc:
        raise MissionAbort(str(exc)) from None
    if found:
        return
    if not s.sim_only:
        raise MissionAbort(f"{s.param}: the autopilot has no such parameter")
    f.skipped.append(f"{s.name}: {s.param} (no such parameter on this vehicle)")
    f.log(f"{s.param}: no such parameter on this vehicle: step {s.name!r} SKIPPED")


async def wait(f: Flight, s: Step) -> None:
    await f.sleep_v(s.duration_s)


async def land(f: Flight, s: Step) -> None:
    st = f.link.state
    f.expect_offboard = False
    if st.armed:
        await f.link.land()
        f.engaged = False
        await f.until(lambda: not st.armed, s.timeout_s, "landing and disarm")


STEPS: dict[str, Callable[[Flight, Step], Awaitable[None]]] = {
    "takeoff": takeoff, "offboard": offboard, "hold": hold, "goto": goto, "set_param": set_param,
    "wait": wait, "land": land,
}


async def run_step(f: Flight, s: Step) -> None:
    await STEPS[s.action](f, s)
