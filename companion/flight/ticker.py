"""Runs the flight's tick where its cause is: in the reader, once the sample for it has been read,
or on a timer at the clock line's time when the sample is missing.

No task is woken per tick: the link calls :meth:`Ticker.on_telemetry` when it has read what
arrived, and the tick (plain code, the flight's) runs there. When the tick grid
(:mod:`.pacing`) says the sample is in already, the tick runs on the event loop's next round, so
the reader always runs between two ticks. A tick's error ends :meth:`Ticker.run` with it, as the
flight's other tasks end theirs.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from companion.link.base import VehicleLink

from .pacing import TickGrid

__all__ = ["Ticker", "PRECISE_SLEEP_S"]

PRECISE_SLEEP_S = 0.0015
"""the last of a wait for the clock line slept blocking, where the line fires every tick: the
event loop's timers fire up to a millisecond late"""


class Ticker:
    def __init__(self, grid: TickGrid, tick: Callable[[], None]) -> None:
        self.grid = grid
        self.tick = tick
        """the flight's tick, at the grid's tick time (``grid.t_next``)"""
        self.ticks_on_clock = 0
        """ticks fired by the clock line because the sample for them had not arrived"""
        self._link: VehicleLink | None = None
        self._timer: asyncio.Handle | None = None
        """the next tick's: the clock line's timer, or a tick due soon (its sample is in)"""
        self._tick_soon = False
        self._wake = 0.0
        """wall time at which the next tick fires on the clock line"""
        self._failed: asyncio.Future[None] | None = None
        self._finished: asyncio.Event | None = None

    async def run(self, link: VehicleLink, finished: asyncio.Event) -> None:
        """Tick until ``finished`` (from when the link's clock first has a sample)."""
        clock, state = link.clock, link.state
        while not clock.ready and not finished.is_set():
            await asyncio.sleep(0.01)
        if finished.is_set():
            return
        self.grid.start(clock.now(time.monotonic()), state.t)
        self._link, self._finished = link, finished
        self._failed = asyncio.get_running_loop().create_future()
        link.on_telemetry = self.on_telemetry
        self._arm()
        ended = asyncio.ensure_future(finished.wait())
        try:
            await asyncio.wait((ended, self._failed), return_when=asyncio.FIRST_COMPLETED)
        finally:
            link.on_telemetry = None
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            ended.cancel()
        error = self._failed.exception() if self._failed.done() else None
        if error is not None:
            raise error

    def _arm(self) -> None:
        """Move the grid to the next tick: fire it soon if its sample is in, else arm the clock
        line's timer for when it is missing."""
        assert self._link is not None
        clock, state, grid = self._link.clock, self._link.state, self.grid
        loop = asyncio.get_running_loop()
        self._wake = grid.next_tick(clock, state.t, time.monotonic())
        self._tick_soon = grid.fires_on(state.t)
        if self._tick_soon:
            self._timer = loop.call_soon(self._fire, False)
        else:
            # where the clock line fires every tick (a stream slower than the loop) the last of the
            # wait is slept, blocking: at most a quarter of a tick (sped up, a tick is a few ms of
            # wall time). Where a sample is awaited, never: a sample arriving meanwhile would go
            # unread, and its tick fire without it.
            precise_s = 0.0 if grid.led_by_samples else min(PRECISE_SLEEP_S, 0.25 * grid.period_s / clock.rate)
            self._timer = loop.call_at(self._wake - precise_s, self._on_clock)

    def on_telemetry(self) -> None:
        """The reader took in a believed stamp: fire the tick it was waiting for."""
        timer, link = self._timer, self._link
        if timer is None or self._tick_soon or link is None or not self.grid.fires_on(link.state.t):
            return
        timer.cancel()
        self._fire(False)

    def _on_clock(self) -> None:
        """The clock line reached the tick (less the precise sleep) without its sample."""
        remaining = self._wake - time.monotonic()
        if remaining > 0:
            time.sleep(remaining)
        self.ticks_on_clock += 1
        self._fire(True)

    def _fire(self, on_clock: bool) -> None:
        self._timer = None
        failed = self._failed
        if failed is None or failed.done() or (self._finished is not None and self._finished.is_set()):
            return
        try:
            link, now = self._link, time.monotonic()
            assert link is not None
            self.grid.ticked(now, link.clock.now(now), link.state.t, on_clock)
            self.tick()
            self._arm()
        except Exception as exc:  # ends run() as the control task's own error would
            failed.set_exception(exc)
