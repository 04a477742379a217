"""``companion demo``: the README's main job, headless and self-contained.

Starts the bundled simulated vehicle (``python -m sitl``, companion/vehicle_process.py) with the
paper's inner loop and in lockstep (the world advances as the companion's setpoints arrive, so a
busy machine makes the demo slower, never different), flies ``missions/hover45.toml`` (the 45
degree hover against the suspended weight, attached then released) and ``missions/waypoints.toml``
with the companion over UDP, prints each flight's summary and writes its record and plots under
``flights/``.

Ctrl-C reaches only the companion (the vehicle runs in a session of its own): it holds, lands and
disarms the vehicle, and the demo ends there instead of flying the next mission.
"""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

from .vehicle_process import VehicleProcess

__all__ = ["run_demo", "MISSIONS_DIR", "DEMO_MISSIONS"]

MISSIONS_DIR = Path(__file__).resolve().parents[1] / "missions"
DEMO_MISSIONS = ("hover45", "waypoints")
INTERRUPTED = 130


def run_demo(out_dir: Path = Path("flights"), speedup: float = 8.0, controller: str = "ism_do") -> int:
    from .flight import Flight, FlightOptions, run_flight
    from .mission import load_mission

    status = 0
    for name in DEMO_MISSIONS:
        mission = load_mission(MISSIONS_DIR / f"{name}.toml")
        vehicle = VehicleProcess("--flavour", "paper", "--lockstep", speedup=speedup)
        try:
            print(f"\n=== {name}: simulated vehicle on udp://{vehicle.url}, lockstep, up to {speedup:g}x ===",
                  flush=True)
            t0 = time.monotonic()
            opts = FlightOptions(connect=f"udp://{vehicle.url}", controller=controller, out_dir=out_dir,
                                 output="attitude_rates", mission_file=MISSIONS_DIR / f"{name}.toml")
            code = asyncio.run(run_flight(Flight(mission, opts), plots=True))
            print(f"({time.monotonic() - t0:.0f} s wall)", flush=True)
        finally:
            vehicle.stop()
        status = status or code
        if code == INTERRUPTED:
            print("companion: demo interrupted: the vehicle was landed; the remaining flights are not flown",
                  flush=True)
            return INTERRUPTED
    return status
