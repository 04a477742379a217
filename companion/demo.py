"""``companion demo``: the README's main job, headless and self-contained.

Starts the bundled simulated vehicle (``python -m sitl``) on a free local port, sped up, flies
``missions/hover45.toml`` (the 45 degree hover against the suspended weight, attached then
released) and ``missions/waypoints.toml`` with the companion over UDP, prints each flight's
summary and writes its record and plots under ``flights/``.
"""

from __future__ import annotations

import asyncio
import socket
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["run_demo", "start_vehicle", "MISSIONS_DIR"]

MISSIONS_DIR = Path(__file__).resolve().parents[1] / "missions"


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_vehicle(speedup: float, *extra: str) -> tuple[subprocess.Popen[str], int]:
    """The bundled vehicle in its own process; returns it and its UDP port once it listens."""
    port = _free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "sitl", "--listen", f"127.0.0.1:{port}", "--speedup", str(speedup), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    lines = []
    while proc.stdout and len(lines) < 5:  # "listening" comes last (after the signing notice, if any)
        lines.append(proc.stdout.readline())
        if "listening" in lines[-1] or not lines[-1]:
            break
    if not lines or "listening" not in lines[-1]:
        proc.kill()
        raise RuntimeError(f"the simulated vehicle did not start: {''.join(lines)}")
    return proc, port


def run_demo(out_dir: Path = Path("flights"), speedup: float = 4.0, controller: str = "ism_do") -> int:
    from .flight import Flight, FlightOptions, run_flight
    from .mission import load_mission

    status = 0
    for name in ("hover45", "waypoints"):
        mission = load_mission(MISSIONS_DIR / f"{name}.toml")
        # the vehicle waits for this process if the machine stalls it (sitl --wait-for-setpoints):
        # sped up 4x, a 0.3 s stall would otherwise be 1.2 s without setpoints and a failsafe
        proc, port = start_vehicle(speedup, "--wait-for-setpoints", "0.05")
        try:
            print(f"\n=== {name}: simulated vehicle on udp://127.0.0.1:{port}, {speedup:g}x ===", flush=True)
            t0 = time.monotonic()
            opts = FlightOptions(connect=f"udp://127.0.0.1:{port}", controller=controller, out_dir=out_dir)
            code = asyncio.run(run_flight(Flight(mission, opts), plots=True))
            print(f"({time.monotonic() - t0:.0f} s wall)")
            status = status or code
        finally:
            proc.terminate()
            proc.wait(timeout=10)
    return status
