"""Which engine steps a simulated vehicle: the compiled kernel or the objects.

The offline simulator (:mod:`sitl.lab.simulation`) flies whole flights on either; the MAVLink
vehicle steps its chunks between two decisions of its rules on either (:mod:`sitl.plant.chunk`).
Both read the choice here: ``$SITL_ENGINE``, else the compiled kernel where numba is installed and
compiles.
"""

from __future__ import annotations

import os

from companion.control.jit import numba_available

__all__ = ["ENGINES", "default_engine"]

ENGINES = ("compiled", "objects")


def default_engine() -> str:
    """``$SITL_ENGINE`` if set, else ``compiled`` when numba is installed and compiles
    (``NUMBA_DISABLE_JIT`` unset: the kernel run interpreted takes ~2.7x the objects' time, as
    in the mutation runs), else ``objects``."""
    jit = numba_available() and os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")
    name = os.environ.get("SITL_ENGINE") or ("compiled" if jit else "objects")
    if name not in ENGINES:
        raise ValueError(f"SITL_ENGINE={name!r}: expected one of {ENGINES}")
    return name
