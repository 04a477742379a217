"""Plant steps of the vehicle under its autopilot: the rules decide, the plant flies, the rules look.

The autopilot's rules (:class:`~sitl.autopilot.logic.Autopilot`) never step the physics; this is
the one place that does, with what the vehicle sensed handed to the rules before and after.
"""

from __future__ import annotations

from .logic import Autopilot
from .sensed import Sensed

__all__ = ["step"]


def step(ap: Autopilot, steps: int = 1) -> None:
    """Advance the vehicle ``steps`` plant steps flying the setpoint its autopilot chose for them
    (the rules run once per call: the live vehicle calls this at least at the position loop's rate)."""
    vehicle = ap.vehicle
    vehicle.step_many(ap.decide(Sensed.of(vehicle), steps), steps)
    ap.observe(Sensed.of(vehicle), steps)
