"""When the world may advance while a companion flies the firmware: lockstep with the companion.

The firmware already runs in lockstep with the plant (its clock is the plant's). What is left is
the companion, a process of its own on the same host: if it stalls, the firmware would fly on
without it. So, while a companion streams setpoints, the world runs only as far as its newest
setpoint allows: each setpoint is stamped with the firmware time of the telemetry it was computed
from (the companion's ``time_boot_ms``), and the world may run while the firmware's newest time,
as its own telemetry says, is less than ``lead_s`` past that stamp — one control period, plus
one telemetry interval so that the sample for the companion's next tick exists, plus a frame.

The world waits only while the vehicle is armed (the firmware's heartbeat, read by the relay).
A command from the companion (a landing, a hold, a mode) lets the world run to the firmware's
first heartbeat ``STREAM_GAP_S`` or more after it (the one that answers a mode change at once
comes before the stream could have been seen to end): a companion that hands the vehicle back
stops streaming on purpose, and the firmware must run to act on the command (frozen, it would
not even send the heartbeat that says so, and the give-up below raced the companion's own 3 s
link watchdog). If by that heartbeat the
newest setpoint is more than ``STREAM_GAP_S`` old, the stream has ended and the world runs on
until a newer one; if not (the switch to OFFBOARD, with the companion streaming on), lockstep
goes on. A stream silent for ``give_up_wall_s`` (3 s, as the bundled vehicle's lockstep) of wall
time while awake is gone, not late: time runs on (the firmware's own offboard-loss failsafe must
be able to act), until a newer setpoint arrives. A companion starved of CPU for a second on a busy
host is late, not gone: with 1 s the world once ran on without it.
Pure: the bridge passes the clocks; :mod:`.relay` extracts the stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["CompanionGate", "STREAM_GAP_S"]

STREAM_GAP_S = 0.1
"""a stream whose newest setpoint is older than this (firmware time) at a heartbeat has ended"""


@dataclass
class CompanionGate:
    lead_s: float
    """how far past the newest setpoint's stamp the firmware may run [s]; 0: no lockstep"""
    give_up_wall_s: float = 3.0
    setpoint_stamp_s: float = math.nan
    """firmware time of the telemetry the newest setpoint was computed from"""
    firmware_now_s: float = math.nan
    """the firmware's newest time, from its telemetry"""
    armed: bool = True
    """the firmware's heartbeat says armed (until one says otherwise)"""
    _commanded: bool = False
    _commanded_at_s: float = math.nan
    """the firmware's time when the command went through"""
    _given_up_on: float = math.nan
    _waiting_since_wall: float | None = None
    _awake_s: float = 0.0
    _checked_wall: float = 0.0
    waits: int = 0
    """times the world stopped for the companion"""
    waited_s: float = 0.0
    gave_up: int = 0
    gave_up_at_s: list[float] = field(default_factory=list)
    """the setpoint stamps given up on (the first few)"""

    def setpoint(self, stamp_s: float) -> None:
        """A setpoint arrived, computed from telemetry stamped ``stamp_s`` (0 or less: unstamped)."""
        if stamp_s > 0.0 and not stamp_s < self.setpoint_stamp_s:
            self.setpoint_stamp_s = stamp_s

    def command(self) -> None:
        """The companion sent a command (to land, to change mode): it may stop streaming on purpose,
        and the firmware must run to act on it, to its next heartbeat."""
        self._commanded = True
        self._commanded_at_s = self.firmware_now_s

    def heartbeat(self, armed: bool) -> None:
        """The firmware's heartbeat: armed or not; after a command, whether the stream goes on."""
        self.armed = armed
        if self._commanded and not self.firmware_now_s < self._commanded_at_s + STREAM_GAP_S:
            self._commanded = False
            if self.setpoint_stamp_s < self.firmware_now_s - STREAM_GAP_S:
                self._given_up_on = self.setpoint_stamp_s  # handed back: runs on until a newer setpoint

    def telemetry(self, stamp_s: float) -> None:
        if stamp_s > 0.0 and not stamp_s < self.firmware_now_s:
            self.firmware_now_s = stamp_s

    def may_advance(self, wall_s: float) -> bool:
        """Whether the world may take its next frame now (``wall_s``: a monotonic clock)."""
        if (self.lead_s <= 0.0 or not self.armed or self._commanded or math.isnan(self.setpoint_stamp_s)
                or self.setpoint_stamp_s == self._given_up_on):
            return self._resume(wall_s)
        if not self.firmware_now_s >= self.setpoint_stamp_s + self.lead_s:
            return self._resume(wall_s)
        if self._waiting_since_wall is None:
            self._waiting_since_wall = self._checked_wall = wall_s
            self._awake_s = 0.0
            self.waits += 1
        self._awake_s += min(wall_s - self._checked_wall, 0.02)  # a stall of the whole host is not the stream going
        self._checked_wall = wall_s
        if self._awake_s > self.give_up_wall_s:
            self._given_up_on = self.setpoint_stamp_s
            self.gave_up += 1
            if len(self.gave_up_at_s) < 10:
                self.gave_up_at_s.append(round(self.setpoint_stamp_s, 3))
            return self._resume(wall_s)
        return False

    def _resume(self, wall_s: float) -> bool:
        if self._waiting_since_wall is not None:
            self.waited_s += wall_s - self._waiting_since_wall
            self._waiting_since_wall = None
        return True
