"""Unit quaternions, scalar first, Hamilton product (paper section II.A, SPEC section 1).

``q = (w, x, y, z)`` rotates body vectors into the inertial frame, ``v_I = R(q) v_B``: the
meaning of MAVLink's ATTITUDE_QUATERNION and SET_ATTITUDE_TARGET, so no conversion happens at
the wire. The paper's ``R_bi`` (inertial to body) is ``R(q)^T``.

``exp`` and ``log`` use the rotation-vector convention: ``exp(phi)`` is the rotation by
``|phi|`` rad about ``phi / |phi|``, and ``log`` is its inverse on the shortest arc.

Components may be floats or batch arrays (see :mod:`companion.control.vector`).
"""

from __future__ import annotations

import math

from .jit import jitable
from .vector import (
    Mat3,
    Real,
    Vec3,
    atan2,
    asin,
    cos,
    is_scalar,
    maximum,
    sin,
    sqrt,
    where,
)

__all__ = [
    "Quat",
    "IDENTITY",
    "mul",
    "relative",
    "conj",
    "normalize",
    "norm",
    "rotate",
    "rotate_inverse",
    "to_rotmat",
    "from_rotmat",
    "exp",
    "log",
    "from_axis_angle",
    "from_yaw",
    "from_euler",
    "to_euler",
    "tilt_angle",
    "positive_scalar",
    "angle_between",
    "integrate",
]

Quat = tuple[Real, Real, Real, Real]

IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)


@jitable
def mul(a: Quat, b: Quat) -> Quat:
    """Hamilton product ``a ⊗ b``: first rotate by ``b``, then by ``a`` (as frames compose)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@jitable
def relative(a: Quat, b: Quat) -> Quat:
    """``a^* ⊗ b``: the rotation from frame ``a`` to frame ``b`` (error (5), increments of (34))."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw + ax * bx + ay * by + az * bz,
        aw * bx - ax * bw - ay * bz + az * by,
        aw * by + ax * bz - ay * bw - az * bx,
        aw * bz - ax * by + ay * bx - az * bw,
    )


@jitable
def conj(q: Quat) -> Quat:
    """Conjugate ``q^*``: the inverse rotation of a unit quaternion."""
    return (q[0], -q[1], -q[2], -q[3])


@jitable
def norm(q: Quat) -> Real:
    return sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


@jitable
def normalize(q: Quat) -> Quat:
    n = norm(q)
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@jitable
def positive_scalar(q: Quat) -> Quat:
    """``q`` or ``-q``, whichever has ``w >= 0`` (same rotation, shortest arc)."""
    s = where(q[0] < 0.0, -1.0, 1.0)
    return (s * q[0], s * q[1], s * q[2], s * q[3])


@jitable
def rotate(q: Quat, v: Vec3) -> Vec3:
    """``R(q) v``: a body vector expressed in the inertial frame."""
    w, x, y, z = q
    # v + 2w (e x v) + 2 e x (e x v), with e the vector part
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    return (
        v[0] + w * tx + (y * tz - z * ty),
        v[1] + w * ty + (z * tx - x * tz),
        v[2] + w * tz + (x * ty - y * tx),
    )


@jitable
def rotate_inverse(q: Quat, v: Vec3) -> Vec3:
    """``R(q)^T v``: an inertial vector expressed in the body frame (``rotate`` by ``q^*``)."""
    w, x, y, z = q
    tx = 2.0 * (z * v[1] - y * v[2])
    ty = 2.0 * (x * v[2] - z * v[0])
    tz = 2.0 * (y * v[0] - x * v[1])
    return (
        v[0] + w * tx - (y * tz - z * ty),
        v[1] + w * ty - (z * tx - x * tz),
        v[2] + w * tz - (x * ty - y * tx),
    )


@jitable
def to_rotmat(q: Quat) -> Mat3:
    """Rotation matrix ``R(q)`` (Euler-Rodrigues), rows as tuples."""
    w, x, y, z = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return (
        (1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)),
        (2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)),
        (2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)),
    )


@jitable
def from_rotmat(m: Mat3) -> Quat:
    """Unit quaternion (``w >= 0``) of a rotation matrix; float form only (used at the edges)."""
    tr = m[0][0] + m[1][1] + m[2][2]
    q: Quat
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q = (0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s)
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2.0
        q = ((m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s)
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2.0
        q = ((m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s)
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2.0
        q = ((m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s)
    return positive_scalar(normalize(q))  # type: ignore[arg-type]


@jitable
def _sin_half_over_angle(angle: Real) -> Real:
    """``sin(angle/2) / angle``, exact at 0 (series below 1e-4 rad)."""
    small = angle < 1e-4
    safe = where(small, 1.0, angle)
    return where(small, 0.5 - angle * angle / 48.0, sin(0.5 * safe) / safe)


@jitable
def exp(phi: Vec3) -> Quat:
    """Unit quaternion of the rotation vector ``phi`` [rad]."""
    angle = sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    if is_scalar(angle):  # one vehicle: skip the element-wise branches
        kf = 0.5 - angle * angle / 48.0 if angle < 1e-4 else math.sin(0.5 * angle) / angle
        return (math.cos(0.5 * angle), kf * phi[0], kf * phi[1], kf * phi[2])
    k = _sin_half_over_angle(angle)
    return (cos(0.5 * angle), k * phi[0], k * phi[1], k * phi[2])


@jitable
def log(q: Quat) -> Vec3:
    """Rotation vector [rad] of ``q`` on the shortest arc (``|log q| <= pi``)."""
    w, x, y, z = positive_scalar(q)
    vn = sqrt(x * x + y * y + z * z)
    angle = 2.0 * atan2(vn, w)
    small = vn < 1e-12
    k = where(small, 2.0 / maximum(w, 1e-300), angle / where(small, 1.0, vn))
    return (k * x, k * y, k * z)


@jitable
def from_axis_angle(axis: Vec3, angle_rad: Real) -> Quat:
    """Rotation by ``angle_rad`` about the unit vector ``axis``."""
    s = sin(0.5 * angle_rad)
    return (cos(0.5 * angle_rad), s * axis[0], s * axis[1], s * axis[2])


@jitable
def from_yaw(yaw_rad: Real) -> Quat:
    """``q_psi`` of (33): rotation by ``yaw_rad`` about the inertial z (down) axis."""
    return (cos(0.5 * yaw_rad), 0.0, 0.0, sin(0.5 * yaw_rad))


@jitable
def from_euler(roll_rad: Real, pitch_rad: Real, yaw_rad: Real) -> Quat:
    """ZYX (yaw, pitch, roll) Euler angles, as MAVLink's ATTITUDE message reports them."""
    cr, sr = cos(0.5 * roll_rad), sin(0.5 * roll_rad)
    cp, sp = cos(0.5 * pitch_rad), sin(0.5 * pitch_rad)
    cy, sy = cos(0.5 * yaw_rad), sin(0.5 * yaw_rad)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


@jitable
def to_euler(q: Quat) -> Vec3:
    """ZYX Euler angles ``(roll, pitch, yaw)`` [rad], for plots and telemetry only."""
    w, x, y, z = q
    roll = atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = asin(2.0 * (w * y - z * x))
    yaw = atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return (roll, pitch, yaw)


@jitable
def tilt_angle(q: Quat) -> Real:
    """Angle [rad] between the body z axis and the inertial z axis (0 when level)."""
    w, x, y, z = q
    # R33 = cos(tilt) = 1 - 2(x^2 + y^2); atan2 form is accurate near 0 and pi
    s = sqrt(x * x + y * y)
    c = sqrt(w * w + z * z)
    return 2.0 * atan2(s, c)


@jitable
def angle_between(a: Quat, b: Quat) -> Real:
    """Rotation angle [rad] of ``a^* ⊗ b`` on the shortest arc, in [0, pi]."""
    d = relative(a, b)
    vn = sqrt(d[1] * d[1] + d[2] * d[2] + d[3] * d[3])
    w = d[0]
    return 2.0 * atan2(vn, where(w < 0.0, -w, w))


@jitable
def integrate(q: Quat, omega_body_rad_s: Vec3, dt_s: Real) -> Quat:
    """``q`` advanced by a body rate held for ``dt_s`` (kinematics (2), exact for a constant rate).

    Renormalised every call so that the quaternion stays on the unit sphere however long it runs.
    """
    px, py, pz = omega_body_rad_s[0] * dt_s, omega_body_rad_s[1] * dt_s, omega_body_rad_s[2] * dt_s
    angle = sqrt(px * px + py * py + pz * pz)
    dw: Real
    dx: Real
    dy: Real
    dz: Real
    if is_scalar(angle):  # exp inlined: this runs twice per simulated millisecond
        k = 0.5 - angle * angle / 48.0 if angle < 1e-4 else math.sin(0.5 * angle) / angle
        dw, dx, dy, dz = math.cos(0.5 * angle), k * px, k * py, k * pz
    else:
        dw, dx, dy, dz = exp((px, py, pz))
    qw, qx, qy, qz = q
    rw = qw * dw - qx * dx - qy * dy - qz * dz
    rx = qw * dx + qx * dw + qy * dz - qz * dy
    ry = qw * dy - qx * dz + qy * dw + qz * dx
    rz = qw * dz + qx * dy - qy * dx + qz * dw
    n = sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
    return (rw / n, rx / n, ry / n, rz / n)
