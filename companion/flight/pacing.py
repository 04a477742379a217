"""When the control loop ticks: a fixed rate in vehicle time, led by the telemetry's stamps.

A tick fires as soon as the sample for it arrives, and the grid of ticks never runs more than one
tick ahead of the newest stamp. So a real autopilot streaming at the loop's rate is ticked on each
fresh sample, and a simulated vehicle in lockstep (``sitl --lockstep``: it waits for the setpoint
computed from its last sample) is answered at once instead of after a wall-clock sleep. The
vehicle clock line (:class:`~companion.link.clock.VehicleClock`) is the fallback when a sample is
missing; the rules below keep that fallback from firing ticks the samples should have fired:

- **Grace.** The line runs through the least-delayed arrivals, so most samples arrive after it:
  a tick waits a quarter of a tick past it, or as long as samples have lately been late.
- **A late sample is its tick's.** After a tick on the clock the grid stands one period on, so
  the late sample that arrives next does not fire another tick 0.2 ms later.
- **Lockstep.** Two cases look alike when a clock tick's sample then arrives: a real-time link
  whose sample was late, and a vehicle in lockstep that waited for this process (a slow answer, a
  stall) and has now answered the clock tick's setpoint. The second sends nothing more until it
  is answered again; with the grid a period on, every tick would then fire on the clock, and as
  the line learns that slower pace, ever later. So when the next tick fires on the clock as well
  and the stamp has moved one period since the last (the vehicle answers the clock ticks one by
  one), or the line has run far past the grid, the grid steps back to the newest stamp and the
  samples lead again. Either escape alone keeps lockstep at its pace; without both it slows to a
  crawl.
- **A slower stream leads nothing.** A stream slower than the loop (250 Hz on 100 Hz attitude)
  fires no tick: its samples, a few ms from the loop's ticks, would fire extra ones. The clock
  line fires every tick, each on the newest sample.

Pure: the ticker (:mod:`.ticker`) reads the clocks and arms the timer. Each rule is tested on
simulated streams in tests/companion/test_tick_grid.py; what they were found by is in
docs/faults.md, "The control loop's timing".
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Protocol

__all__ = ["TickGrid", "TICK_TOLERANCE", "RESYNC_TICKS", "GRACE_TICKS"]

TICK_TOLERANCE = 0.1
"""a sample stamped this fraction of a tick before the tick's time counts as the tick's sample
(stamps are whole milliseconds; the grid is not)"""
RESYNC_TICKS = 5
"""the grid resyncs when the clock line is this many ticks off it"""
GRACE_TICKS = 0.25
"""how long past the clock line a tick waits for its sample before it fires without it, at least
[ticks]; and at least as long as most samples arrive after the line (it runs through the
least-delayed arrivals), at most :data:`RESYNC_TICKS`"""


STREAM_MOVES = 9
"""the stamp moves the stream's period is the median of"""
SLOWER_STREAM = 1.5
"""a stream whose period is this many ticks or more leads no tick: the clock line fires them all"""


class ClockLine(Protocol):
    """What the grid reads of :class:`~companion.link.clock.VehicleClock`."""

    @property
    def rate(self) -> float: ...

    @property
    def lateness_s(self) -> float: ...

    def now(self, wall_t: float) -> float: ...

    def wall_at(self, vehicle_t: float) -> float: ...


@dataclass
class TickGrid:
    period_s: float
    t_next: float = math.nan
    """vehicle time of the next tick [s]"""
    last_tick_wall: float = -math.inf
    late_ticks: int = 0
    clock_tick_newest: float = math.nan
    """the newest stamp when the last tick fired on the clock line (NaN: its sample fired it)"""
    follow_clock: bool = False
    """the grid may run ahead of the newest stamp: the last tick fired on the clock, and the vehicle
    is not answering clock ticks one by one"""
    stream_period_s: float = math.nan
    """how far the newest stamp moves between ticks that see it move (the median of the last few):
    the telemetry's period as this loop sees it"""
    _moves: deque[float] = field(default_factory=lambda: deque(maxlen=STREAM_MOVES), repr=False)
    _seen: float = math.nan
    line_ahead: bool = False
    """the clock line ran far past the grid (a vehicle that slowed down: lockstep starting after a
    faster stretch, a stalled host) and no sample has fired a tick since: the line's rate does not
    describe the vehicle now, so a tick on it also waits the grace for its sample"""

    def start(self, line_now: float, newest: float) -> None:
        self.t_next = min(line_now, newest)

    def advance(self, newest: float) -> float:
        """The next tick's vehicle time: one period on, never more than a period past ``newest``
        (while following the clock line, never more than :data:`RESYNC_TICKS`)."""
        lead = RESYNC_TICKS if self.follow_clock else 1
        self.t_next = min(self.t_next + self.period_s, newest + lead * self.period_s)
        return self.t_next

    def due_stamp(self) -> float:
        """The stamp whose arrival fires the tick."""
        return self.t_next - TICK_TOLERANCE * self.period_s

    @property
    def led_by_samples(self) -> bool:
        """Samples fire the ticks: the stream is as fast as the loop (or a vehicle in lockstep that
        answers each tick). A slower stream does not: its samples, a few ms apart from the loop's
        ticks, would fire extra ones; the clock line fires every tick, and each takes the newest
        sample."""
        return not self.stream_period_s >= SLOWER_STREAM * self.period_s

    def fires_on(self, newest: float) -> bool:
        """Whether the sample stamped ``newest`` fires the next tick now."""
        return newest >= self.due_stamp() and self.led_by_samples

    def grace_wall(self, rate: float, lateness_s: float) -> float:
        """How long after the clock line the tick waits for its sample [wall s]."""
        if not self.led_by_samples:
            return 0.0  # no sample to wait for: the ticks keep the line's time
        wall_period = self.period_s / max(rate, 1e-3)
        return min(max(GRACE_TICKS * wall_period, lateness_s), RESYNC_TICKS * wall_period)

    def fallback_wall(self, line_wall: float, rate: float, grace_s: float = 0.0) -> float:
        """Wall time at which to tick without a sample: ``grace_s`` after the clock line's, but no
        sooner than (almost) a period of wall time at the vehicle's ``rate`` after the last tick
        (and the grace on top while the line is ahead of the vehicle). Almost: a tick fired a
        little late must not delay every later one."""
        wall_period = self.period_s / max(rate, 1e-3)
        soonest = self.last_tick_wall + (1 - TICK_TOLERANCE) * wall_period + (grace_s if self.line_ahead else 0.0)
        return max(line_wall + grace_s, soonest)

    def next_tick(self, clock: ClockLine, newest: float, now_wall: float) -> float:
        """Move to the next tick; the wall time to fire it on the clock line if its sample
        (:meth:`due_stamp`) has not arrived by then. If the line re-anchored far behind us (a
        vehicle that paused), the grid ticks from where the line is."""
        t_next = self.advance(newest)
        rate = clock.rate
        grace = self.grace_wall(rate, clock.lateness_s)
        line_wall = clock.wall_at(t_next)
        if line_wall - now_wall > RESYNC_TICKS * self.period_s / max(rate, 1e-3):
            self.t_next = min(clock.now(now_wall), newest) + self.period_s
            return clock.wall_at(self.t_next) + grace
        return self.fallback_wall(line_wall, rate, grace)

    def ticked(self, now_wall: float, line_now: float, newest: float, on_clock: bool = False) -> None:
        """After a tick (``on_clock``: fired by the clock line, its sample not in): whether the grid
        may run ahead of the stamps; if the line is far past the grid (a stalled vehicle or
        machine), skip ahead."""
        # the vehicle answered the last clock tick's setpoint with the sample one period on, and
        # this tick is on the clock again: it waits for each setpoint (lockstep)
        answered = newest >= self.clock_tick_newest + (1 - TICK_TOLERANCE) * self.period_s
        self.follow_clock = on_clock and not (answered and self.led_by_samples)
        self.clock_tick_newest = newest if on_clock else math.nan
        self.last_tick_wall = now_wall
        if not newest <= self._seen:  # a newer stamp than any seen (or the first: NaN)
            if not math.isnan(self._seen):
                self._moves.append(newest - self._seen)
                self.stream_period_s = sorted(self._moves)[len(self._moves) // 2]
            self._seen = newest
        if not on_clock:
            self.line_ahead = False
        if line_now - self.t_next > RESYNC_TICKS * self.period_s:
            self.late_ticks += 1
            self.line_ahead = True
            self.follow_clock = False  # a line this far off is not followed: the samples lead
            self.t_next = min(line_now, newest + self.period_s)
