"""One plant step of the vehicle under its autopilot: the rules decide, the plant flies, the rules look.

The autopilot's rules (:class:`~sitl.autopilot.logic.Autopilot`) never step the physics; this is
the one place that does, with what the vehicle sensed handed to the rules before and after.
"""

from __future__ import annotations

from .logic import Autopilot
from .sensed import Sensed

__all__ = ["step"]


def step(ap: Autopilot) -> None:
    """Advance the vehicle one plant step flying the setpoint its autopilot chose."""
    vehicle = ap.vehicle
    vehicle.step(ap.decide(Sensed.of(vehicle)))
    ap.observe(Sensed.of(vehicle))
