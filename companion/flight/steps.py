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


async def offboard(f: Flight, s: Step) -> None:
    """Stream setpoints (PX4 wants > 2 Hz for > 1 s before the switch), then switch. The controller
    restarts from the vehicle's state right before the switch (integrators and observers empty,
    reference where the vehicle is): until then the autopilot flew its own hold, and what the
    controller learnt meanwhile was the autopilot's doing, not a disturbance (bumpless)."""
    c, st = f.controller, f.link.state
    c.start(st)
    f.engaged = True
    await f.sleep_v(1.2)
    if f.taking_over:  # checked again right before the switch: a failsafe may have begun meanwhile
        why = f.take_over_refusal()
        if why is not None:
            raise MissionAbort(f"not taken over: {why}")
    c.start(st)
    await f.link.start_offboard()
    f.ours = True
    await f.until(lambda: st.offboard, s.timeout_s, "offboard mode")
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
