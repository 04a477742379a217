"""The vehicle's clock as seen from here: maps wall time to vehicle time and back.

Every timestamped telemetry message gives a pair (vehicle time, arrival wall time). Arrival is
always *late* by a varying transport delay, never early, so the line through the
**least-delayed** samples is the clock: the rate (vehicle seconds per wall second: 1 for a real
vehicle, the speed-up for the simulated one) is the slope between the least-delayed sample of
the older and of the newer half of a few seconds' window, and the anchor is the least-delayed
sample of the last second. Anchoring on the newest sample instead would pass every packet's
delay jitter straight into the control loop's tick times.

Cost stays constant per packet however fast telemetry arrives: one sample is kept per 10 ms of
wall time (the least delayed of that bin), the anchor is updated as packets come, and the rate
is refitted at most ten times a second. After 50 ms without a sample the line is re-anchored on
the next one: a paused (simulated) vehicle resumes behind the old line, a link outage on it.
How late samples arrive after the line is kept as well (the latest arrival, forgotten by 5 % a
sample): it tells the control loop how long to wait for a sample before it ticks without it.
Stamps reach it only through :class:`~companion.link.stamps.StampGate` (no jumps, no other time
base). A sample that repeats the newest stamp after such a silence says the vehicle's clock stood still
(a simulated vehicle waiting for this process, see ``sitl --wait-for-setpoints``): the line is
re-anchored on it, so the waiting is not mistaken for telemetry growing old.

The control loop runs at a fixed rate *in vehicle time* by sleeping until :meth:`wall_at` its
next tick, and takes its ``dt`` from vehicle time, so the controller works at any speed-up.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["VehicleClock"]

BIN_S = 0.01
REFIT_S = 0.1
SILENCE_S = 0.05
"""wall seconds without a timestamped sample after which the clock line is re-anchored"""
LATE_DECAY = 0.95
"""per sample: how much of the latest lateness is still expected"""


class VehicleClock:
    def __init__(self, window_s: float = 4.0, anchor_window_s: float = 1.0) -> None:
        self.window_s = window_s
        self.anchor_window_s = anchor_window_s
        self._samples: deque[tuple[float, float]] = deque()
        self._rate = 1.0
        self._newest: tuple[float, float] | None = None
        self._anchor: tuple[float, float] | None = None
        self._last_fit = -math.inf
        self._lateness = 0.0

    def reset(self) -> None:
        """Forget the line: the vehicle's time base changed (it restarted). Only the stamp gate
        (:mod:`companion.link.stamps`) decides that; a stamp that merely goes back is never believed."""
        self._samples.clear()
        self._newest = self._anchor = None
        self._rate = 1.0
        self._last_fit = -math.inf
        self._lateness = 0.0

    @property
    def ready(self) -> bool:
        return self._newest is not None

    def _delay(self, sample: tuple[float, float]) -> float:
        """Arrival relative to the clock line (larger: later): wall - vehicle / rate."""
        return sample[1] - sample[0] / self._rate

    def observe(self, vehicle_t: float, wall_t: float) -> None:
        if not math.isfinite(vehicle_t):
            return
        if self._newest is not None and vehicle_t <= self._newest[0]:
            if vehicle_t == self._newest[0] and wall_t - self._newest[1] > SILENCE_S:
                self._samples.clear()  # the vehicle's clock stood still: it is now, here
                self._newest = self._anchor = (vehicle_t, wall_t)
                self._samples.append(self._newest)
            return
        sample = (vehicle_t, wall_t)
        if self._newest is not None and wall_t - self._newest[1] > SILENCE_S:
            # after a silence the old line may be off: a simulated vehicle that paused (a stalled
            # host) resumes behind it. Re-anchor on this sample; the rate stays until refitted.
            self._samples.clear()
            self._anchor = sample
        self._newest = sample
        s = self._samples
        if s and int(s[-1][1] / BIN_S) == int(wall_t / BIN_S):
            if self._delay(sample) < self._delay(s[-1]):
                s[-1] = sample  # one sample per bin: the least delayed
        else:
            s.append(sample)
            while len(s) > 2 and wall_t - s[0][1] > self.window_s:
                s.popleft()
        a = self._anchor
        if a is not None:
            self._lateness = max(wall_t - a[1] - (vehicle_t - a[0]) / self._rate, LATE_DECAY * self._lateness)
        if a is None or wall_t - a[1] > self.anchor_window_s or self._delay(sample) <= self._delay(a):
            self._anchor = sample if a is None or self._delay(sample) <= self._delay(a) else self._best_recent()

    def _best_recent(self) -> tuple[float, float]:
        assert self._newest is not None
        recent = [x for x in self._samples if x[1] >= self._newest[1] - self.anchor_window_s]
        return min(recent, key=self._delay) if recent else self._newest

    def _refit(self) -> None:
        """Rate from the least-delayed samples of the two halves of the window (bounded cost)."""
        assert self._newest is not None
        self._last_fit = self._newest[1]
        s = self._samples
        if len(s) >= 4 and s[-1][1] - s[0][1] > 0.5:
            mid = 0.5 * (s[0][1] + s[-1][1])
            old = min((x for x in s if x[1] < mid), key=self._delay)
            new = min((x for x in s if x[1] >= mid), key=self._delay)
            if new[1] - old[1] > 0.25:
                rate = (new[0] - old[0]) / (new[1] - old[1])
                if 0.01 < rate < 1000.0:
                    self._rate = rate
                    self._anchor = self._best_recent()

    def _anchor_now(self) -> tuple[float, float] | None:
        if self._newest is None:
            return None
        if self._newest[1] - self._last_fit > REFIT_S:
            self._refit()
        return self._anchor

    @property
    def rate(self) -> float:
        """Vehicle seconds per wall second."""
        self._anchor_now()
        return self._rate

    @property
    def lateness_s(self) -> float:
        """How long after the line the recent samples arrived, the latest counted most [wall s]."""
        return self._lateness

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
