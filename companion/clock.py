"""The vehicle's clock as seen from here: maps wall time to vehicle time and back.

Every timestamped telemetry message gives a pair (vehicle time, arrival wall time). Arrival is
always *late* by a varying transport delay, never early, so the line through the
**least-delayed** samples is the clock: the rate (vehicle seconds per wall second: 1 for a real
vehicle, the speed-up for the simulated one) is the slope between the least-delayed sample of
the older and of the newer half of a few seconds' window, and the anchor is the least-delayed
sample of the last second. Anchoring on the newest sample instead would pass every packet's
delay jitter straight into the control loop's tick times.

The control loop runs at a fixed rate *in vehicle time* by sleeping until :meth:`wall_at` its
next tick, and takes its ``dt`` from vehicle time, so the controller works at any speed-up.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["VehicleClock"]


class VehicleClock:
    def __init__(self, window_s: float = 4.0, anchor_window_s: float = 1.0) -> None:
        self.window_s = window_s
        self.anchor_window_s = anchor_window_s
        self._samples: deque[tuple[float, float]] = deque()
        self._rate = 1.0
        self._newest: tuple[float, float] | None = None
        self._anchor: tuple[float, float] | None = None
        self._dirty = False

    @property
    def ready(self) -> bool:
        return self._newest is not None

    def observe(self, vehicle_t: float, wall_t: float) -> None:
        if not math.isfinite(vehicle_t):
            return
        if self._newest is not None and vehicle_t < self._newest[0] - 1.0:
            self._samples.clear()  # the vehicle restarted: its clock jumped back
            self._newest = None
        if self._newest is not None and vehicle_t <= self._newest[0]:
            return
        self._newest = (vehicle_t, wall_t)
        s = self._samples
        s.append((vehicle_t, wall_t))
        while len(s) > 2 and wall_t - s[0][1] > self.window_s:
            s.popleft()
        self._dirty = True

    @property
    def rate(self) -> float:
        """Vehicle seconds per wall second."""
        self._anchor_now()
        return self._rate

    def _least_delayed(self, samples: list[tuple[float, float]]) -> tuple[float, float]:
        r = self._rate
        return min(samples, key=lambda vw: vw[1] - vw[0] / r)

    def _fit(self) -> None:
        s = list(self._samples)
        if len(s) >= 4 and s[-1][1] - s[0][1] > 0.5:
            mid = 0.5 * (s[0][1] + s[-1][1])
            old = self._least_delayed([x for x in s if x[1] < mid])
            new = self._least_delayed([x for x in s if x[1] >= mid])
            if new[1] - old[1] > 0.25:
                rate = (new[0] - old[0]) / (new[1] - old[1])
                if 0.01 < rate < 1000.0:
                    self._rate = rate
        assert self._newest is not None
        recent = [x for x in s if x[1] >= self._newest[1] - self.anchor_window_s] or [self._newest]
        self._anchor = self._least_delayed(recent)
        self._dirty = False

    def _anchor_now(self) -> tuple[float, float] | None:
        if self._newest is None:
            return None
        if self._dirty or self._anchor is None:
            self._fit()
        return self._anchor

    def now(self, wall_t: float) -> float:
        """Vehicle time at wall time ``wall_t`` (from the clock line, not the newest packet)."""
        a = self._anchor_now()
        if a is None:
            return -math.inf
        return a[0] + (wall_t - a[1]) * self._rate

    def wall_at(self, vehicle_t: float) -> float:
        """Wall time at which the vehicle's clock reaches ``vehicle_t``."""
        a = self._anchor_now()
        if a is None:
            return math.inf
        return a[1] + (vehicle_t - a[0]) / self._rate

    def age(self, vehicle_t: float, wall_t: float) -> float:
        """How old, in vehicle seconds, a sample stamped ``vehicle_t`` is at wall time ``wall_t``."""
        return self.now(wall_t) - vehicle_t
