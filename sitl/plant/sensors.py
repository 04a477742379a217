"""Sensors of the paper's vehicle (section V.B, SPEC section 5).

- IMU at the plant rate: gyro and accelerometer with a constant bias (drawn from the seed) and
  white noise.
- Motion capture at 60 Hz: position and attitude with noise, delivered after a transport
  delay. Velocity and acceleration come from differencing consecutive samples and low-pass
  filtering, which adds the delay the paper mentions; the filter state is held between samples.

Defaults: an MPU-6000-class IMU (gyro 0.005 rad/s and accelerometer 0.05 m/s^2 per 1 kHz
sample; biases 0.005 rad/s, 0.05 m/s^2) and a sub-millimetre tracking system (0.3 mm, 0.1 deg).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple, Sequence

from companion.control import quaternion as quat
from companion.control.jit import depends_on, jitable
from companion.control.quaternion import Quat
from companion.control.vector import ZERO3, Real, Vec3, lowpass_alpha

from .dynamics import RigidBodyState, Wrench
from .noise import GaussianStream

__all__ = ["SensorParams", "ImuSample", "Imu", "MocapSample", "Mocap", "imu_reading", "tracked_pose",
           "differentiated"]

depends_on(__file__)  # the compiled kernel (kernel.py) calls the three laws below


@dataclass(frozen=True)
class SensorParams:
    gyro_noise_rad_s: float = 0.005
    gyro_bias_rad_s: float = 0.005
    accel_noise_m_s2: float = 0.05
    accel_bias_m_s2: float = 0.05
    mocap_rate_hz: float = 60.0
    mocap_pos_noise_m: float = 0.0003
    mocap_att_noise_rad: float = math.radians(0.1)
    mocap_delay_s: float = 0.01
    velocity_filter_hz: float = 5.0
    """first-order low-pass on the differenced position: 0.3 mm of noise differenced at 60 Hz is
    0.025 m/s, which (34) would turn into ~20 deg/s of rate-command noise in hover; 5 Hz costs
    3 deg of phase at the position loop's 1.5 rad/s"""
    accel_filter_hz: float = 5.0


class ImuSample(NamedTuple):
    gyro_rad_s: Vec3
    specific_force_body_m_s2: Vec3


@jitable
def imu_reading(omega_rad_s: Vec3, gyro_bias_rad_s: Vec3, gyro_noise_rad_s: Real, n_gyro: Vec3,
                specific_force_m_s2: Vec3, accel_bias_m_s2: Vec3, accel_noise_m_s2: Real,
                n_accel: Vec3) -> tuple[Vec3, Vec3]:
    """Gyro [rad/s] and accelerometer [m/s^2] readings: truth + bias + noise (``n_*``: unit normals)."""
    w, gb, gn = omega_rad_s, gyro_bias_rad_s, gyro_noise_rad_s
    f, ab, an = specific_force_m_s2, accel_bias_m_s2, accel_noise_m_s2
    return ((w[0] + gb[0] + gn * n_gyro[0], w[1] + gb[1] + gn * n_gyro[1], w[2] + gb[2] + gn * n_gyro[2]),
            (f[0] + ab[0] + an * n_accel[0], f[1] + ab[1] + an * n_accel[1], f[2] + ab[2] + an * n_accel[2]))


@jitable
def tracked_pose(pos_ned_m: Vec3, q: Quat, pos_noise_m: Real, att_noise_rad: Real, n_pos: Vec3,
                 n_att: Vec3) -> tuple[Vec3, Quat]:
    """What the tracking system measures: position [m] plus noise, attitude turned by a small
    random rotation (``n_*``: unit normals)."""
    pn, an = pos_noise_m, att_noise_rad
    pos = (pos_ned_m[0] + pn * n_pos[0], pos_ned_m[1] + pn * n_pos[1], pos_ned_m[2] + pn * n_pos[2])
    return pos, quat.mul(q, quat.exp((an * n_att[0], an * n_att[1], an * n_att[2])))


class Imu:
    def __init__(self, params: SensorParams, seeds: int | Sequence[int]) -> None:
        self.params = params
        self._noise = GaussianStream(seeds, "gyro", 6)
        b = GaussianStream(seeds, "bias", 6).initial()
        gb, ab = params.gyro_bias_rad_s, params.accel_bias_m_s2
        self.gyro_bias: Vec3 = (gb * b[0], gb * b[1], gb * b[2])
        self.accel_bias: Vec3 = (ab * b[3], ab * b[4], ab * b[5])

    def sample(self, state: RigidBodyState, wrench: Wrench) -> ImuSample:
        n = self._noise.next()
        p = self.params
        gyro, accel = imu_reading(state.omega_rad_s, self.gyro_bias, p.gyro_noise_rad_s, (n[0], n[1], n[2]),
                                  wrench.specific_force_body_m_s2, self.accel_bias, p.accel_noise_m_s2,
                                  (n[3], n[4], n[5]))
        return ImuSample(gyro, accel)


class MocapSample(NamedTuple):
    """Latest delivered tracking data and what is derived from it."""

    time_s: float
    """time the delivered sample was taken"""
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    accel_ned_m_s2: Vec3
    q: Quat


class Mocap:
    """60 Hz tracking with delay; :meth:`update` returns a new sample when one is delivered."""

    def __init__(self, params: SensorParams, seeds: int | Sequence[int], state: RigidBodyState) -> None:
        self.params = params
        self._noise = GaussianStream(seeds, "mocap", 6)
        self.period_s = 1.0 / params.mocap_rate_hz
        self._next_t = 0.0
        self._pending: deque[tuple[float, float, Vec3, Quat]] = deque()
        self._av = lowpass_alpha(2.0 * math.pi * params.velocity_filter_hz, self.period_s)
        self._aa = lowpass_alpha(2.0 * math.pi * params.accel_filter_hz, self.period_s)
        self.latest = MocapSample(0.0, state.pos_ned_m, ZERO3, ZERO3, state.q)
        self._pos_prev: Vec3 | None = None

    def update(self, t_s: float, state: RigidBodyState) -> MocapSample | None:
        p = self.params
        if t_s + 1e-9 >= self._next_t:
            n = self._noise.next()
            pos, q = tracked_pose(state.pos_ned_m, state.q, p.mocap_pos_noise_m, p.mocap_att_noise_rad,
                                  (n[0], n[1], n[2]), (n[3], n[4], n[5]))
            self._pending.append((t_s + p.mocap_delay_s, t_s, pos, q))
            self._next_t += self.period_s
        fresh = None
        while self._pending and self._pending[0][0] <= t_s + 1e-9:
            _, taken, pos, q = self._pending.popleft()
            fresh = self._deliver(taken, pos, q)
        return fresh

    def drop_out(self, t_s: float) -> None:
        """A dropout at ``t_s``: nothing is taken, and what was in transit never arrives."""
        while t_s + 1e-9 >= self._next_t:
            self._next_t += self.period_s
        self._pending.clear()

    def _deliver(self, taken_s: float, pos: Vec3, q: Quat) -> MocapSample:
        prev = self._pos_prev
        self._pos_prev = pos
        if prev is None:
            self.latest = MocapSample(taken_s, pos, ZERO3, ZERO3, q)
        else:
            self.latest = differentiated(self.latest, prev, taken_s, pos, q, self._av, self._aa)
        return self.latest


@jitable
def differentiated(latest: MocapSample, pos_prev: Vec3, taken_s: float, pos: Vec3, q: Quat,
                   velocity_alpha: float, accel_alpha: float) -> MocapSample:
    """The next tracking sample with its velocity [m/s] and acceleration [m/s^2]: backward
    differences over the samples' own timestamps (on the plant's time grid), each low-passed."""
    inv = 1.0 / (taken_s - latest.time_s)
    av, aa, prev = velocity_alpha, accel_alpha, pos_prev
    v0 = latest.vel_ned_m_s
    vel = (v0[0] + av * ((pos[0] - prev[0]) * inv - v0[0]), v0[1] + av * ((pos[1] - prev[1]) * inv - v0[1]),
           v0[2] + av * ((pos[2] - prev[2]) * inv - v0[2]))
    a0 = latest.accel_ned_m_s2
    acc = (a0[0] + aa * ((vel[0] - v0[0]) * inv - a0[0]), a0[1] + aa * ((vel[1] - v0[1]) * inv - a0[1]),
           a0[2] + aa * ((vel[2] - v0[2]) * inv - a0[2]))
    return MocapSample(taken_s, pos, vel, acc, q)
