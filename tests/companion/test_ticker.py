"""The ticker runs the flight's tick in the reader when the sample for it is in, on the clock line
when it is missing, and ends with a tick's error (companion/flight/ticker.py)."""

import asyncio
import time
from types import SimpleNamespace

import pytest

from companion.flight.pacing import TickGrid
from companion.flight.ticker import Ticker
from companion.link.clock import VehicleClock


def vehicle() -> SimpleNamespace:
    """What the ticker reads of a link: its clock, its state's newest stamp, the reader's hook."""
    return SimpleNamespace(clock=VehicleClock(), state=SimpleNamespace(t=0.0), on_telemetry=None)


def sample(link: SimpleNamespace, t: float) -> None:
    link.clock.observe(t, time.monotonic())
    link.state.t = t
    if link.on_telemetry is not None:
        link.on_telemetry()  # as the reader does once it has read what arrived


def test_each_sample_fires_its_tick_in_the_reader_and_a_missing_one_fires_on_the_clock():
    """Twenty samples, each a period on, each answered by its own tick inside the reader's call
    (no task to wake: the tick has run before the reader returns); then none for 0.1 s of wall
    time, and the clock line fires the ticks, at most one a period. No bound here depends on how
    busy the host is."""
    async def main() -> tuple[list[int], list[tuple[int, float]]]:
        link, finished, ticks = vehicle(), asyncio.Event(), []
        ticker = Ticker(TickGrid(0.01), lambda: ticks.append((ticker.ticks_on_clock, link.state.t)))
        sample(link, 0.0)
        run = asyncio.create_task(ticker.run(link, finished))
        await asyncio.sleep(0)  # the ticker starts
        in_the_reader = []
        for k in range(1, 21):
            before = len(ticks)
            sample(link, round(0.01 * k, 3))
            in_the_reader.append(len(ticks) - before)
        streamed = len(ticks)
        await asyncio.sleep(0.1)
        finished.set()
        await run
        return in_the_reader, ticks[streamed:]

    in_the_reader, silent = asyncio.run(main())
    assert in_the_reader == [1] * 20
    assert 1 <= len(silent) <= 11 and all(t == 0.2 for _, t in silent)  # on the clock, on the last sample
    assert [n for n, _ in silent] == list(range(1, len(silent) + 1))


def test_a_ticks_error_ends_the_run_with_it():
    def tick() -> None:
        raise ValueError("the recorder's disk is full")

    async def main() -> None:
        link = vehicle()
        sample(link, 0.0)
        await asyncio.wait_for(Ticker(TickGrid(0.01), tick).run(link, asyncio.Event()), 2.0)

    with pytest.raises(ValueError, match="disk is full"):
        asyncio.run(main())
