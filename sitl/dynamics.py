"""Rigid-body quadrotor dynamics (3) with rotors, drag and ground, stepped at 1 kHz.

    m r''   = m g e3 - T R(q) e3 + R(q) F_drag + F_ext
    J w'    = tau - w x (J w) + p_cp x F_drag + tau_com + tau_ext
    q'      = 1/2 q ⊗ (0, w)

Semi-implicit Euler for velocities and positions, the exact exponential map for the quaternion
(which is renormalised every step, so it stays on the unit sphere), and the exact solution of
the first-order rotor lag. Components may be floats or batch arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from companion.control import quaternion as quat
from companion.control.allocation import Rotors4, wrench_from_rotor_speeds_sq
from companion.control.params import VehicleParams
from companion.control.quaternion import Quat
from companion.control.vector import (
    ZERO3,
    Real,
    Vec3,
    add,
    cross,
    exp,
    mul,
    norm,
    sub,
    where,
)

from .airframe import AirframeParams

__all__ = ["RigidBodyState", "Wrench", "Plant"]


class RigidBodyState(NamedTuple):
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    q: Quat
    """body (FRD) to NED"""
    omega_rad_s: Vec3
    """body rates, FRD"""
    rotor_speed_rad_s: Rotors4


class Wrench(NamedTuple):
    """What acted on the body during a step, for sensors, observers' ground truth and logs."""

    specific_force_body_m_s2: Vec3
    """(r'' - g e3) in body axes: what an ideal accelerometer reads"""
    thrust_n: Real
    torque_rotors_nm: Vec3
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
        v = self.vehicle
        self._dt = -1.0
        self._alpha: Real = 0.0
        self._inertia = v.inertia_kg_m2
        self._inv_inertia = (1.0 / v.inertia_kg_m2[0], 1.0 / v.inertia_kg_m2[1], 1.0 / v.inertia_kg_m2[2])
        self._inv_mass = 1.0 / v.mass_kg
        self._eff = self.airframe.motor_efficiency

    @staticmethod
    def at_rest(
        vehicle: VehicleParams, airframe: AirframeParams, pos_ned_m: Vec3, yaw_rad: Real = 0.0, hovering: bool = True
    ) -> Plant:
        """A plant at ``pos_ned_m``, level, rotors at hover speed (or stopped on the ground)."""
        w = (vehicle.weight_n / (4.0 * vehicle.k_thrust_n_s2)) ** 0.5 if hovering else 0.0
        state = RigidBodyState(pos_ned_m, ZERO3, quat.from_yaw(yaw_rad), ZERO3, (w, w, w, w))
        return Plant(vehicle, airframe, state)

    def step(
        self,
        rotor_cmd_rad_s: Rotors4,
        wind_ned_m_s: Vec3,
        force_ext_ned_n: Vec3,
        torque_ext_body_nm: Vec3,
        dt_s: float,
    ) -> Wrench:
        """Advance ``dt_s`` with the rotor speed command held; returns the wrench that acted."""
        af = self.airframe
        s = self.state
        if dt_s != self._dt:
            self._alpha = 1.0 - exp(-dt_s / af.rotor_time_constant_s)
            self._dt = dt_s
        a = self._alpha
        w = s.rotor_speed_rad_s
        w = (
            w[0] + a * (rotor_cmd_rad_s[0] - w[0]),
            w[1] + a * (rotor_cmd_rad_s[1] - w[1]),
            w[2] + a * (rotor_cmd_rad_s[2] - w[2]),
            w[3] + a * (rotor_cmd_rad_s[3] - w[3]),
        )
        e = self._eff
        torque_rot, thrust = wrench_from_rotor_speeds_sq(
            (e[0] * w[0] * w[0], e[1] * w[1] * w[1], e[2] * w[2] * w[2], e[3] * w[3] * w[3]), self.vehicle
        )

        q = s.q
        v_rel_body = quat.rotate_inverse(q, sub(s.vel_ned_m_s, wind_ned_m_s))
        airspeed = norm(v_rel_body)
        dl, dq = af.drag_linear_n_s_m, af.drag_quadratic_n_s2_m2
        drag_body = (
            -(dl[0] + dq * airspeed) * v_rel_body[0],
            -(dl[1] + dq * airspeed) * v_rel_body[1],
            -(dl[2] + dq * airspeed) * v_rel_body[2],
        )
        com = af.center_of_mass_offset_m
        # thrust acts at the geometric centre, -com from the CoM: (-com) x (0, 0, -T)
        torque_com = (com[1] * thrust, -com[0] * thrust, 0.0)
        torque_dist = add(add(cross(af.center_of_pressure_m, drag_body), torque_com), torque_ext_body_nm)
        force_dist = add(quat.rotate(q, drag_body), force_ext_ned_n)

        # translational: specific force in body = (-T e3 + drag) / m + R^T F_ext / m
        inv_m = self._inv_mass
        ext_body = quat.rotate_inverse(q, force_ext_ned_n)
        sf_body = (
            (drag_body[0] + ext_body[0]) * inv_m,
            (drag_body[1] + ext_body[1]) * inv_m,
            (drag_body[2] + ext_body[2] - thrust) * inv_m,
        )
        sf_ned = quat.rotate(q, sf_body)
        g = self.vehicle.gravity_m_s2
        vel = s.vel_ned_m_s
        vel = (vel[0] + sf_ned[0] * dt_s, vel[1] + sf_ned[1] * dt_s, vel[2] + (sf_ned[2] + g) * dt_s)
        pos = s.pos_ned_m
        pos = (pos[0] + vel[0] * dt_s, pos[1] + vel[1] * dt_s, pos[2] + vel[2] * dt_s)

        # rotational: J w' = tau - w x J w + h_tau
        om = s.omega_rad_s
        jw = mul(self._inertia, om)
        tau = add(sub(torque_rot, cross(om, jw)), torque_dist)
        ij = self._inv_inertia
        om = (om[0] + ij[0] * tau[0] * dt_s, om[1] + ij[1] * tau[1] * dt_s, om[2] + ij[2] * tau[2] * dt_s)
        q = quat.integrate(q, om, dt_s)

        pos, vel, q, om, sf_body = self._ground_contact(pos, vel, q, om, sf_body, thrust)
        self.state = RigidBodyState(pos, vel, q, om, w)
        return Wrench(sf_body, thrust, torque_rot, force_dist, torque_dist)

    def _ground_contact(
        self, pos: Vec3, vel: Vec3, q: Quat, om: Vec3, sf_body: Vec3, thrust: Real
    ) -> tuple[Vec3, Vec3, Quat, Vec3, Vec3]:
        """The ground holds the vehicle up: at or below ground level with thrust under the
        weight it rests, level, at its yaw, with no velocity; a ground reaction replaces the
        missing lift in the specific force."""
        ground = self.airframe.ground_z_m
        below = pos[2] >= ground
        if not (below is True or (type(below) is not bool and below.any())):  # type: ignore[union-attr]
            return pos, vel, q, om, sf_body
        resting = below & (thrust < self.vehicle.weight_n) if type(below) is not bool else (
            below and thrust < self.vehicle.weight_n
        )
        # touching down: cannot sink further
        pos = (pos[0], pos[1], where(below, ground, pos[2]))
        vz = where(below, where(vel[2] > 0.0, 0.0, vel[2]), vel[2])
        vel = (where(resting, 0.0, vel[0]), where(resting, 0.0, vel[1]), vz)
        yaw = quat.to_euler(q)[2]
        level = quat.from_yaw(yaw)
        q = (
            where(resting, level[0], q[0]),
            where(resting, level[1], q[1]),
            where(resting, level[2], q[2]),
            where(resting, level[3], q[3]),
        )
        om = (where(resting, 0.0, om[0]), where(resting, 0.0, om[1]), where(resting, 0.0, om[2]))
        g = self.vehicle.gravity_m_s2
        sf_body = (
            where(resting, 0.0, sf_body[0]),
            where(resting, 0.0, sf_body[1]),
            where(resting, -g, sf_body[2]),
        )
        return pos, vel, q, om, sf_body

