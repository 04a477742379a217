"""A flight of the companion: the runner and its parts.

- :mod:`.runner` — :class:`Flight`: the tasks (reader, control loop, watchdog, mission);
- :mod:`.supervisor` — the judge: pure decisions from what was seen and the clock;
- :mod:`.pacing` — when the control loop ticks; :mod:`.control_time` — the controller's own time;
- :mod:`.steps` — what each kind of mission step does; :mod:`.prepare` — thrust scale and the
  autopilot parameters a flight changes (and puts back);
- :mod:`.offboard` — one control tick; :mod:`.guard` — what may be sent; :mod:`.thrust_scale`;
- :mod:`.recorder`, :mod:`.health` — the flight record; :mod:`.silence` — awake-counted silence.

:func:`run_flight` is the one entry the command line and the demo use.
"""

from __future__ import annotations

import asyncio
import signal
import sys

from .errors import EXIT_CODES, LinkLost, MissionAbort
from .runner import Flight, FlightOptions, FlightResult

__all__ = ["Flight", "FlightOptions", "FlightResult", "EXIT_CODES", "LinkLost", "MissionAbort", "run_flight"]


async def run_flight(flight: Flight, plots: bool) -> int:
    """Fly with Ctrl-C and SIGTERM handled (hold, land, disarm), print the summary, draw the plots;
    the exit code."""
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGINT, flight.interrupt)
    loop.add_signal_handler(signal.SIGTERM, flight.interrupt)
    result = await flight.run()
    if not (flight.folder / "summary.md").exists():  # it never reached a vehicle
        print(f"companion: {result.result}: {result.message}", file=sys.stderr, flush=True)
        return result.exit_code
    print((flight.folder / "summary.md").read_text())
    if plots:
        from companion.plots import draw_flight

        for p in draw_flight(flight.folder):
            print(f"plot: {p}")
    stream = sys.stdout if result.exit_code == 0 else sys.stderr
    print(f"companion: {result.result}: {result.message} -> {flight.folder}", file=stream, flush=True)
    return result.exit_code
