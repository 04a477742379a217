"""Setpoint sanity checks: nothing leaves the companion that the vehicle should not fly."""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.control import quaternion as quat
from companion.control.quaternion import Quat
from companion.control.vector import Vec3

__all__ = ["SetpointGuard"]


@dataclass(frozen=True)
class SetpointGuard:
    max_tilt_rad: float = math.radians(60.0)
    max_rate_rad_s: float = math.radians(250.0)

    def check(self, q: Quat, body_rates_rad_s: Vec3, thrust: float) -> str | None:
        """Why this setpoint must not be sent, or None. Thrust is normalised."""
        values = (*q, *body_rates_rad_s, thrust)
        if not all(isinstance(v, float | int) and math.isfinite(v) for v in values):
            return "non-finite value"
        n = math.sqrt(sum(c * c for c in q))
        if abs(n - 1.0) > 1e-6:
            return f"quaternion norm {n:.6f}"
        if not 0.0 <= thrust <= 1.0:
            return f"thrust {thrust:.3f} outside [0, 1]"
        rate = math.sqrt(sum(w * w for w in body_rates_rad_s))
        if rate > self.max_rate_rad_s * (1.0 + 1e-9):
            return f"rate {math.degrees(rate):.0f} deg/s above {math.degrees(self.max_rate_rad_s):.0f}"
        tilt = quat.tilt_angle(q)
        if tilt > self.max_tilt_rad + 1e-9:
            return f"tilt {math.degrees(tilt):.1f} deg above {math.degrees(self.max_tilt_rad):.0f}"
        return None
