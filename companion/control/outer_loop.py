"""The position loop of Fig. 3: measurement and reference in, attitude setpoint out.

One object that the offline simulator, the simulated vehicle's own position hold and the
companion process all run: position controller (section IV.A) -> force limits -> attitude and
thrust (32)-(33) -> rate command (34). It keeps the force it commanded so that the force
observer (30) is fed, at the next step, either that force ``f = -T R(q_d) e3`` (the paper's,
``force_source = "commanded"``) or the thrust along the measured attitude ``-T R(q) e3``
(``"measured"``): :func:`observer_force`.
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

__all__ = ["AttitudeSetpoint", "PositionMeasurement", "PositionLoop", "thrust_force", "observer_force"]


def thrust_force(thrust_n: Real, q: Quat) -> Vec3:
    """``-T R(q) e3``: collective thrust along the body's -z axis, in NED (3)."""
    return scale(-thrust_n, quat.rotate(q, E3))


def observer_force(force_source: str, thrust_n: Real, q_measured: Quat, q_commanded: Quat | None) -> Vec3:
    """The force that (30) subtracts: the commanded ``-T R(q_d) e3`` (the paper's) or the thrust
    along the measured attitude ``-T R(q) e3``; before any command, the measured one."""
    if force_source == "commanded" and q_commanded is not None:
        return thrust_force(thrust_n, q_commanded)
    return thrust_force(thrust_n, q_measured)


class AttitudeSetpoint(NamedTuple):
    """What SET_ATTITUDE_TARGET carries: attitude, body-rate feed-forward (in D) and thrust, and,
    where the position loop runs next to the attitude loop, the rate's derivative for (13)."""

    q_d: Quat
    omega_d_rad_s: Vec3
    thrust_n: Real
    omega_d_dot_rad_s2: Vec3 = ZERO3
    """(not on the wire: a vehicle flown over MAVLink gets zero)"""


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
    q_d: Quat | None = None
    """last commanded attitude (None before the first step): with ``thrust_n``, the commanded force"""
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
        self.q_d = None

    def update(self, meas: PositionMeasurement, ref: PositionReference, dt_s: float) -> AttitudeSetpoint:
        force_applied = observer_force(self.controller.gains.force_source, self.thrust_n, meas.q, self.q_d)
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
        q_d = self.rate_reference.q_ref or q_d
        self.force_n = f
        self.thrust_n = thrust
        self.q_d = q_d
        return AttitudeSetpoint(q_d, omega_d, thrust, self.rate_reference.omega_d_dot)
