"""The bundled vehicle with its pieces timed in place (CPU time of each call), for bench_lockstep.

    python benchmarks/timed_vehicle.py OUT.json -m sitl [sitl's options]

runs ``sitl`` as ``python -m sitl`` would; at each SIGUSR1 it notes the CPU seconds and calls of each
piece so far, the process's CPU and the simulated time, and on exit writes those marks to OUT.json
(bench_lockstep marks the companion taking control and the flight's end). The pieces: plant (the
plant steps between two decisions of the rules, ``SimVehicle.step_many``), rules (the autopilot's
decide and observe), telemetry (the streams due: encode, pack, coalesce), send (the ``sendto``
calls, of coalesced frames), receive (datagrams in: parse and handle); the rest is the event loop,
the pacing, the guard.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

Piece = tuple[str, str | None, str]
"""(module, class or None for a module's function, function): a piece timed in place"""

PIECES: dict[str, Piece] = {  # piece: (module, class, method) timed in place
    "plant": ("sitl.plant.vehicle", "SimVehicle", "step_many"),
    "rules": ("sitl.autopilot.logic", "Autopilot", "decide"),
    "rules ": ("sitl.autopilot.logic", "Autopilot", "observe"),
    "telemetry": ("sitl.autopilot.server", "MavlinkServer", "_telemetry_tick"),
    "send": ("companion.mavlink.udp", "UdpEndpoint", "_send_now"),
    "receive": ("sitl.autopilot.server", "MavlinkServer", "datagram_received"),
}


def time_in_place(pieces: dict[str, Piece]) -> tuple[dict[str, list[float]], list[tuple[Any, str, Any]]]:
    """Wrap each piece's function so that every call adds its CPU seconds and one call to the
    piece's tally; (the tallies, what :func:`put_back` restores). bench_lockstep times the
    companion's pieces with it too."""
    import importlib
    spent: dict[str, list[float]] = {}
    undo = []
    for piece, (module, cls, name) in pieces.items():
        owner = getattr(importlib.import_module(module), cls) if cls else importlib.import_module(module)
        original = getattr(owner, name)
        acc = spent[piece] = [0.0, 0]

        def timed(*args: Any, _f: Callable[..., Any] = original, _acc: list[float] = acc, **kw: Any) -> Any:
            c0 = time.process_time()
            try:
                return _f(*args, **kw)
            finally:
                _acc[0] += time.process_time() - c0
                _acc[1] += 1
        setattr(owner, name, timed)
        undo.append((owner, name, original))
    return spent, undo


def put_back(undo: list[tuple[Any, str, Any]]) -> None:
    for owner, name, original in undo:
        setattr(owner, name, original)


def main() -> int:
    out = Path(sys.argv[1])
    if sys.argv[2:4] != ["-m", "sitl"]:
        raise SystemExit("usage: timed_vehicle.py OUT.json -m sitl [options]")
    spent, _ = time_in_place(PIECES)
    from sitl.autopilot import server as server_module
    from sitl.cli import main as sitl_main

    servers: list[Any] = []
    original_init = server_module.MavlinkServer.__init__

    def keep(self: Any, *args: Any, **kw: Any) -> None:
        original_init(self, *args, **kw)
        servers.append(self)
    server_module.MavlinkServer.__init__ = keep  # type: ignore[method-assign]
    marks: list[dict[str, Any]] = []

    def mark(*_: Any) -> None:
        """SIGUSR1: the pieces so far, the process's CPU and the simulated time, kept for OUT.json."""
        pieces = {p.strip(): [0.0, 0] for p in spent}
        for p, (cpu, n) in spent.items():
            pieces[p.strip()][0] += cpu
            pieces[p.strip()][1] += int(n)
        marks.append({"pieces": pieces, "cpu_s": time.process_time(), "sim_s": servers[0].ap.t if servers else 0.0})
    signal.signal(signal.SIGUSR1, mark)
    code = sitl_main(sys.argv[4:])
    out.write_text(json.dumps({"marks": marks}))
    return code


if __name__ == "__main__":
    raise SystemExit(main())
