"""The vehicle's clock as seen from here: maps wall time to vehicle time and back.

Every timestamped telemetry message gives a pair (vehicle time, arrival wall time). The rate
(vehicle seconds per wall second: 1 for a real vehicle, the speed-up for the simulated one) is
the slope over a sliding window of about two wall seconds; the offset is anchored to the newest
sample. The control loop runs at a fixed rate *in vehicle time* by sleeping until
:meth:`VehicleClock.wall_at` its next tick, and takes its ``dt`` from vehicle time, so the same
controller works at any speed-up.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["VehicleClock"]


class VehicleClock:
    def __init__(self, window_s: float = 2.0) -> None:
        self.window_s = window_s
        self._samples: deque[tuple[float, float]] = deque()
        self.rate = 1.0
        self._anchor: tuple[float, float] | None = None

    @property
    def ready(self) -> bool:
        return self._anchor is not None

    def observe(self, vehicle_t: float, wall_t: float) -> None:
        if not math.isfinite(vehicle_t):
            return
        if self._anchor is not None and vehicle_t < self._anchor[0] - 1.0:
            self._samples.clear()  # the vehicle restarted: its clock jumped back
            self._anchor = None
        if self._anchor is not None and vehicle_t <= self._anchor[0]:
            return
        self._anchor = (vehicle_t, wall_t)
        s = self._samples
        s.append((vehicle_t, wall_t))
        while len(s) > 2 and wall_t - s[0][1] > self.window_s:
            s.popleft()
        if len(s) >= 2 and s[-1][1] - s[0][1] > 0.2:
            rate = (s[-1][0] - s[0][0]) / (s[-1][1] - s[0][1])
            if 0.01 < rate < 1000.0:
                self.rate = rate

    def now(self, wall_t: float) -> float:
        """Vehicle time at wall time ``wall_t`` (extrapolated from the newest sample)."""
        if self._anchor is None:
            return -math.inf
        v, w = self._anchor
        return v + (wall_t - w) * self.rate

    def wall_at(self, vehicle_t: float) -> float:
        """Wall time at which the vehicle's clock reaches ``vehicle_t``."""
        if self._anchor is None:
            return math.inf
        v, w = self._anchor
        return w + (vehicle_t - v) / self.rate

    def age(self, vehicle_t: float, wall_t: float) -> float:
        """How old, in vehicle seconds, a sample stamped ``vehicle_t`` is at wall time ``wall_t``."""
        return self.now(wall_t) - vehicle_t
