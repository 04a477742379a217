"""The position loop of Fig. 3: measurement and reference in, attitude setpoint out.

One object that the offline simulator, the simulated vehicle's own position hold and the
companion process all run: position controller (section IV.A) -> force limits -> attitude and
thrust (32)-(33) -> rate command (34). It keeps the thrust it commanded so that the force
observer is fed ``f_applied = -T R(q_measured) e3`` at the next step (30).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from . import quaternion as quat
from .params import PositionGains, ReferenceParams, VehicleParams
from .position import PositionController
from .quaternion import Quat
from .reference import RateReference, attitude_from_force, limit_force
from .trajectory import PositionReference
from .vector import E3, ZERO3, Real, Vec3, clip, scale, sub

__all__ = ["AttitudeSetpoint", "PositionMeasurement", "PositionLoop"]


class AttitudeSetpoint(NamedTuple):
    """What SET_ATTITUDE_TARGET carries: attitude, body-rate feed-forward (in D) and thrust."""

    q_d: Quat
    omega_d_rad_s: Vec3
    thrust_n: Real


class PositionMeasurement(NamedTuple):
    """The position loop's inputs; ``specific_force_ned_m_s2`` is ``r_dd - g e3`` or ``None``."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    q: Quat
    specific_force_ned_m_s2: Vec3 | None = None


@dataclass
class PositionLoop:
    controller: PositionController
    vehicle: VehicleParams
    """the controller's nominal vehicle: m0 and the thrust range"""
    reference: ReferenceParams = field(default_factory=ReferenceParams)
    force_n: Vec3 = ZERO3
    """last force after the tilt and direction limits"""
    thrust_n: Real = 0.0
    rate_reference: RateReference = field(init=False)

    def __post_init__(self) -> None:
        self.rate_reference = RateReference(self.reference)
        self._min_up_n = self.reference.min_up_force_fraction * self.vehicle.weight_n

    @classmethod
    def create(
        cls,
        kind: str,
        vehicle: VehicleParams,
        gains: PositionGains | None = None,
        reference: ReferenceParams | None = None,
    ) -> PositionLoop:
        ctrl = PositionController(kind, gains or PositionGains(), vehicle.mass_kg, vehicle.gravity_m_s2)
        return cls(ctrl, vehicle, reference or ReferenceParams())

    def reset(self) -> None:
        self.controller.reset()
        self.rate_reference.reset()
        self.force_n = ZERO3
        self.thrust_n = 0.0

    def update(self, meas: PositionMeasurement, ref: PositionReference, dt_s: float) -> AttitudeSetpoint:
        force_applied = scale(-self.thrust_n, quat.rotate(meas.q, E3))
        f = self.controller.update(
            sub(meas.pos_ned_m, ref.pos_ned_m),
            sub(meas.vel_ned_m_s, ref.vel_ned_m_s),
            ref.accel_ned_m_s2,
            meas.specific_force_ned_m_s2,
            force_applied,
            dt_s,
        )
        f = limit_force(f, self._min_up_n, self.reference.tilt_max_rad)
        q_d, thrust = attitude_from_force(f, ref.yaw_rad)
        thrust = clip(thrust, 0.0, self.vehicle.thrust_max_n)
        omega_d = self.rate_reference.update(q_d, dt_s)
        self.force_n = f
        self.thrust_n = thrust
        return AttitudeSetpoint(q_d, omega_d, thrust)
