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
    """A vehicle at 1x streaming at the loop's 100 Hz, then silent for 0.1 s."""
    async def main() -> tuple[list[tuple[bool, float]], int]:
        link, finished, ticks = vehicle(), asyncio.Event(), []
        ticker = Ticker(TickGrid(0.01), lambda: ticks.append((ticker.ticks_on_clock, link.state.t)))
        t0 = time.monotonic()
        sample(link, 0.0)
        run = asyncio.create_task(ticker.run(link, finished))
        for k in range(1, 21):
            await asyncio.sleep(t0 + 0.01 * k - time.monotonic())
            sample(link, round(time.monotonic() - t0, 3))
        streamed = list(ticks)
        await asyncio.sleep(0.1)
        finished.set()
        await run
        return streamed, ticks[len(streamed):]

    streamed, silent = asyncio.run(main())
    fired_by_samples = sum(1 for (n, _), (m, _) in zip(streamed, streamed[1:]) if m == n)
    assert fired_by_samples >= 15  # of 20 samples: each fires its own tick, bar a few late ones
    assert 6 <= len(silent) <= 11  # 0.1 s without samples: the clock line, one tick a period at most
    assert all(t == silent[0][1] for _, t in silent)  # each on the last sample


def test_a_ticks_error_ends_the_run_with_it():
    def tick() -> None:
        raise ValueError("the recorder's disk is full")

    async def main() -> None:
        link = vehicle()
        sample(link, 0.0)
        await asyncio.wait_for(Ticker(TickGrid(0.01), tick).run(link, asyncio.Event()), 2.0)

    with pytest.raises(ValueError, match="disk is full"):
        asyncio.run(main())
