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
    exp,
    mat_t_vec,
    matvec,
    sqrt,
    where,
)

from .airframe import AirframeParams

__all__ = ["RigidBodyState", "Wrench", "Plant"]

_new = tuple.__new__


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
        w = sqrt(vehicle.weight_n / (4.0 * vehicle.k_thrust_n_s2)) if hovering else 0.0
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
        """Advance ``dt_s`` with the rotor speed command held; returns the wrench that acted.

        Written on unpacked components: this runs 1000 times per simulated second.
        """
        af = self.airframe
        s = self.state
        if dt_s != self._dt:
            self._alpha = 1.0 - exp(-dt_s / af.rotor_time_constant_s)
            self._dt = dt_s
        a = self._alpha
        w1, w2, w3, w4 = s.rotor_speed_rad_s
        c1, c2, c3, c4 = rotor_cmd_rad_s
        w1 += a * (c1 - w1)
        w2 += a * (c2 - w2)
        w3 += a * (c3 - w3)
        w4 += a * (c4 - w4)
        e1, e2, e3, e4 = self._eff
        (t_rx, t_ry, t_rz), thrust = wrench_from_rotor_speeds_sq(
            (e1 * w1 * w1, e2 * w2 * w2, e3 * w3 * w3, e4 * w4 * w4), self.vehicle
        )

        q = s.q
        rot = quat.to_rotmat(q)  # once per step: four vectors change frame below
        vx, vy, vz = s.vel_ned_m_s
        ux, uy, uz = wind_ned_m_s
        bx, by, bz = mat_t_vec(rot, (vx - ux, vy - uy, vz - uz))  # air-relative velocity, body
        airspeed = sqrt(bx * bx + by * by + bz * bz)
        dlx, dly, dlz = af.drag_linear_n_s_m
        dq = af.drag_quadratic_n_s2_m2 * airspeed
        dx, dy, dz = -(dlx + dq) * bx, -(dly + dq) * by, -(dlz + dq) * bz  # drag, body
        mx, my, _ = af.center_of_mass_offset_m
        px, py, pz = af.center_of_pressure_m
        tx, ty, tz = torque_ext_body_nm
        # drag moment p_cp x F_drag, plus thrust acting at the geometric centre, -com from the
        # CoM: (-com) x (0, 0, -T) = (com_y T, -com_x T, 0)
        torque_dist = (
            py * dz - pz * dy + my * thrust + tx,
            pz * dx - px * dz - mx * thrust + ty,
            px * dy - py * dx + tz,
        )
        fx, fy, fz = force_ext_ned_n
        gx, gy, gz = matvec(rot, (dx, dy, dz))
        hx, hy, hz = gx + fx, gy + fy, gz + fz  # lumped disturbance force h_f, NED

        # translational: m r'' = m g e3 - T R e3 + h_f; R e3 is the third column of R
        inv_m = self._inv_mass
        ax = (hx - thrust * rot[0][2]) * inv_m  # specific force, NED
        ay = (hy - thrust * rot[1][2]) * inv_m
        az = (hz - thrust * rot[2][2]) * inv_m
        if force_ext_ned_n is ZERO3:  # the common case: no external force to take to body axes
            sf_body = (dx * inv_m, dy * inv_m, (dz - thrust) * inv_m)
        else:
            ex, ey, ez = mat_t_vec(rot, force_ext_ned_n)
            sf_body = ((dx + ex) * inv_m, (dy + ey) * inv_m, (dz + ez - thrust) * inv_m)
        vx += ax * dt_s
        vy += ay * dt_s
        vz += (az + self.vehicle.gravity_m_s2) * dt_s
        rx, ry, rz = s.pos_ned_m
        pos = (rx + vx * dt_s, ry + vy * dt_s, rz + vz * dt_s)
        vel = (vx, vy, vz)

        # rotational: J w' = tau - w x J w + h_tau
        o0, o1, o2 = s.omega_rad_s
        j0, j1, j2 = self._inertia
        i0, i1, i2 = self._inv_inertia
        jw0, jw1, jw2 = j0 * o0, j1 * o1, j2 * o2
        h0, h1, h2 = torque_dist
        om = (
            o0 + i0 * (t_rx - (o1 * jw2 - o2 * jw1) + h0) * dt_s,
            o1 + i1 * (t_ry - (o2 * jw0 - o0 * jw2) + h1) * dt_s,
            o2 + i2 * (t_rz - (o0 * jw1 - o1 * jw0) + h2) * dt_s,
        )
        q = quat.integrate(q, om, dt_s)
        w = (w1, w2, w3, w4)

        if type(pos[2]) is not float or pos[2] >= af.ground_z_m:
            pos, vel, q, om, sf_body = self._ground_contact(pos, vel, q, om, sf_body, thrust)
        # tuple.__new__ skips the NamedTuples' Python-level __new__ (a measurable cost at 1 kHz)
        self.state = _new(RigidBodyState, (pos, vel, q, om, w))
        return _new(Wrench, (sf_body, thrust, (hx, hy, hz), torque_dist))

    def _ground_contact(
        self, pos: Vec3, vel: Vec3, q: Quat, om: Vec3, sf_body: Vec3, thrust: Real
    ) -> tuple[Vec3, Vec3, Quat, Vec3, Vec3]:
        """The ground holds the vehicle up: at or below ground level with thrust under the
        weight it rests, level, at its yaw, with no velocity; a ground reaction replaces the
        missing lift in the specific force."""
        ground = self.airframe.ground_z_m
        below = pos[2] >= ground
        if below is False or (type(below) is not bool and not below.any()):  # type: ignore[union-attr]
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

