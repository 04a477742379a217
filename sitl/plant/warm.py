"""``python -m sitl.plant.warm``: compile the bundled vehicle's kernel into the disk cache now.

The first ``sitl`` on a machine would otherwise compile it while it boots (~15 s, the kernel of
:mod:`sitl.plant.chunk`); ``make test`` runs this beside pytest's start-up, so that the vehicles
its tests boot wait for one compilation instead of each starting its own.
"""

from __future__ import annotations

import time

from companion.control.vector import ZERO3

from .scenario import Scenario
from .vehicle import SimVehicle

__all__ = ["main"]


def main() -> int:
    t0 = time.monotonic()
    v = SimVehicle(Scenario(name="warm-up"), "ism_do", 1, ZERO3, 0.0, hovering=False)
    if not v.compile_chunks():
        print("sitl.plant.warm: numba is not installed: the vehicle steps its objects")
        return 0
    print(f"sitl.plant.warm: the vehicle's kernel is compiled and cached ({time.monotonic() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
