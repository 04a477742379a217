"""Control allocation (4) for the "+" quadrotor in FRD, both directions.

Rotors sit on the body axes at distance ``L``, numbered counter-clockwise seen from above
starting at +x: 1 front (+x), 2 left (-y), 3 back (-x), 4 right (+y). Rotor ``i`` pushes
``F_i = k_F w_i^2`` along ``-z_B`` from position ``p_i``, so its moment is
``p_i x (0, 0, -F_i) = (-p_y F_i, p_x F_i, 0)``. Rotors 1 and 3 spin clockwise seen from above
(angular velocity along +z_B, reaction torque ``-k_Q w^2`` about z_B), rotors 2 and 4
counter-clockwise (``+k_Q w^2``). With ``W_i = w_i^2``::

    tau_x = L k_F (W2 - W4)        left rotor up  -> roll right  (+x)
    tau_y = L k_F (W1 - W3)        front rotor up -> nose up     (+y)
    tau_z = k_Q (-W1 + W2 - W3 + W4)                             yaw right (+z, down)
    T     = k_F (W1 + W2 + W3 + W4)

This is (4) with the roll row's sign flipped by the FRD y axis. The "x" layout is the same four
rotors turned by -45 degrees about z_B (rotor 1 front-left, 2 back-left, 3 back-right, 4
front-right, the same spin directions): a moment is linear in the rotor positions, so its
torque is the "+" torque turned by the same angle, ``tau_xy' = R_z(-45 deg) tau_xy`` (PX4's and
ArduPilot's quad X motors 1-4 are rotors 4, 2, 1, 3). The plant calls
:func:`wrench_from_rotor_speeds` (the physics) and the onboard loop :func:`rotor_speeds_sq_for`
(the mixer): the matrix exists once.
"""

from __future__ import annotations

from typing import NamedTuple, Union

from .jit import jitable
from .params import VehicleParams
from .vector import Real, Vec3, clip

__all__ = [
    "Rotors4",
    "wrench_from_rotor_speeds_sq",
    "wrench_from_rotor_speeds",
    "rotor_speeds_sq_for",
    "allocate",
    "RotorModel",
]

Rotors4 = tuple[Real, Real, Real, Real]


class RotorModel(NamedTuple):
    """The rotor constants of :class:`~companion.control.params.VehicleParams`, by the same names, as
    a tuple for compiled code: the functions below take either."""

    k_thrust_n_s2: float
    k_torque_nm_s2: float
    arm_length_m: float
    rotor_speed_min_rad_s: float
    rotor_speed_max_rad_s: float
    layout_cos: float
    layout_sin: float
    """the layout's turn about z_B (:attr:`VehicleParams.layout`): (1, 0) for the "plus" layout"""

    @staticmethod
    def of(vehicle: VehicleParams) -> RotorModel:
        v = vehicle
        return RotorModel(v.k_thrust_n_s2, v.k_torque_nm_s2, v.arm_length_m, v.rotor_speed_min_rad_s,
                          v.rotor_speed_max_rad_s, v.layout_cos, v.layout_sin)


Rotors = Union[VehicleParams, RotorModel]


@jitable
def wrench_from_rotor_speeds_sq(w_sq: Rotors4, vehicle: Rotors) -> tuple[Vec3, Real]:
    """Body torque [N m] and collective thrust [N] of squared rotor speeds, (4)."""
    kf, kq, arm = vehicle.k_thrust_n_s2, vehicle.k_torque_nm_s2, vehicle.arm_length_m
    w1, w2, w3, w4 = w_sq
    tx, ty = arm * kf * (w2 - w4), arm * kf * (w1 - w3)
    s = vehicle.layout_sin
    if s != 0.0:  # the "x" layout: the "+" moment turned about z_B
        c = vehicle.layout_cos
        tx, ty = c * tx - s * ty, s * tx + c * ty
    return (tx, ty, kq * (-w1 + w2 - w3 + w4)), kf * (w1 + w2 + w3 + w4)


@jitable
def wrench_from_rotor_speeds(w: Rotors4, vehicle: Rotors) -> tuple[Vec3, Real]:
    """As :func:`wrench_from_rotor_speeds_sq`, from rotor speeds [rad/s]."""
    return wrench_from_rotor_speeds_sq((w[0] * w[0], w[1] * w[1], w[2] * w[2], w[3] * w[3]), vehicle)


@jitable
def rotor_speeds_sq_for(torque_nm: Vec3, thrust_n: Real, vehicle: Rotors) -> Rotors4:
    """``Omega = B^-1 u``, solved analytically (unclipped, may leave the rotors' range)."""
    kf, kq, arm = vehicle.k_thrust_n_s2, vehicle.k_torque_nm_s2, vehicle.arm_length_m
    a = thrust_n / kf
    tx, ty = torque_nm[0], torque_nm[1]
    s = vehicle.layout_sin
    if s != 0.0:  # the "x" layout: turn the moment back onto the "+" rotors
        c = vehicle.layout_cos
        tx, ty = c * tx + s * ty, -s * tx + c * ty
    x = tx / (arm * kf)
    y = ty / (arm * kf)
    z = torque_nm[2] / kq
    front_back = 0.25 * (a - z)
    left_right = 0.25 * (a + z)
    return (front_back + 0.5 * y, left_right + 0.5 * x, front_back - 0.5 * y, left_right - 0.5 * x)


@jitable
def allocate(torque_nm: Vec3, thrust_n: Real, vehicle: Rotors) -> tuple[Rotors4, Vec3, Real]:
    """Squared rotor speeds clipped to the rotors' range, and the wrench they actually produce.

    The disturbance observers must be fed the applied torque and thrust (SPEC section 1), which
    differ from the request whenever a rotor saturates.
    """
    lo = vehicle.rotor_speed_min_rad_s ** 2
    hi = vehicle.rotor_speed_max_rad_s ** 2
    w = rotor_speeds_sq_for(torque_nm, thrust_n, vehicle)
    clipped = (clip(w[0], lo, hi), clip(w[1], lo, hi), clip(w[2], lo, hi), clip(w[3], lo, hi))
    torque, thrust = wrench_from_rotor_speeds_sq(clipped, vehicle)
    return clipped, torque, thrust
