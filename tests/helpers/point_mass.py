"""A position controller flying an ideal point mass along x: the plant of the control-core tests."""

from __future__ import annotations

import numpy as np

from companion.control.params import PositionGains
from companion.control.position import PositionController

G = 9.81
DEFAULT_GAINS = PositionGains()


def point_mass(kind: str, force_n: float, seconds: float = 20.0, dt: float = 0.01,
               gains: PositionGains = DEFAULT_GAINS, m: float = 0.63) -> tuple[np.ndarray, PositionController]:
    """``m r'' = m g e3 + f + h`` along x only (ideal actuator, accelerometer without noise), ``h`` a
    step of ``force_n`` at 1 s; the positions and the controller after ``seconds``."""
    ctrl = PositionController(kind, gains, m)
    x = v = 0.0
    applied = (0.0, 0.0, -m * G)
    xs = []
    for k in range(int(seconds / dt)):
        h = force_n if k * dt >= 1.0 else 0.0
        acc = (applied[0] + h) / m
        f = ctrl.update((x, 0.0, 0.0), (v, 0.0, 0.0), (0, 0, 0), (acc, 0.0, -G), applied, dt)
        applied = f
        v += (f[0] + h) / m * dt
        x += v * dt
        xs.append(x)
    return np.array(xs), ctrl
