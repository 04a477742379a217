"""External forces and torques as functions of time (SPEC section 5).

A :class:`Profile` is one time function of a 3-vector: ``constant``, ``step`` (on at
``start_s``, off at ``stop_s``, with an optional linear ``rise_s``) or ``chirp`` (a sine whose
frequency sweeps linearly from ``f0_hz`` to ``f1_hz`` and whose amplitude goes linearly from
``value`` to ``value * end_scale`` between ``start_s`` and ``stop_s``). Several profiles add up.
Forces are in NED [N], torques in body axes [N m]. ``value`` components may be batch arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from companion.control.jit import depends_on, jitable
from companion.control.vector import ZERO3, Real, Vec3

depends_on(__file__)  # the compiled kernel (kernel.py) calls profile_factor

__all__ = ["PROFILE_KINDS", "Profile", "evaluate", "profile_factor"]

PROFILE_KINDS = ("constant", "step", "chirp")
"""in this order: a profile's kind is its index here where profiles are arrays (sitl/plant/kernel.py)"""
CONSTANT, STEP = 0, 1


@jitable
def profile_factor(kind: int, start_s: float, stop_s: float, rise_s: float, f0_hz: float, f1_hz: float,
                   end_scale: float, t_s: float) -> float:
    """The scalar multiplying a profile's value at ``t_s``: 1 (constant); 0 outside
    ``[start_s, stop_s)``; a step rising linearly over ``rise_s``; a chirp whose frequency sweeps
    linearly from ``f0_hz`` to ``f1_hz`` and whose amplitude goes from 1 to ``end_scale``."""
    if kind == CONSTANT:
        return 1.0
    if t_s < start_s or t_s >= stop_s:
        return 0.0
    tau = t_s - start_s
    if kind == STEP:
        return min(1.0, tau / rise_s) if rise_s > 0.0 else 1.0
    span = stop_s - start_s
    sweep = (f1_hz - f0_hz) / span
    phase = 2.0 * math.pi * (f0_hz * tau + 0.5 * sweep * tau * tau)
    amplitude = 1.0 + (end_scale - 1.0) * tau / span
    return amplitude * math.sin(phase)


@dataclass(frozen=True)
class Profile:
    kind: str = "step"
    value: Vec3 = ZERO3
    start_s: float = 0.0
    stop_s: float = math.inf
    rise_s: float = 0.0
    f0_hz: float = 0.1
    f1_hz: float = 1.0
    end_scale: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in PROFILE_KINDS:
            raise ValueError(f"kind: expected one of {', '.join(PROFILE_KINDS)}, got {self.kind!r}")
        if self.stop_s < self.start_s:
            raise ValueError(f"stop_s ({self.stop_s}) is before start_s ({self.start_s})")
        if self.kind == "chirp" and not math.isfinite(self.stop_s):
            raise ValueError("a chirp needs a finite stop_s (its sweep ends there)")

    def factor(self, t_s: float) -> float:
        """The scalar multiplying ``value`` at ``t_s`` (:func:`profile_factor`)."""
        return profile_factor(PROFILE_KINDS.index(self.kind), self.start_s, self.stop_s, self.rise_s, self.f0_hz,
                              self.f1_hz, self.end_scale, t_s)


def evaluate(profiles: Sequence[Profile], t_s: float) -> Vec3:
    """Sum of the profiles at ``t_s``."""
    if not profiles:
        return ZERO3
    x: Real = 0.0
    y: Real = 0.0
    z: Real = 0.0
    for p in profiles:
        k = p.factor(t_s)
        if k != 0.0:
            x = x + k * p.value[0]
            y = y + k * p.value[1]
            z = z + k * p.value[2]
    return (x, y, z)
