"""The controller's time: vehicle time, but never further ahead of the newest telemetry than a
small lead.

The control loop ticks on a grid led by the telemetry's stamps (:class:`~.pacing.TickGrid`); when
samples are missing it falls back to the clock line (:class:`~companion.link.clock.VehicleClock`),
which extrapolates the vehicle's clock from past packets. Integrating the controller on that line
alone would assume the vehicle's clock kept running. A simulated vehicle may stop it (a stalled host, or
``sitl --wait-for-setpoints`` waiting for us); a real one never does, but its telemetry can stop
arriving. Either way, the reference and the integrators would then advance through time the
vehicle has not been seen to live: at 2 m/s, each 50 ms of such time puts the reference 10 cm
ahead of a vehicle that did not move.

So the controller's time is ``min(line, newest stamp + lead)``: on a healthy link the newest
stamp is a few ms old and the line decides (regular ticks); when telemetry stops, the
controller holds (the last setpoint is re-sent) once it is ``lead`` ahead of it, and when the
stamps move on it advances by exactly the vehicle time they moved, in sub-steps no longer than
1.5 ticks (an observer or integral stepped over a long dt could diverge). A gap longer than
``max_catch_up_s`` is not replayed: the reference pauses for the rest (a link outage; the
watchdog has paused the setpoints by then anyway).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ControllerTime", "default_lead_s"]


def default_lead_s(period_s: float) -> float:
    """Two ticks, at least 20 ms: telemetry is a few ms old on a healthy link at any speed-up."""
    return max(2.0 * period_s, 0.02)


@dataclass
class ControllerTime:
    period_s: float
    lead_s: float
    max_catch_up_s: float = 0.25
    t_s: float = math.nan
    """vehicle time the controller has been advanced to [s] (NaN: not started)"""
    held_ticks: int = 0
    """ticks with no new vehicle time to step (the last setpoint was re-sent)"""
    sub_steps: int = 0
    """extra controller steps taken to cover a gap longer than a tick"""
    dropped_s: float = 0.0
    """vehicle time not replayed after gaps longer than ``max_catch_up_s``"""

    def restart(self) -> None:
        self.t_s = math.nan

    def advance(self, t_line_s: float, t_newest_s: float) -> list[float]:
        """The steps [s] that bring the controller to ``min(t_line_s, t_newest_s + lead_s)``;
        empty when that is less than half a tick past where it is (hold)."""
        t = min(t_line_s, t_newest_s + self.lead_s)
        if not math.isfinite(t):
            return []
        if math.isnan(self.t_s):
            self.t_s = t
            return [self.period_s]
        gap = t - self.t_s
        if gap < 0.5 * self.period_s:
            self.held_ticks += 1
            return []
        self.t_s = t
        if gap > self.max_catch_up_s:
            self.dropped_s += gap - self.max_catch_up_s
            gap = self.max_catch_up_s
        n = max(1, round(gap / self.period_s))
        self.sub_steps += n - 1
        return [gap / n] * n
