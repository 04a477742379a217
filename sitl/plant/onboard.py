"""The simulated vehicle's firmware at 1 kHz: attitude estimate, attitude loop, mixer.

As on the paper's Hummingbird (section V.B): a strapdown integration of the gyros corrected
from the tracking system's attitude (a complementary filter that also learns the gyro bias),
the attitude controller of :mod:`companion.control.attitude`, and the allocation of
:mod:`companion.control.allocation`, whose rotor-speed commands are quantised like the
vehicle's 8-bit motor interface. The applied torque (after rotor limits and quantisation) is
fed back to the torque observer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from companion.control import quaternion as quat
from companion.control.allocation import Rotors4, rotor_speeds_sq_for, wrench_from_rotor_speeds
from companion.control.attitude import AttitudeController
from companion.control.jit import depends_on, jitable
from companion.control.outer_loop import AttitudeSetpoint
from companion.control.params import AttitudeGains, VehicleParams
from companion.control.quaternion import Quat
from companion.control.vector import ZERO3, Real, Vec3, clip, is_scalar, maximum, rint, sqrt

depends_on(__file__)  # the kernel inlines estimator_correct

__all__ = ["EstimatorGains", "AttitudeEstimator", "OnboardAttitudeLoop", "estimator_correct",
           "command_level"]


@dataclass(frozen=True)
class EstimatorGains:
    attitude_gain: float = 0.1
    """fraction of the tracking-system attitude error corrected per sample (about 0.17 s at 60 Hz)"""
    bias_gain: float = 0.005
    """fraction of that error, per sample, taken into the gyro-bias estimate [rad/s per rad]"""


@dataclass
class AttitudeEstimator:
    """Gyro strapdown at the loop rate, corrected by each tracking sample (complementary filter)."""

    gains: EstimatorGains
    q: Quat
    gyro_bias: Vec3 = ZERO3

    def predict(self, gyro_rad_s: Vec3, dt_s: float) -> Vec3:
        """Integrate the bias-corrected rate; returns that rate (what the controller uses)."""
        b = self.gyro_bias
        omega = (gyro_rad_s[0] - b[0], gyro_rad_s[1] - b[1], gyro_rad_s[2] - b[2])
        self.q = quat.integrate(self.q, omega, dt_s)
        return omega

    def correct(self, q_measured: Quat) -> None:
        """Pull the estimate towards a tracking sample and learn the gyro bias (:func:`estimator_correct`)."""
        self.q, self.gyro_bias = estimator_correct(self.gains.attitude_gain, self.gains.bias_gain, self.q,
                                                   self.gyro_bias, q_measured)


@jitable
def estimator_correct(attitude_gain: Real, bias_gain: Real, q_est: Quat, gyro_bias: Vec3,
                      q_measured: Quat) -> tuple[Quat, Vec3]:
    """Pull the estimate towards a tracking sample and learn the gyro bias (PI correction): the
    estimate and bias after one sample. A positive bias makes the estimate run ahead of the
    measurement, giving a negative error, so the bias estimate moves against the error."""
    err = quat.log(quat.relative(q_est, q_measured))  # body-frame error [rad]
    k, kb = attitude_gain, bias_gain
    q = quat.normalize(quat.mul(q_est, quat.exp((k * err[0], k * err[1], k * err[2]))))
    b = gyro_bias
    return q, (b[0] - kb * err[0], b[1] - kb * err[1], b[2] - kb * err[2])


@jitable
def command_level(w_sq: Real, lo_rad_s: float, hi_rad_s: float, step_rad_s: float) -> Real:
    """One rotor's speed command [rad/s] for a squared speed: clipped to range, then on the
    motor interface's grid (the compiled kernel's mixer calls this too, on floats or lanes)."""
    if is_scalar(w_sq):  # one vehicle: plain comparisons, the same numbers as the element-wise form
        w = math.sqrt(w_sq) if w_sq > 0.0 else 0.0
        w = lo_rad_s if w < lo_rad_s else (hi_rad_s if w > hi_rad_s else w)
        return lo_rad_s + round((w - lo_rad_s) / step_rad_s) * step_rad_s
    w = clip(sqrt(maximum(w_sq, 0.0)), lo_rad_s, hi_rad_s)
    return lo_rad_s + rint((w - lo_rad_s) / step_rad_s) * step_rad_s


def _round(x: Real) -> Real:
    return np.rint(x) if type(x) is np.ndarray else float(round(x))


@dataclass
class OnboardAttitudeLoop:
    """Attitude controller plus mixer: setpoint and sensors in, rotor speed commands out."""

    controller: AttitudeController
    vehicle: VehicleParams
    """the firmware's nominal vehicle (J0, rotor constants)"""
    command_levels: int = 256
    torque_applied_nm: Vec3 = ZERO3
    rotor_cmd_rad_s: Rotors4 = field(default=(0.0, 0.0, 0.0, 0.0))

    def __post_init__(self) -> None:
        v = self.vehicle
        self._w_min = v.rotor_speed_min_rad_s
        self._w_max = v.rotor_speed_max_rad_s
        self._step = (self._w_max - self._w_min) / (self.command_levels - 1)

    @classmethod
    def create(cls, kind: str, vehicle: VehicleParams, gains: AttitudeGains | None = None,
               command_levels: int = 256) -> OnboardAttitudeLoop:
        ctrl = AttitudeController(kind, gains or AttitudeGains(), vehicle.inertia_kg_m2)
        return cls(ctrl, vehicle, command_levels)

    def reset(self) -> None:
        self.controller.reset()
        self.torque_applied_nm = ZERO3

    def quantise_all(self, w_sq: Rotors4) -> Rotors4:
        """Rotor speed commands [rad/s] for squared speeds: clipped to range, then quantised."""
        lo, hi, step = self._w_min, self._w_max, self._step
        if type(w_sq[0]) is float:  # one vehicle: plain floats, several times faster
            return (command_level(w_sq[0], lo, hi, step), command_level(w_sq[1], lo, hi, step),
                    command_level(w_sq[2], lo, hi, step), command_level(w_sq[3], lo, hi, step))
        ws = [clip(sqrt(clip(x, 0.0, math.inf)), lo, hi) for x in w_sq]
        return tuple(lo + _round((w - lo) / step) * step for w in ws)  # type: ignore[return-value]

    def update(self, q: Quat, omega_rad_s: Vec3, sp: AttitudeSetpoint, dt_s: float) -> Rotors4:
        tau = self.controller.update(q, omega_rad_s, sp.q_d, sp.omega_d_rad_s, self.torque_applied_nm, dt_s,
                                     sp.omega_d_dot_rad_s2)
        cmd = self.quantise_all(rotor_speeds_sq_for(tau, sp.thrust_n, self.vehicle))
        self.torque_applied_nm = wrench_from_rotor_speeds(cmd, self.vehicle)[0]
        self.rotor_cmd_rad_s = cmd
        return cmd

    def stop(self) -> Rotors4:
        """Motors off (disarmed): nothing applied, the observers see zero torque."""
        self.torque_applied_nm = ZERO3
        self.rotor_cmd_rad_s = (0.0, 0.0, 0.0, 0.0)
        return self.rotor_cmd_rad_s
