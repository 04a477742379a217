"""Estimator resets: the autopilot's position estimate jumps while the vehicle does not.

An EKF that has drifted on a glitching GPS (or lost and found its vision or its origin) resets its
position to the measurement: from one LOCAL_POSITION_NED to the next, the reported position moves
by metres in milliseconds. PX4 announces it (ODOMETRY's ``reset_counter`` counts position, velocity
and heading resets); ArduPilot does not say so on the wire. Flown as a real error, a 4 m reset is a
4 m step of the position loop: a steep tilt, metres per second, and a vehicle flown 4 m from where
it held, towards a place the jump invented.

The companion keeps flying in the frame it started in: every reset found is added to an offset,
and the position the controller, the mission and the safety volume see is the reported one less
that offset (:class:`~companion.link.state.VehicleState` applies it). A reset is found

- **unannounced**: a step between consecutive position samples that their velocities cannot
  explain — more than ``½ a_max dt² + v_err dt`` beyond the velocities' trapezoid, where ``a_max``
  is the most the vehicle's thrust and gravity can accelerate it (:meth:`ResetBound.for_vehicle`)
  — and at least ``floor_m`` (smaller corrections are flown as real errors);
- **announced**: the same jump within ``ANNOUNCE_WINDOW_S`` of a change of the reset counter
  (before or after: the counter and the position are separate streams), labelled so. The floor
  holds for it too: the counter also counts heading and velocity resets, and PX4's SIH changes it
  again and again beside 0.09-0.19 m steps, its GPS corrections, which must not move the
  companion's frame away from PX4's. An announcement with no jump is counted, not applied.

Pure: samples and times in, decisions out; no clock, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

from companion.control.vector import Vec3

__all__ = ["ResetBound", "PositionReset", "ResetDetector", "ResetsTold", "unstable_reason", "unexplained_step",
           "ANNOUNCE_WINDOW_S"]

ANNOUNCE_WINDOW_S = 0.25
"""vehicle seconds between a reset counter's change and the position jump it announces (ODOMETRY
arrives at 30 Hz, LOCAL_POSITION_NED at 10-60 Hz)"""
UNSTABLE_WINDOW_S = 10.0
UNSTABLE_RESETS = 3
"""this many resets within UNSTABLE_WINDOW_S: the estimate is not one to fly offboard on"""


@dataclass(frozen=True)
class ResetBound:
    """How far a position sample may be from where the previous one and the velocities put it."""

    max_accel_m_s2: float = 60.0
    """the most the vehicle can accelerate [m/s^2] (thrust and gravity, with margin)"""
    velocity_error_m_s: float = 1.0
    """how far a reported velocity may be from the true mean over a sample interval (filter lag,
    noise; the bundled vehicle's 5 Hz filter lags 0.3 m/s at 10 m/s^2)"""
    floor_m: float = 0.25
    """the smallest unannounced jump taken as a reset: estimate noise and small corrections below
    it are flown as errors (what it can command is bounded by the controller's error limit)"""

    @classmethod
    def for_vehicle(cls, thrust_max_n: float, mass_kg: float, gravity_m_s2: float = 9.81) -> ResetBound:
        """``a_max``: full thrust plus gravity (thrust pointed down, or the motors off in free
        fall), with 50 % for wind, drag and an external push."""
        return cls(max_accel_m_s2=1.5 * (thrust_max_n / mass_kg + gravity_m_s2))

    def explained_m(self, dt_s: float) -> float:
        """The most a position may move beyond the velocities' trapezoid over ``dt_s``."""
        return 0.5 * self.max_accel_m_s2 * dt_s * dt_s + self.velocity_error_m_s * dt_s


@dataclass(frozen=True)
class PositionReset:
    """One reset found: at vehicle time ``t_s`` the estimate moved by ``shift_ned_m``."""

    t_s: float
    shift_ned_m: Vec3
    announced: bool

    @property
    def size_m(self) -> float:
        return math.hypot(*self.shift_ned_m)


def unexplained_step(t0_s: float, pos0: Vec3, vel0: Vec3, t1_s: float, pos1: Vec3, vel1: Vec3) -> Vec3:
    """How far ``pos1`` is from ``pos0`` carried forward by the mean of the two velocities [m, NED]."""
    dt = t1_s - t0_s
    return tuple(p1 - p0 - 0.5 * (v0 + v1) * dt  # type: ignore[return-value]
                 for p0, v0, p1, v1 in zip(pos0, vel0, pos1, vel1))


@dataclass
class ResetDetector:
    """Finds resets in the position stream (:meth:`observe`) and the reset counter
    (:meth:`announce`); ``offset_ned_m`` is the sum of their shifts."""

    bound: ResetBound = field(default_factory=ResetBound)
    offset_ned_m: Vec3 = (0.0, 0.0, 0.0)
    resets: list[PositionReset] = field(default_factory=list)
    announcements: int = 0
    """reset counter changes seen (position, velocity or heading resets)"""
    counter: int | None = None
    _last: tuple[float, Vec3, Vec3] | None = None
    _announced_at: float = -math.inf

    def observe(self, t_s: float, pos_ned_m: Vec3, vel_ned_m_s: Vec3) -> PositionReset | None:
        """A new position sample (as reported, newer than the last): the reset it shows, if any."""
        last, self._last = self._last, (t_s, pos_ned_m, vel_ned_m_s)
        if last is None or t_s <= last[0]:
            return None
        step = unexplained_step(last[0], last[1], last[2], t_s, pos_ned_m, vel_ned_m_s)
        size = math.hypot(*step)
        if not size > self.bound.explained_m(t_s - last[0]):
            return None
        if size < self.bound.floor_m:
            return None
        announced = abs(t_s - self._announced_at) <= ANNOUNCE_WINDOW_S
        if announced:
            self._announced_at = -math.inf
        return self._apply(t_s, step, announced)

    def announce(self, counter: int, t_s: float) -> None:
        """The autopilot's reset counter at vehicle time ``t_s`` (the first one sets the baseline):
        a change labels a jump already taken, or the next one, within ``ANNOUNCE_WINDOW_S``."""
        previous, self.counter = self.counter, counter
        if previous is None or counter == previous:
            return
        self.announcements += 1
        for i in range(len(self.resets) - 1, -1, -1):
            r = self.resets[i]
            if abs(r.t_s - t_s) <= ANNOUNCE_WINDOW_S and not r.announced:
                self.resets[i] = PositionReset(r.t_s, r.shift_ned_m, True)
                return
        self._announced_at = t_s

    def _apply(self, t_s: float, step: Vec3, announced: bool) -> PositionReset:
        o = self.offset_ned_m
        self.offset_ned_m = (o[0] + step[0], o[1] + step[1], o[2] + step[2])
        reset = PositionReset(t_s, step, announced)
        self.resets.append(reset)
        return reset

    def unstable(self, t_s: float) -> bool:
        """So many resets so recently that the estimate is not one to fly on."""
        return sum(1 for r in self.resets if t_s - r.t_s <= UNSTABLE_WINDOW_S) >= UNSTABLE_RESETS


class ResetsTold(NamedTuple):
    """How far a reader of a :class:`ResetDetector` has told what it found (the flight's log)."""

    resets: int = 0
    """resets logged"""
    announcements: int = 0
    """reset-counter changes logged"""
    unstable: str | None = None
    """why the position estimate is not to be flown on (resets too often), or None"""


def unstable_reason() -> str:
    """What a flight says when :meth:`ResetDetector.unstable` first holds."""
    return f"position estimate reset {UNSTABLE_RESETS} times within {UNSTABLE_WINDOW_S:g} s: not flown on"
