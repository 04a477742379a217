"""Component-wise 3-vector and 3x3-matrix algebra shared by every control law.

A vector is a tuple of three components and a matrix a tuple of three row tuples. A
component is either a Python ``float`` (one vehicle: plain float arithmetic, about four
times faster than NumPy on 3-element arrays) or a NumPy array of shape ``(N,)`` (a batch of
N vehicles stepped together). Every law in :mod:`companion.control` is written once on top of
these helpers and runs unchanged in both forms, so the offline sweeps, the simulated
vehicle and the companion share one copy of the mathematics.

The scalar helpers (:func:`sqrt`, :func:`clip`, :func:`where`, ...) dispatch on the type of
their argument; branches in control laws go through :func:`where` so that they stay
element-wise in the batch form.
"""

from __future__ import annotations

import math
from typing import Sequence, Union

import numpy as np
from numpy.typing import NDArray

from .jit import float_form, jitable

__all__ = [
    "Real",
    "Vec3",
    "Mat3",
    "ZERO3",
    "E3",
    "sqrt",
    "exp",
    "sin",
    "cos",
    "atan2",
    "asin",
    "absolute",
    "minimum",
    "maximum",
    "clip",
    "where",
    "rint",
    "any_of",
    "all_of",
    "lowpass_alpha",
    "add",
    "sub",
    "neg",
    "scale",
    "mul",
    "div",
    "dot",
    "cross",
    "norm",
    "sat",
    "clip_norm",
    "matvec",
    "mat_t_vec",
    "matmul",
    "transpose",
    "diag",
    "skew",
    "vee",
    "as_vec3",
    "is_scalar",
]

Real = Union[float, NDArray[np.float64]]
Vec3 = tuple[Real, Real, Real]
Mat3 = tuple[Vec3, Vec3, Vec3]

ZERO3: Vec3 = (0.0, 0.0, 0.0)
E3: Vec3 = (0.0, 0.0, 1.0)
"""Unit vector along NED down (the paper's z_i)."""

_ndarray = np.ndarray


# --- element-wise scalar functions (float or batch) -----------------------------------


@float_form(lambda x: True)
def is_scalar(x: object) -> bool:
    """True for one vehicle's float (always, in compiled code), False for a batch array: the
    float-only fast paths of a few hot laws test this."""
    return type(x) is float


@float_form(lambda x: math.sqrt(x))
def sqrt(x: Real) -> Real:
    return np.sqrt(x) if type(x) is _ndarray else math.sqrt(x)


@float_form(lambda x: math.exp(x))
def exp(x: Real) -> Real:
    return np.exp(x) if type(x) is _ndarray else math.exp(x)


@float_form(lambda x: math.sin(x))
def sin(x: Real) -> Real:
    return np.sin(x) if type(x) is _ndarray else math.sin(x)


@float_form(lambda x: math.cos(x))
def cos(x: Real) -> Real:
    return np.cos(x) if type(x) is _ndarray else math.cos(x)


@float_form(lambda y, x: math.atan2(y, x))
def atan2(y: Real, x: Real) -> Real:
    if type(y) is _ndarray or type(x) is _ndarray:
        return np.arctan2(y, x)
    return math.atan2(y, x)


@float_form(lambda x: math.asin(min(1.0, max(-1.0, x))))
def asin(x: Real) -> Real:
    """Arc-sine with the argument clipped to [-1, 1] (rounding can push it past)."""
    return np.arcsin(np.clip(x, -1.0, 1.0)) if type(x) is _ndarray else math.asin(min(1.0, max(-1.0, x)))


@float_form(lambda x: abs(x))
def absolute(x: Real) -> Real:
    return np.abs(x) if type(x) is _ndarray else abs(x)  # type: ignore[return-value]


@float_form(lambda a, b: a if a < b else b)
def minimum(a: Real, b: Real) -> Real:
    if type(a) is _ndarray or type(b) is _ndarray:
        return np.minimum(a, b)
    return a if a < b else b


@float_form(lambda a, b: a if a > b else b)
def maximum(a: Real, b: Real) -> Real:
    if type(a) is _ndarray or type(b) is _ndarray:
        return np.maximum(a, b)
    return a if a > b else b


@float_form(lambda x, lo, hi: lo if x < lo else (hi if x > hi else x))
def clip(x: Real, lo: Real, hi: Real) -> Real:
    if type(x) is _ndarray or type(lo) is _ndarray or type(hi) is _ndarray:
        return np.minimum(np.maximum(x, lo), hi)
    return lo if x < lo else (hi if x > hi else x)


@jitable
def lowpass_alpha(bandwidth_rad_s: Real, dt_s: float) -> Real:
    """Gain of a first-order low-pass ``y += alpha (u - y)`` held over ``dt_s`` (exact, ZOH)."""
    return 1.0 - exp(-bandwidth_rad_s * dt_s)


@float_form(lambda cond, a, b: a if cond else b)
def where(cond: bool | NDArray[np.bool_], a: Real, b: Real) -> Real:
    """``a`` where ``cond`` holds, else ``b`` (element-wise for a batch)."""
    if type(cond) is _ndarray:
        return np.where(cond, a, b)
    return a if cond else b


@float_form(lambda x: float(round(x)))
def rint(x: Real) -> Real:
    """The nearest integer (halves to even), as a float."""
    return np.rint(x) if type(x) is _ndarray else float(round(float(x)))  # type: ignore[arg-type]


@float_form(lambda cond: cond)
def any_of(cond: bool | NDArray[np.bool_]) -> bool:
    """Whether ``cond`` holds for any vehicle (for one vehicle: whether it holds): a branch that
    element-wise code needs to take only when some vehicle needs it."""
    return bool(np.any(cond)) if type(cond) is _ndarray else bool(cond)


@float_form(lambda cond: cond)
def all_of(cond: bool | NDArray[np.bool_]) -> bool:
    """Whether ``cond`` holds for every vehicle (for one vehicle: whether it holds): a shortcut
    that element-wise code may take only when all vehicles may take it."""
    return bool(np.all(cond)) if type(cond) is _ndarray else bool(cond)


# --- vectors -------------------------------------------------------------------------


def as_vec3(v: Sequence[float]) -> Vec3:
    """A 3-tuple of floats from any 3-element sequence (the edge between I/O and the core)."""
    x, y, z = v
    return (float(x), float(y), float(z))


@jitable
def add(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@jitable
def sub(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@jitable
def neg(a: Vec3) -> Vec3:
    return (-a[0], -a[1], -a[2])


@jitable
def scale(k: Real, a: Vec3) -> Vec3:
    return (k * a[0], k * a[1], k * a[2])


@jitable
def mul(a: Vec3, b: Vec3) -> Vec3:
    """Element-wise product (a diagonal gain times a vector)."""
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@jitable
def div(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] / b[0], a[1] / b[1], a[2] / b[2])


@jitable
def dot(a: Vec3, b: Vec3) -> Real:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@jitable
def cross(a: Vec3, b: Vec3) -> Vec3:
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


@jitable
def norm(a: Vec3) -> Real:
    # sqrt, not ** 0.5: CPython computes float ** 0.5 with pow(), which is off by one ulp now and
    # then, where compiled code and NumPy take the correctly rounded square root
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@jitable
def sat(a: Vec3, width: Vec3) -> Vec3:
    """Element-wise ``sat(a / width)`` clipped to [-1, 1] (the boundary layer of (23))."""
    if is_scalar(a[0]):
        u0, u1, u2 = a[0] / width[0], a[1] / width[1], a[2] / width[2]
        return (
            -1.0 if u0 < -1.0 else (1.0 if u0 > 1.0 else u0),
            -1.0 if u1 < -1.0 else (1.0 if u1 > 1.0 else u1),
            -1.0 if u2 < -1.0 else (1.0 if u2 > 1.0 else u2),
        )
    return (
        clip(a[0] / width[0], -1.0, 1.0),
        clip(a[1] / width[1], -1.0, 1.0),
        clip(a[2] / width[2], -1.0, 1.0),
    )


@jitable
def clip_norm(a: Vec3, limit: Real) -> Vec3:
    """``a`` scaled down, keeping its direction, so that ``|a| <= limit``."""
    n = norm(a)
    k = where(n > limit, limit / maximum(n, 1e-300), 1.0)
    return scale(k, a)


# --- matrices (tuples of rows) -------------------------------------------------------


@jitable
def matvec(m: Mat3, v: Vec3) -> Vec3:
    r0, r1, r2 = m
    x, y, z = v
    return (
        r0[0] * x + r0[1] * y + r0[2] * z,
        r1[0] * x + r1[1] * y + r1[2] * z,
        r2[0] * x + r2[1] * y + r2[2] * z,
    )


@jitable
def mat_t_vec(m: Mat3, v: Vec3) -> Vec3:
    """``m^T v`` without forming the transpose."""
    return (
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    )


@jitable
def transpose(m: Mat3) -> Mat3:
    return (
        (m[0][0], m[1][0], m[2][0]),
        (m[0][1], m[1][1], m[2][1]),
        (m[0][2], m[1][2], m[2][2]),
    )


@jitable
def matmul(a: Mat3, b: Mat3) -> Mat3:
    bt = transpose(b)
    return (
        (dot(a[0], bt[0]), dot(a[0], bt[1]), dot(a[0], bt[2])),
        (dot(a[1], bt[0]), dot(a[1], bt[1]), dot(a[1], bt[2])),
        (dot(a[2], bt[0]), dot(a[2], bt[1]), dot(a[2], bt[2])),
    )


@jitable
def diag(d: Vec3) -> Mat3:
    return ((d[0], 0.0, 0.0), (0.0, d[1], 0.0), (0.0, 0.0, d[2]))


@jitable
def skew(a: Vec3) -> Mat3:
    """The paper's S(a): ``skew(a) b = a x b``."""
    return ((0.0, -a[2], a[1]), (a[2], 0.0, -a[0]), (-a[1], a[0], 0.0))


@jitable
def vee(m: Mat3) -> Vec3:
    """Inverse of :func:`skew` (takes the skew-symmetric part of ``m``)."""
    return (
        0.5 * (m[2][1] - m[1][2]),
        0.5 * (m[0][2] - m[2][0]),
        0.5 * (m[1][0] - m[0][1]),
    )
