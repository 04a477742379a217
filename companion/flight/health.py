"""The companion's own health over a flight, one row every ``every_s`` vehicle seconds: memory,
CPU, the receive queue and how long datagrams waited in it, the oldest telemetry the controller
used, message and setpoint rates, late ticks and the vehicle's speed-up.

Long flights (and the soak benchmark) read it from the flight folder's ``health.csv`` to show
that memory stays flat, no queue grows and the loop rate does not drift.
"""

from __future__ import annotations

import math
import os
import resource
import time
from dataclasses import dataclass

__all__ = ["HealthMonitor", "HEALTH_COLUMNS", "rss_mb"]

HEALTH_COLUMNS = ("t_s", "wall_s", "rss_mb", "cpu_s", "rx_queue", "rx_lag_max_ms", "telemetry_age_max_ms",
                  "rx_per_s", "setpoints_per_s", "late_ticks", "vehicle_speedup")
"""rx_lag_max_ms: the longest a datagram waited in our queue before it was parsed [wall ms];
telemetry_age_max_ms: the oldest state a control tick used [vehicle ms] (both over the row's interval)"""

_PAGE_MB = os.sysconf("SC_PAGE_SIZE") / 2**20 if hasattr(os, "sysconf") else 4096 / 2**20


def rss_mb(pid: int | str = "self") -> float:
    """Resident memory now [MiB] (Linux /proc; elsewhere the peak, which only ever grows)."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * _PAGE_MB
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@dataclass
class HealthMonitor:
    every_s: float = 10.0
    _t_next: float = math.nan
    _last: tuple[float, float, int, int] | None = None
    """(vehicle t, wall, datagrams received, setpoints sent) at the previous row"""
    _wall0: float = math.nan
    _age_max_s: float = 0.0

    def observe_age(self, age_s: float) -> None:
        """The age of the state a control tick used [vehicle s]."""
        if math.isfinite(age_s) and age_s > self._age_max_s:
            self._age_max_s = age_s

    def sample(self, t_s: float, received: int, sent: int, rx_queue: int, late_ticks: int,
               rx_lag_max_s: float = 0.0) -> tuple | None:
        """A row when ``every_s`` vehicle seconds have passed since the last one, else None."""
        if not math.isfinite(t_s):
            return None
        if math.isnan(self._t_next):
            self._t_next = t_s + self.every_s
            self._wall0 = time.monotonic()
            self._last = (t_s, self._wall0, received, sent)
            return None
        if t_s < self._t_next:
            return None
        self._t_next += self.every_s * max(1, math.floor((t_s - self._t_next) / self.every_s) + 1)
        wall = time.monotonic()
        assert self._last is not None
        t0, wall0, rx0, sent0 = self._last
        self._last = (t_s, wall, received, sent)
        dt, dwall = max(t_s - t0, 1e-9), max(wall - wall0, 1e-9)
        age_max, self._age_max_s = self._age_max_s, 0.0
        return (round(t_s, 3), round(wall - self._wall0, 3), round(rss_mb(), 2), round(time.process_time(), 3),
                rx_queue, round(rx_lag_max_s * 1e3, 2), round(age_max * 1e3, 1),
                round((received - rx0) / dt, 1), round((sent - sent0) / dt, 2), late_ticks,
                round(dt / dwall, 3))
