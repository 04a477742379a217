"""When the bundled vehicle's world may step: real time x speed-up, paused for a late setpoint, or
in lockstep with the companion.

- **Real time** (the default): simulated time runs at ``speedup`` times wall time from an anchor.
  A world that falls behind by more than ``max_catchup_wall_s`` (a stalled host, a speed-up the
  machine cannot give) is not raced back: the anchor moves to now, the overrun is counted and the
  simulated time lost is summed (``skipped_ms``).
- **Waiting for setpoints** (``wait_for_setpoints_s``): while the vehicle follows a stream whose
  newest setpoint is older than that, the world pauses.
- **Lockstep** (``lockstep_period_s``): while the vehicle follows a stream, the world runs at once
  to one period past the telemetry stamp of the newest setpoint and stops there; the state at the
  stop goes out at once and is repeated every :data:`REPEAT_WALL_S` while waiting. A stream silent
  for ``max_wait_wall_s`` of awake wall time is gone, not late: time runs on until a newer setpoint.

Pure: the server passes the clocks (wall seconds from a monotonic clock, the world's simulated
seconds) and does what the answers ask (step, send the state, sleep).
"""

from __future__ import annotations

import enum
import math
from collections import Counter, deque
from dataclasses import dataclass, field

__all__ = ["Wait", "Pass", "WorldPacing", "REPEAT_WALL_S", "AWAKE_STEP_WALL_S"]

REPEAT_WALL_S = 0.02
"""while the world waits, the newest state goes out again this often [wall s]"""
AWAKE_STEP_WALL_S = 0.02
"""the most wall time one check of a wait counts as awake: a stall of the whole machine (both
processes) is not the stream going silent"""


class Wait(enum.Enum):
    """What the world does on this pass of the loop."""

    RUN = "run"
    """not waiting: step"""
    BEGIN = "begin"
    """a lockstep stop begins: send the state at the stop now"""
    REPEAT = "repeat"
    """still waiting, and the newest state is due again"""
    HOLD = "hold"
    """still waiting"""


@dataclass(frozen=True)
class Pass:
    """One pass of the loop that steps: how far, and whether lockstep set it."""

    target_t: float
    """step while the world's time is at most half a step short of this [simulated s]"""
    locked: bool


@dataclass
class WorldPacing:
    """The pace of one world; the limits are :class:`~sitl.autopilot.server.ServerConfig`'s."""

    speedup: float
    dt_s: float
    lockstep_period_s: float
    wait_for_setpoints_s: float
    max_wait_wall_s: float
    max_catchup_wall_s: float
    stats: Counter[str] = field(default_factory=Counter)
    """shared with the server's report: setpoint_waits, waited_ms, lockstep_gave_up, overruns, skipped_ms"""
    anchor_wall: float = 0.0
    anchor_t: float = 0.0
    acted_on_t: float = -math.inf
    """the newest setpoint's telemetry stamp (its arrival if unstamped) [simulated s]"""
    gave_up_on: float = math.nan
    """the acted_on_t of a stream given up on (time runs on until a newer setpoint)"""
    longest_wait_s: float = 0.0
    """the longest the world waited for a setpoint [wall s]"""
    idle_s: float = 0.0
    """wall seconds slept between passes because the world was ahead of time (its headroom)"""
    lateness_s: deque[float] = field(default_factory=lambda: deque(maxlen=100_000))
    """wall-clock lateness of the latest passes that stepped in real time"""
    run_wall0: float = math.nan
    run_t0: float = 0.0
    _wait_start: float | None = None
    _repeat_due: float = 0.0
    _awake_s: float = 0.0
    _checked: float = 0.0

    def start(self, now_wall: float, t: float) -> None:
        self.anchor_wall, self.anchor_t = now_wall, t
        self.run_wall0, self.run_t0 = now_wall, t

    def resume(self, now_wall: float, t: float) -> None:
        """Anchor here, one step due at once: after a pause, with no catching up."""
        self.anchor_wall, self.anchor_t = now_wall - self.dt_s / self.speedup, t

    def setpoint(self, acted_on_t: float) -> None:
        """A setpoint was accepted, computed from telemetry of simulated time ``acted_on_t``."""
        self.acted_on_t = acted_on_t

    def locked(self, follows_stream: bool) -> bool:
        """Lockstep sets the pace (the vehicle follows a stream not given up on)."""
        return self.lockstep_period_s > 0 and follows_stream and self.acted_on_t != self.gave_up_on

    def late(self, t: float, follows_stream: bool) -> bool:
        """The world has reached where it must wait for the next setpoint."""
        if not follows_stream or self.acted_on_t == self.gave_up_on:
            return False
        if self.lockstep_period_s > 0:
            return t >= self.acted_on_t + self.lockstep_period_s - 0.5 * self.dt_s
        return self.wait_for_setpoints_s > 0 and t - self.acted_on_t > self.wait_for_setpoints_s

    def wait(self, now_wall: float, t: float, follows_stream: bool) -> Wait:
        """Whether this pass waits for a setpoint, and what to send meanwhile."""
        late = self.late(t, follows_stream)
        begin = late and self._wait_start is None
        if begin:
            self._wait_start, self._repeat_due = now_wall, now_wall + REPEAT_WALL_S
            self._awake_s, self._checked = 0.0, now_wall
            self.stats["setpoint_waits"] += 1
        if late:
            self._awake_s += min(now_wall - self._checked, AWAKE_STEP_WALL_S)
            self._checked = now_wall
            if self._awake_s > self.max_wait_wall_s:
                self.gave_up_on = self.acted_on_t  # gone, not late: time runs on
                self.stats["lockstep_gave_up"] += 1
                late = False
        if late:
            if begin:
                return Wait.BEGIN if self.lockstep_period_s > 0 else Wait.HOLD
            if now_wall >= self._repeat_due:
                self._repeat_due = now_wall + REPEAT_WALL_S
                return Wait.REPEAT
            return Wait.HOLD
        if self._wait_start is not None:
            waited = now_wall - self._wait_start
            self._wait_start = None
            self.stats["waited_ms"] += round(waited * 1e3)
            self.longest_wait_s = max(self.longest_wait_s, waited)
        return Wait.RUN

    def plan(self, now_wall: float, t: float, follows_stream: bool) -> Pass:
        """How far to step on this pass: to the wall clock's time in real time (a pass started late
        is recorded; one too far behind re-anchors instead of racing), at once to the next stop in
        lockstep."""
        speedup, dt = self.speedup, self.dt_s
        target = self.anchor_t + (now_wall - self.anchor_wall) * speedup
        locked = self.locked(follows_stream)
        if locked:
            target = max(target, self.acted_on_t + self.lockstep_period_s)
        else:
            due_wall = self.anchor_wall + (t + dt - self.anchor_t) / speedup
            if now_wall >= due_wall:
                self.lateness_s.append(now_wall - due_wall)
            behind = target - t
            if behind > self.max_catchup_wall_s * speedup:
                self.stats["overruns"] += 1
                self.stats["skipped_ms"] += round((behind - dt) * 1e3)
                self.resume(now_wall, t)
                target = t + dt
        return Pass(target, locked)

    def sleep_s(self, now_wall: float, t: float, locked: bool) -> float:
        """Wall seconds to sleep after a pass that stepped to ``t`` (lockstep: none, paced by
        setpoints, not the wall)."""
        if locked:
            self.resume(now_wall, t)
        pause = max(0.0, self.anchor_wall + (t + self.dt_s - self.anchor_t) / self.speedup - now_wall)
        self.idle_s += pause
        return pause

    def report(self, now_wall: float, t: float, run_wall_s: float | None = None) -> dict[str, float]:
        """How the world kept its speed: simulated and wall seconds since :meth:`start`, their ratio
        against the speed-up asked for, the fraction of wall time asleep ahead of time (headroom),
        and the simulated time skipped after stalls (docs/sitl.md, Time)."""
        wall = run_wall_s if run_wall_s is not None else (0.0 if math.isnan(self.run_wall0)
                                                           else now_wall - self.run_wall0)
        sim = t - self.run_t0
        return {"wall_s": round(wall, 3), "sim_s": round(sim, 3),
                "speedup": round(sim / wall, 3) if wall > 0 else 0.0, "speedup_asked": self.speedup,
                "idle_fraction": round(self.idle_s / wall, 3) if wall > 0 else 0.0,
                "skipped_s": round(self.stats.get("skipped_ms", 0) / 1000.0, 3)}
