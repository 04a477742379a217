"""Online estimate of the vehicle's thrust scale (newtons at normalised thrust 1.0).

SET_ATTITUDE_TARGET carries normalised thrust ``u``; the controller computes newtons ``T`` and
sends ``u = T / T_max``. If ``T_max`` is wrong by a factor, the thrust that acts is
``k T`` with ``k = T_max,true / T_max``, and the force observer (30), which assumes ``T``, sees
the difference along the thrust direction ``b = -R(q) e3`` as a disturbance:
``h_hat = (k - 1) T b + h_ext``. Its **vertical** component is free of horizontal forces (wind, a
suspended weight), so in level or tilted flight with negligible vertical external force::

    k - 1 = h_hat_z / (T b_z)

The estimate low-passes that measurement (time constant ``time_constant_s``, much slower than
the observer) and, if ``adapt``, rescales ``T_max`` by it so the feed-forward is right and the
observer's vertical estimate returns to real external forces. In hover it cannot tell a thrust
error from a mass error or a steady vertical force: all three are "the model's weight-to-thrust
ratio", and correcting the scale absorbs them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.control import quaternion as quat
from companion.control.quaternion import Quat
from companion.control.vector import E3, Vec3

__all__ = ["ThrustScaleEstimator"]


@dataclass
class ThrustScaleEstimator:
    thrust_max_n: float
    """the scale in use: ``u = T / thrust_max_n``"""
    adapt: bool = True
    time_constant_s: float = 4.0
    min_vertical_thrust_n: float = 1.0
    limits: tuple[float, float] = (0.6, 1.4)
    """the adapted scale stays within these factors of the initial one"""

    def __post_init__(self) -> None:
        self.initial_n = self.thrust_max_n
        self.ratio = 1.0
        """filtered k: actual thrust / commanded thrust, for the scale in use"""
        self.samples = 0

    @property
    def estimated_thrust_max_n(self) -> float:
        """Best estimate of the true scale: the one in use times the measured ratio."""
        return self.thrust_max_n * self.ratio

    def normalise(self, thrust_n: float) -> float:
        return thrust_n / self.thrust_max_n

    def update(self, h_hat_ned_n: Vec3, q: Quat, thrust_cmd_n: float, dt_s: float) -> None:
        b = quat.rotate(q, (-E3[0], -E3[1], -E3[2]))
        vertical = thrust_cmd_n * b[2]  # negative: up
        if not (math.isfinite(h_hat_ned_n[2]) and vertical < -self.min_vertical_thrust_n):
            return
        measured = 1.0 + h_hat_ned_n[2] / vertical
        alpha = 1.0 - math.exp(-dt_s / self.time_constant_s)
        self.ratio += alpha * (measured - self.ratio)
        self.samples += 1
        if self.adapt:
            # move the scale in use towards the estimate at the same slow rate; the observer
            # then sees the remaining error shrink, so the measured ratio returns to 1
            lo, hi = self.limits
            new = min(max(self.thrust_max_n * (1.0 + alpha * (self.ratio - 1.0)), lo * self.initial_n),
                      hi * self.initial_n)
            self.ratio *= self.thrust_max_n / new
            self.thrust_max_n = new
