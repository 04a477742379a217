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
from .jit import jitable
from .params import PositionGains, ReferenceParams, VehicleParams
from .position import PositionConst, PositionController, PositionState, position_step
from .quaternion import Quat
from .reference import RateConst, RateReference, RateState, attitude_from_force, limit_force, rate_step
from .trajectory import PositionReference
from .vector import E3, ZERO3, Real, Vec3, clip, scale, sub

__all__ = ["AttitudeSetpoint", "PositionMeasurement", "PositionLoop", "thrust_force", "observer_force",
           "LoopConst", "LoopState", "loop_const", "position_loop_step"]


@jitable
def thrust_force(thrust_n: Real, q: Quat) -> Vec3:
    """``-T R(q) e3``: collective thrust along the body's -z axis, in NED (3)."""
    return scale(-thrust_n, quat.rotate(q, E3))


def observer_force(force_source: str, thrust_n: Real, q_measured: Quat, q_commanded: Quat | None) -> Vec3:
    """The force that (30) subtracts: the commanded ``-T R(q_d) e3`` (the paper's) or the thrust
    along the measured attitude ``-T R(q) e3``; before any command, the measured one."""
    return _observer_force(force_source == "commanded", thrust_n, q_measured,
                           q_commanded if q_commanded is not None else q_measured, q_commanded is not None)


@jitable
def _observer_force(commanded: bool, thrust_n: Real, q_measured: Quat, q_commanded: Quat, has_command: bool) -> Vec3:
    if commanded and has_command:
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


class LoopConst(NamedTuple):
    position: PositionConst
    commanded_force: bool
    """the force observer subtracts the commanded force (``force_source = "commanded"``)"""
    min_up_n: Real
    tilt_max_rad: float
    thrust_max_n: float
    rate: RateConst


class LoopState(NamedTuple):
    position: PositionState
    force_n: Vec3
    """last force after the tilt and direction limits"""
    thrust_n: Real
    q_d: Quat
    """last commanded attitude (meaningless before the first step: ``has_q_d``)"""
    has_q_d: bool
    rate: RateState


def loop_const(position: PositionConst, gains: PositionGains, vehicle: VehicleParams, reference: ReferenceParams,
               rate: RateConst) -> LoopConst:
    return LoopConst(position, gains.force_source == "commanded", reference.min_up_force_fraction * vehicle.weight_n,
                     reference.tilt_max_rad, vehicle.thrust_max_n, rate)


@jitable
def position_loop_step(c: LoopConst, st: LoopState, pos_ned_m: Vec3, vel_ned_m_s: Vec3, q: Quat,
                       specific_force_ned_m_s2: Vec3, has_specific_force: bool,
                       ref: PositionReference) -> tuple[LoopState, AttitudeSetpoint]:
    """Fig. 3: controller -> limits -> (32), (33) -> (34): the new state and the setpoint."""
    force_applied = _observer_force(c.commanded_force, st.thrust_n, q, st.q_d, st.has_q_d)
    position, f = position_step(c.position, st.position, sub(pos_ned_m, ref.pos_ned_m),
                                sub(vel_ned_m_s, ref.vel_ned_m_s), ref.accel_ned_m_s2, specific_force_ned_m_s2,
                                has_specific_force, force_applied)
    f = limit_force(f, c.min_up_n, c.tilt_max_rad)
    q_d, thrust = attitude_from_force(f, ref.yaw_rad)
    thrust = clip(thrust, 0.0, c.thrust_max_n)
    rate = rate_step(c.rate, st.rate, q_d)
    q_d = rate.q_ref
    return (LoopState(position, f, thrust, q_d, True, rate),
            AttitudeSetpoint(q_d, rate.omega_d, thrust, rate.omega_d_dot))


@dataclass
class PositionLoop:
    """The position loop of Fig. 3 as an object: a thin wrapper around :func:`position_loop_step`
    whose state lives in ``controller``, ``rate_reference`` and the fields below."""

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
    _const: LoopConst | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.rate_reference = RateReference(self.reference)

    def const(self, dt_s: float) -> LoopConst:
        c = self._const
        if c is None or c.position.dt_s != dt_s:
            c = self._const = loop_const(self.controller.const(dt_s), self.controller.gains, self.vehicle,
                                         self.reference, self.rate_reference.const(dt_s))
        return c

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

    @property
    def state(self) -> LoopState:
        q_d = self.q_d
        return LoopState(self.controller.state, self.force_n, self.thrust_n, q_d if q_d is not None else quat.IDENTITY,
                         q_d is not None, self.rate_reference.state)

    @state.setter
    def state(self, st: LoopState) -> None:
        self.controller.state = st.position
        self.rate_reference.state = st.rate
        self.force_n, self.thrust_n = st.force_n, st.thrust_n
        self.q_d = st.q_d if st.has_q_d else None

    def update(self, meas: PositionMeasurement, ref: PositionReference, dt_s: float) -> AttitudeSetpoint:
        sf = meas.specific_force_ned_m_s2
        self.state, sp = position_loop_step(self.const(dt_s), self.state, meas.pos_ned_m, meas.vel_ned_m_s, meas.q,
                                            sf if sf is not None else ZERO3, sf is not None, ref)
        return sp
