"""Attitude, rate and thrust reference from the control force (section IV.B, SPEC section 4).

(32) as printed is garbled; the quaternion that turns the hover thrust direction ``-e3`` onto
``f / |f|`` is ``q_f ∝ [|f| - e3^T f, (-e3) x f]``. It is singular only for a force pointing
straight down, which :func:`limit_force` rules out by keeping a minimum upward component.
(34) differentiates the *desired* rotation of consecutive position steps; because that
amplifies sensor noise, the rate (or, optionally, the attitude it is computed from) is low-pass
filtered and limited in norm (:class:`RateReference`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

from . import quaternion as quat
from .jit import jitable
from .params import ReferenceParams
from .quaternion import Quat
from .vector import (
    ZERO3,
    Real,
    Vec3,
    clip_norm,
    lowpass_alpha,
    maximum,
    norm,
    sqrt,
    where,
)

__all__ = [
    "limit_force",
    "thrust_quaternion",
    "attitude_from_force",
    "RateReference",
    "RateConst",
    "RateState",
    "rate_const",
    "rate_init",
    "rate_step",
]


@jitable
def limit_force(force_ned_n: Vec3, min_up_n: Real, tilt_max_rad: float) -> Vec3:
    """The force with at least ``min_up_n`` upward and at most ``tilt_max_rad`` off vertical.

    The vertical component is raised first (never towards the ground), then the horizontal part
    is shortened, keeping its direction, to fit the tilt cone: the altitude loop keeps priority.
    """
    up = maximum(-force_ned_n[2], min_up_n)
    horizontal = sqrt(force_ned_n[0] * force_ned_n[0] + force_ned_n[1] * force_ned_n[1])
    h_max = up * math.tan(tilt_max_rad)
    k = where(horizontal > h_max, h_max / maximum(horizontal, 1e-300), 1.0)
    return (k * force_ned_n[0], k * force_ned_n[1], -up)


@jitable
def thrust_quaternion(force_ned_n: Vec3) -> Quat:
    """``q_f`` of (32), corrected: the shortest rotation taking ``-e3`` to ``f / |f|``.

    ``[|f| - e3^T f, (-e3) x f] = [|f| - f_z, f_y, -f_x, 0]``, normalised. Requires ``f`` not
    pointing straight down (``f_z < |f|``), which :func:`limit_force` guarantees.
    """
    fx, fy, fz = force_ned_n
    w = norm(force_ned_n) - fz
    n = sqrt(w * w + fx * fx + fy * fy)
    return (w / n, fy / n, -fx / n, 0.0 * fx)


@jitable
def attitude_from_force(force_ned_n: Vec3, yaw_rad: Real) -> tuple[Quat, Real]:
    """``(q_d, T)`` with ``q_d = q_f ⊗ q_psi`` (33) and ``T = |f|``.

    ``q_psi`` rotates about the inertial z axis, so yaw is the angle about z_I, not the Euler yaw.
    """
    return quat.mul(thrust_quaternion(force_ned_n), quat.from_yaw(yaw_rad)), norm(force_ned_n)


class RateConst(NamedTuple):
    alpha: float
    """the filter's gain over one step"""
    rate_limit_rad_s: float
    filter_attitude: bool
    dt_s: float


class RateState(NamedTuple):
    omega_d: Vec3
    omega_d_dot: Vec3
    q_ref: Quat
    """the attitude to send (meaningless until ``primed``)"""
    primed: bool


def rate_const(params: ReferenceParams, dt_s: float) -> RateConst:
    tc = params.rate_filter_time_constant_s
    a = lowpass_alpha(1.0 / tc, dt_s) if tc > 0.0 else 1.0
    return RateConst(float(a), params.rate_limit_rad_s, params.filter_attitude, dt_s)


@jitable
def rate_init() -> RateState:
    return RateState(ZERO3, ZERO3, quat.IDENTITY, False)


@jitable
def rate_step(c: RateConst, st: RateState, q_d: Quat) -> RateState:
    """One position step of (34): the new state, whose ``q_ref`` is the attitude to send and
    ``omega_d`` (in D) the rate; see :class:`RateReference`."""
    if not st.primed:
        return RateState(st.omega_d, st.omega_d_dot, q_d, True)
    prev, dt_s = st.q_ref, c.dt_s
    delta = quat.log(quat.relative(prev, q_d))
    a = c.alpha
    o, limit = st.omega_d, c.rate_limit_rad_s
    if c.filter_attitude:
        step = clip_norm((a * delta[0], a * delta[1], a * delta[2]), limit * dt_s)
        q_ref = quat.mul(prev, quat.exp(step))
        new = (step[0] / dt_s, step[1] / dt_s, step[2] / dt_s)
    else:
        raw = (delta[0] / dt_s, delta[1] / dt_s, delta[2] / dt_s)
        new = clip_norm((o[0] + a * (raw[0] - o[0]), o[1] + a * (raw[1] - o[1]), o[2] + a * (raw[2] - o[2])),
                        limit)
        q_ref = q_d
    omega_d_dot = ((new[0] - o[0]) / dt_s, (new[1] - o[1]) / dt_s, (new[2] - o[2]) / dt_s)
    return RateState(new, omega_d_dot, q_ref, True)


@dataclass
class RateReference:
    """Angular-velocity command of (34) and the attitude reference sent with it.

    (34) differentiates consecutive desired attitudes, ``omega_d,k = log(q_d,k-1^* ⊗ q_d,k) / t_s``
    (expressed in D), which amplifies sensor noise (SPEC section 3: filter what it is computed
    from, or omega_d itself). Two forms, chosen by ``ReferenceParams.filter_attitude``:

    - ``False`` (the paper's structure, the default): the attitude sent is (33)'s ``q_d``; the
      rate is low-pass filtered (``rate_filter_time_constant_s``) and limited in norm
      (``rate_limit_rad_s``).
    - ``True``: the attitude sent, :attr:`q_ref`, follows ``q_d`` through that first-order filter
      along the shortest arc with its step limited to ``rate_limit_rad_s``, and ``omega_d`` is
      exactly that step over ``t_s``: attitude and rate are one motion, so the limit bounds the
      body rate too. In the default form the filtered rate lags the attitude it belongs to, the
      attitude loop closes the gap at whatever rate it takes, and in E4 the body turns at up to
      360 deg/s behind a command limited to 250 deg/s; the filtered attitude keeps it within
      270 deg/s but puts the filter's lag into the position loop (E1 peaks 15-20 % higher).

    ``omega_d_dot = (omega_d,k - omega_d,k-1) / t_s`` is the feed-forward ``R~^T omega_d'`` of
    (13); over the next step it integrates to exactly the change, so the attitude loop's sliding
    variable does not collect the commanded rate changes.
    """

    params: ReferenceParams = field(default_factory=ReferenceParams)
    state: RateState = field(default_factory=rate_init, repr=False)
    _const: RateConst | None = field(default=None, repr=False)

    def const(self, dt_s: float) -> RateConst:
        c = self._const
        if c is None or c.dt_s != dt_s:
            c = self._const = rate_const(self.params, dt_s)
        return c

    @property
    def omega_d(self) -> Vec3:
        return self.state.omega_d

    @property
    def omega_d_dot(self) -> Vec3:
        return self.state.omega_d_dot

    @property
    def q_ref(self) -> Quat | None:
        """the attitude to send (None before the first update)"""
        return self.state.q_ref if self.state.primed else None

    def reset(self) -> None:
        self.state = rate_init()

    def update(self, q_d: Quat, dt_s: float) -> Vec3:
        """One position step: sets :attr:`q_ref` and returns ``omega_d`` (in D)."""
        self.state = rate_step(self.const(dt_s), self.state, q_d)
        return self.state.omega_d
