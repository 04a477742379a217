"""Rigid-body quadrotor dynamics (3) with rotors, drag and ground, stepped at 1 kHz.

    m r''   = m g e3 - T R(q) e3 + R(q) F_drag + F_ext
    J w'    = tau - w x (J w) + p_cp x F_drag + tau_com + tau_ext
    q'      = 1/2 q ⊗ (0, w)

Semi-implicit Euler for velocities and positions, the exact exponential map for the quaternion
(which is renormalised every step, so it stays on the unit sphere), and the exact solution of
the first-order rotor lag. Components may be floats or batch arrays.

The law itself is :func:`sitl.plant.body.plant_step`, the one the compiled kernel flies:
:class:`Plant` holds the state and the parameters the live vehicle may change in flight.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from companion.control import quaternion as quat
from companion.control.params import VehicleParams
from companion.control.vector import ZERO3, Real, Vec3, sqrt

from .airframe import AirframeParams
from .body import PlantConst, RigidBody, plant_const, plant_step

__all__ = ["RigidBodyState", "Wrench", "Plant"]

_new = tuple.__new__

RigidBodyState = RigidBody
"""position, velocity, attitude (body FRD to NED), body rates, rotor speeds"""


class Wrench(NamedTuple):
    """What acted on the body during a step, for sensors, observers' ground truth and logs."""

    specific_force_body_m_s2: Vec3
    """(r'' - g e3) in body axes: what an ideal accelerometer reads"""
    thrust_n: Real
    disturbance_force_ned_n: Vec3
    """true lumped h_f: drag + external force"""
    disturbance_torque_nm: Vec3
    """true lumped h_tau: drag moment + centre-of-mass offset + external torque"""


@dataclass
class Plant:
    vehicle: VehicleParams
    airframe: AirframeParams
    state: RigidBodyState

    def __post_init__(self) -> None:
        """(Again after ``vehicle`` or ``airframe`` changed in flight.)"""
        self._const: PlantConst | None = None

    @staticmethod
    def at_rest(
        vehicle: VehicleParams, airframe: AirframeParams, pos_ned_m: Vec3, yaw_rad: Real = 0.0, hovering: bool = True
    ) -> Plant:
        """A plant at ``pos_ned_m``, level, rotors at hover speed (or stopped on the ground)."""
        w = sqrt(vehicle.weight_n / (4.0 * vehicle.k_thrust_n_s2)) if hovering else 0.0
        state = RigidBodyState(pos_ned_m, ZERO3, quat.from_yaw(yaw_rad), ZERO3, (w, w, w, w))
        return Plant(vehicle, airframe, state)

    def step(
        self,
        rotor_cmd_rad_s: tuple[Real, Real, Real, Real],
        wind_ned_m_s: Vec3,
        force_ext_ned_n: Vec3,
        torque_ext_body_nm: Vec3,
        dt_s: float,
    ) -> Wrench:
        """Advance ``dt_s`` with the rotor speed command held; returns the wrench that acted."""
        c = self._const
        if c is None or self._dt != dt_s:
            c = self._const = plant_const(self.vehicle, self.airframe, dt_s)
            self._dt = dt_s
        self.state, f = plant_step(c, self.state, rotor_cmd_rad_s, wind_ned_m_s, force_ext_ned_n,
                                   torque_ext_body_nm, dt_s)
        # tuple.__new__ skips the NamedTuple's Python-level __new__ (a measurable cost at 1 kHz)
        return _new(Wrench, (f.specific_force_body_m_s2, f.thrust_n, f.disturbance_force_ned_n,
                             f.disturbance_torque_nm))
