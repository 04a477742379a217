"""When the control loop ticks: a fixed rate in vehicle time, led by the telemetry's stamps.

The tick grid never runs more than one tick ahead of the newest telemetry stamp, and a tick fires
as soon as the sample for it arrives; the vehicle clock line (:class:`~companion.link.clock.VehicleClock`)
is only the fallback when samples are missing, and then never faster than the rate in wall time.
So a real autopilot streaming at the loop's rate is ticked on each fresh sample, and a simulated
vehicle in lockstep (``sitl --lockstep``: it waits for the setpoint computed from its last sample)
is answered at once instead of after a wall-clock sleep. Pure: the runner reads the clocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["TickGrid", "TICK_TOLERANCE", "RESYNC_TICKS"]

TICK_TOLERANCE = 0.1
"""a sample stamped this fraction of a tick before the tick's time counts as the tick's sample
(stamps are whole milliseconds; the grid is not)"""
RESYNC_TICKS = 5
"""the grid resyncs when the clock line is this many ticks off it"""


@dataclass
class TickGrid:
    period_s: float
    t_next: float = math.nan
    """vehicle time of the next tick [s]"""
    last_tick_wall: float = -math.inf
    late_ticks: int = 0

    def start(self, line_now: float, newest: float) -> None:
        self.t_next = min(line_now, newest)

    def advance(self, newest: float) -> float:
        """The next tick's vehicle time: one period on, never more than a period past ``newest``."""
        self.t_next = min(self.t_next + self.period_s, newest + self.period_s)
        return self.t_next

    def due_stamp(self) -> float:
        """The stamp whose arrival fires the tick."""
        return self.t_next - TICK_TOLERANCE * self.period_s

    def fallback_wall(self, line_wall: float, rate: float) -> float:
        """Wall time at which to tick without a sample: the clock line's, but at most one tick per
        period of wall time at the vehicle's ``rate``."""
        return max(line_wall, self.last_tick_wall + self.period_s / max(rate, 1e-3))

    def rebase_if_line_moved_back(self, wake_wall: float, now_wall: float, rate: float, line_now: float,
                                  newest: float) -> bool:
        """The clock line re-anchored behind us (a vehicle that paused): tick from where it is."""
        if wake_wall - now_wall > RESYNC_TICKS * self.period_s / max(rate, 1e-3):
            self.t_next = min(line_now, newest) + self.period_s
            return True
        return False

    def ticked(self, now_wall: float, line_now: float, newest: float) -> None:
        """After a tick: if the line is far past the grid (a stalled vehicle or machine), skip ahead."""
        self.last_tick_wall = now_wall
        if line_now - self.t_next > RESYNC_TICKS * self.period_s:
            self.late_ticks += 1
            self.t_next = min(line_now, newest + self.period_s)
