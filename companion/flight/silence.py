"""Silence on the link, counted only while this process was awake to hear it.

``now - last arrival`` counts a stall of this machine as silence: when the host deschedules
the whole VM for a second, both the vehicle (simulated on it) and this process stop, nothing is
sent, and on waking every wall-clock age reads one second old. Judged on that, the companion
paused its setpoints, commanded hold, and aborted flights that nothing had gone wrong with
(docs/faults.md). The watchdog wakes every few ms; each wake-up adds at most ``max_step_s`` of
silence, so a real outage (the watchdog running, nothing arriving) still counts at full speed,
and a stall counts as one step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["AwakeSilence"]


@dataclass
class AwakeSilence:
    max_step_s: float
    """the most one check may add: about twice the watchdog's period"""
    silent_s: float = 0.0
    _mark: float = -math.inf
    _checked: float = math.nan

    def check(self, last_arrival: float, now: float) -> float:
        """Silence [s] since ``last_arrival`` (wall), as this process saw it at ``now`` (wall)."""
        step = 0.0 if math.isnan(self._checked) else min(max(now - self._checked, 0.0), self.max_step_s)
        self._checked = now
        if last_arrival > self._mark:
            self._mark = last_arrival
            self.silent_s = min(now - last_arrival, self.max_step_s)
        else:
            self.silent_s += step
        return self.silent_s
