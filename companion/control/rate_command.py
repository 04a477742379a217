"""Body rates from an attitude target: the outer half of the cascade an autopilot runs itself.

When the autopilot is asked to fly *rates* (SET_ATTITUDE_TARGET with the attitude ignored), the
attitude loop must be closed here: a proportional law on the geometric error of section III,

    omega_cmd = R~^T omega_d - k e,      e = 2 eta~ eps~,  q~ = q_d^* ⊗ q   (5), (6)

with the desired body rates ``omega_d`` of (34) as feed-forward (PX4's own attitude controller is
this law, ``MC_ROLL_P`` ~ 6.5 1/s). Like the rest of the core: no I/O, floats or arrays.
"""

from __future__ import annotations

from . import quaternion as quat
from .jit import jitable
from .quaternion import Quat
from .vector import Vec3

__all__ = ["body_rate_command"]


@jitable
def body_rate_command(q: Quat, q_d: Quat, omega_d_rad_s: Vec3, k_per_s: float) -> Vec3:
    """Body rates [rad/s, FRD] that turn ``q`` towards ``q_d`` at ``k_per_s`` [1/s], plus ``omega_d``
    (expressed in the desired frame D) carried into the body frame."""
    q_err = quat.relative(q_d, q)  # (5): from D to B
    ff = quat.rotate_inverse(q_err, omega_d_rad_s)  # R~^T omega_d (6)
    k = 2.0 * k_per_s * q_err[0]  # e = 2 eta~ eps~
    return (ff[0] - k * q_err[1], ff[1] - k * q_err[2], ff[2] - k * q_err[3])
