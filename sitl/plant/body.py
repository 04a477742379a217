"""The rigid body (3) with rotor lag, drag, centre-of-mass offset and ground contact: one step.

:func:`plant_step` is the one copy of the plant's law: the object-based plant
(:class:`sitl.plant.dynamics.Plant`, the live vehicle's, one vehicle on floats or a batch on
arrays) calls it, and the compiled kernel (:mod:`sitl.plant.kernel`) inlines it. Everything that
does not change in flight is a :class:`PlantConst` (built once by :func:`plant_const`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from companion.control import quaternion as quat
from companion.control.allocation import Rotors4, RotorModel, wrench_from_rotor_speeds_sq
from companion.control.jit import depends_on, jitable
from companion.control.quaternion import Quat
from companion.control.vector import Real, Vec3, any_of, is_scalar, mat_t_vec, matvec, sqrt, where

depends_on(__file__)

__all__ = ["PlantConst", "RigidBody", "Forces", "plant_const", "plant_step", "GROUND_SETTLE_S"]

GROUND_SETTLE_S = 0.03
"""time constant with which a vehicle resting on the ground settles level"""


class PlantConst(NamedTuple):
    mass_kg: float
    gravity_m_s2: float
    inertia_kg_m2: Vec3
    inv_inertia: Vec3
    rotors: RotorModel
    rotor_alpha: float
    """the first-order rotor lag over one step"""
    efficiency: Rotors4
    drag_linear_n_s_m: Vec3
    drag_quadratic_n_s2_m2: float
    center_of_pressure_m: Vec3
    center_of_mass_offset_m: Vec3
    ground_z_m: float
    weight_n: float
    ground_decel_m_s2: float


class RigidBody(NamedTuple):
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    q: Quat
    """body (FRD) to NED"""
    omega_rad_s: Vec3
    """body rates, FRD"""
    rotor_speed_rad_s: Rotors4


class Forces(NamedTuple):
    """What acted on the body during a step, for sensors, observers' ground truth and logs."""

    specific_force_body_m_s2: Vec3
    """(r'' - g e3) in body axes: what an ideal accelerometer reads"""
    thrust_n: float
    torque_rotors_nm: Vec3
    disturbance_force_ned_n: Vec3
    """true lumped h_f: drag + external force"""
    disturbance_torque_nm: Vec3
    """true lumped h_tau: drag moment + centre-of-mass offset + external torque"""


def plant_const(vehicle: object, airframe: object, dt_s: float) -> PlantConst:
    v, af = vehicle, airframe
    j = v.inertia_kg_m2  # type: ignore[attr-defined]
    return PlantConst(
        float(v.mass_kg), float(v.gravity_m_s2), j, (1.0 / j[0], 1.0 / j[1], 1.0 / j[2]),  # type: ignore[attr-defined]
        RotorModel.of(v), 1.0 - math.exp(-dt_s / af.rotor_time_constant_s),  # type: ignore[arg-type, attr-defined]
        tuple(float(e) for e in af.motor_efficiency), af.drag_linear_n_s_m,  # type: ignore[arg-type, attr-defined]
        float(af.drag_quadratic_n_s2_m2), af.center_of_pressure_m, af.center_of_mass_offset_m,  # type: ignore[attr-defined]
        float(af.ground_z_m), float(v.weight_n), float(af.ground_decel_m_s2))  # type: ignore[attr-defined]


@jitable
def plant_step(c: PlantConst, s: RigidBody, rotor_cmd_rad_s: Rotors4, wind_ned_m_s: Vec3, force_ext_ned_n: Vec3,
               torque_ext_body_nm: Vec3, dt_s: float) -> tuple[RigidBody, Forces]:
    """Advance ``dt_s`` with the rotor speed command held; the new body and what acted on it.

    Semi-implicit Euler for velocities and positions, the exact exponential map for the quaternion
    (renormalised every step), the exact solution of the first-order rotor lag.
    """
    a = c.rotor_alpha
    w1, w2, w3, w4 = s.rotor_speed_rad_s
    c1, c2, c3, c4 = rotor_cmd_rad_s
    w1 += a * (c1 - w1)
    w2 += a * (c2 - w2)
    w3 += a * (c3 - w3)
    w4 += a * (c4 - w4)
    e1, e2, e3, e4 = c.efficiency
    (t_rx, t_ry, t_rz), thrust = wrench_from_rotor_speeds_sq(
        (e1 * w1 * w1, e2 * w2 * w2, e3 * w3 * w3, e4 * w4 * w4), c.rotors)

    q = s.q
    rot = quat.to_rotmat(q)  # once per step: four vectors change frame below
    vx, vy, vz = s.vel_ned_m_s
    ux, uy, uz = wind_ned_m_s
    bx, by, bz = mat_t_vec(rot, (vx - ux, vy - uy, vz - uz))  # air-relative velocity, body
    airspeed = sqrt(bx * bx + by * by + bz * bz)  # not ** 0.5: CPython's pow() is off by an ulp
    dlx, dly, dlz = c.drag_linear_n_s_m
    dq = c.drag_quadratic_n_s2_m2 * airspeed
    dx, dy, dz = -(dlx + dq) * bx, -(dly + dq) * by, -(dlz + dq) * bz  # drag, body
    mx, my, _ = c.center_of_mass_offset_m
    px, py, pz = c.center_of_pressure_m
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
    inv_m = 1.0 / c.mass_kg
    ax = (hx - thrust * rot[0][2]) * inv_m  # specific force, NED
    ay = (hy - thrust * rot[1][2]) * inv_m
    az = (hz - thrust * rot[2][2]) * inv_m
    if is_scalar(fx) and fx == 0.0 and fy == 0.0 and fz == 0.0:  # the common case, 1 us a step in Python
        sf_body = (dx * inv_m, dy * inv_m, (dz - thrust) * inv_m)
    else:
        ex, ey, ez = mat_t_vec(rot, force_ext_ned_n)
        sf_body = ((dx + ex) * inv_m, (dy + ey) * inv_m, (dz + ez - thrust) * inv_m)
    vx += ax * dt_s
    vy += ay * dt_s
    vz += (az + c.gravity_m_s2) * dt_s
    rx, ry, rz = s.pos_ned_m
    pos = (rx + vx * dt_s, ry + vy * dt_s, rz + vz * dt_s)
    vel = (vx, vy, vz)

    # rotational: J w' = tau - w x J w + h_tau
    o0, o1, o2 = s.omega_rad_s
    j0, j1, j2 = c.inertia_kg_m2
    i0, i1, i2 = c.inv_inertia
    jw0, jw1, jw2 = j0 * o0, j1 * o1, j2 * o2
    h0, h1, h2 = torque_dist
    om = (
        o0 + i0 * (t_rx - (o1 * jw2 - o2 * jw1) + h0) * dt_s,
        o1 + i1 * (t_ry - (o2 * jw0 - o0 * jw2) + h1) * dt_s,
        o2 + i2 * (t_rz - (o0 * jw1 - o1 * jw0) + h2) * dt_s,
    )
    q = quat.integrate(q, om, dt_s)
    if any_of(pos[2] >= c.ground_z_m):  # a batch: element-wise, whoever is down
        pos, vel, q, om, sf_body = _ground_contact(c, pos, vel, q, om, sf_body, thrust, rot, dt_s, s.q, s.pos_ned_m)
    return (RigidBody(pos, vel, q, om, (w1, w2, w3, w4)),
            Forces(sf_body, thrust, (t_rx, t_ry, t_rz), (hx, hy, hz), torque_dist))


@jitable
def _ground_contact(c: PlantConst, pos: Vec3, vel: Vec3, q: Quat, om: Vec3, sf_body: Vec3,
                    thrust: Real, rot: object, dt_s: float, q_before: Quat, pos_before: Vec3
                    ) -> tuple[Vec3, Vec3, Quat, Vec3, Vec3]:
    """The ground holds the vehicle up. A body that reaches it sinking is decelerated at up to
    ``ground_decel_m_s2`` (it sinks a few millimetres meanwhile) and put back on the surface once
    stopped; with thrust under the weight it rests at its yaw, where it was at the step's start
    (friction holds it against wind and pushes), and settles level. The accelerometer feels what
    the ground did: the change of velocity it imposed in the step, ``R^T dv / dt``, on top of the
    other forces — at rest that is the reaction that replaces the missing lift (``-g`` along z_B),
    at a touchdown the deceleration that stopped the descent. At rest the ground holds it against
    the rotors' torques and it settles level from where the step began (``q_before``,
    :data:`GROUND_SETTLE_S`): its body rate, what the gyro reads, is that settling. Element-wise
    for a batch."""
    ground = c.ground_z_m
    below = pos[2] >= ground
    resting = below & (thrust < c.weight_n)
    vz_free = vel[2]
    slowed = vz_free - c.ground_decel_m_s2 * dt_s
    vz = where(below & (vz_free > 0.0), where(slowed > 0.0, slowed, 0.0), vz_free)
    pos = (where(resting, pos_before[0], pos[0]), where(resting, pos_before[1], pos[1]),
           where(below & (vz <= 0.0), ground, pos[2]))
    stopped = (where(resting, 0.0, vel[0]), where(resting, 0.0, vel[1]), vz)
    k = 1.0 / dt_s
    dv = ((stopped[0] - vel[0]) * k, (stopped[1] - vel[1]) * k, (stopped[2] - vel[2]) * k)
    felt = mat_t_vec(rot, dv)  # type: ignore[arg-type]
    sf_body = (sf_body[0] + felt[0], sf_body[1] + felt[1], sf_body[2] + felt[2])
    # a resting vehicle settles level on its legs within a few tens of milliseconds, turning at a
    # rate the gyro reads (levelled at once, unseen, PX4's EKF2 kept a landing's 19 deg of tilt
    # and its horizontal velocity ran away to 100 m/s on the ground); the ground holds it against
    # the rotors' torques, so only the settling turns it
    err = quat.log(quat.relative(q_before, quat.from_yaw(quat.to_euler(q_before)[2])))  # body axes, to level
    k = 1.0 / GROUND_SETTLE_S
    settle = (err[0] * k, err[1] * k, 0.0)
    q_settled = quat.integrate(q_before, settle, dt_s)
    q = (where(resting, q_settled[0], q[0]), where(resting, q_settled[1], q[1]), where(resting, q_settled[2], q[2]),
         where(resting, q_settled[3], q[3]))
    om = (where(resting, settle[0], om[0]), where(resting, settle[1], om[1]), where(resting, 0.0, om[2]))
    return pos, stopped, q, om, sf_body
