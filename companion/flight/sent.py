"""What the flight has sent: how many setpoints, over which vehicle time, and how evenly in wall time."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["SentSetpoints", "MAX_PERIODS"]

MAX_PERIODS = 100_000
"""wall-clock spacings kept (the oldest half dropped past it): a long flight stays bounded"""


@dataclass
class SentSetpoints:
    count: int = 0
    first_t: float = math.nan
    """vehicle time of the first setpoint sent [s]"""
    last_t: float = math.nan
    """vehicle time of the newest setpoint sent [s]"""
    last_wall: float = math.nan
    periods_s: list[float] = field(default_factory=list, repr=False)
    """wall-clock spacing of consecutive setpoints [s] (the jitter benchmark's)"""

    def sent(self, t_s: float, wall_s: float) -> None:
        """One more setpoint, at vehicle time ``t_s`` and wall time ``wall_s``."""
        self.count += 1
        if math.isnan(self.first_t):
            self.first_t = t_s
        self.last_t = t_s
        if math.isfinite(self.last_wall):
            self.periods_s.append(wall_s - self.last_wall)
            if len(self.periods_s) > MAX_PERIODS:
                del self.periods_s[:MAX_PERIODS // 2]
        self.last_wall = wall_s

    def rate_hz(self) -> float | None:
        """Setpoints per vehicle second between the first and the newest (None: too few)."""
        if self.count > 1 and self.last_t > self.first_t:
            return (self.count - 1) / (self.last_t - self.first_t)
        return None

    def timing(self) -> dict[str, float]:
        """The median wall-clock spacing and the 99th percentile of its deviation from it [ms]."""
        periods = sorted(self.periods_s)
        if len(periods) <= 10:
            return {}
        med = periods[len(periods) // 2]
        return {"median_period_ms": 1000 * med,
                "p99_abs_jitter_ms": 1000 * sorted(abs(p - med) for p in periods)[int(0.99 * len(periods))]}
