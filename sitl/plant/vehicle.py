"""One simulated vehicle stepped at the plant rate: physics, environment, sensors, firmware.

Everything below the setpoint: external forces and wind at ``t``, the onboard attitude
estimate and attitude loop, the mixer, the plant, the IMU and the tracking system. The offline
simulator and the MAVLink vehicle both step this object, so the wiring exists once.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from companion.control.outer_loop import AttitudeSetpoint
from companion.control.params import VehicleParams
from companion.control.vector import ZERO3, Real, Vec3

from .disturbances import Profile, evaluate
from .faults import ImuMonitor, MocapRates, SensorFaults
from .dynamics import Plant, RigidBodyState, Wrench
from .onboard import AttitudeEstimator, OnboardAttitudeLoop
from .scenario import Scenario
from .sensors import Imu, ImuSample, Mocap, MocapSample
from .wind import Wind, WindParams

__all__ = ["SimVehicle"]


def _batched(x: object, n: int) -> object:
    """Broadcast the components of nested tuples of floats to arrays of length n."""
    if isinstance(x, tuple):
        return tuple(_batched(v, n) for v in x)
    return np.full(n, float(x))  # type: ignore[arg-type]


class SimVehicle:
    """Plant + environment + sensors + onboard 1 kHz loop of one vehicle (or a batch)."""

    def __init__(
        self,
        scenario: Scenario,
        attitude: str,
        seeds: int | Sequence[int],
        pos_ned_m: Vec3,
        yaw_rad: float = 0.0,
        hovering: bool = True,
    ) -> None:
        sc = self.scenario = scenario
        self.batch = not isinstance(seeds, (int, np.integer))
        self.seeds: int | tuple[int, ...] = tuple(int(s) for s in seeds) if self.batch else int(seeds)  # type: ignore[union-attr]
        self.n = len(self.seeds) if isinstance(self.seeds, tuple) else 1
        self.dt = 1.0 / sc.plant_rate_hz
        self.t = 0.0
        plant = Plant.at_rest(sc.plant_vehicle, sc.airframe, pos_ned_m, yaw_rad, hovering=hovering)
        if self.batch:
            plant.state = RigidBodyState(*_batched(tuple(plant.state), self.n))  # type: ignore[arg-type]
        self.plant = plant
        self.imu = Imu(sc.sensors, self.seeds)
        self.mocap = Mocap(sc.sensors, self.seeds, plant.state)
        self.wind = Wind(sc.wind, self.seeds, self.dt)
        self.wind_ned: Vec3 = sc.wind.mean_ned_m_s
        self.estimator = AttitudeEstimator(sc.estimator, plant.state.q)
        self.onboard = OnboardAttitudeLoop.create(attitude, sc.vehicle, sc.attitude, sc.airframe.rotor_command_levels)
        self.forces: tuple[Profile, ...] = sc.forces
        self.torques: tuple[Profile, ...] = sc.torques
        self.extra_force_ned_n: Vec3 = ZERO3
        """a constant force on top of the scenario's profiles (set at run time, e.g. a parameter)"""
        self.extra_torque_nm: Vec3 = ZERO3
        self.wrench: Wrench | None = None
        self.imu_sample = ImuSample(ZERO3, (0.0, 0.0, -sc.vehicle.gravity_m_s2))
        self.omega_est: Vec3 = ZERO3
        """bias-corrected gyro rate the firmware uses"""
        self.motors_on = True
        self._sf_sum = [0.0, 0.0, 0.0]
        self._sf_count = 0
        self.faults: SensorFaults | None = None
        """injected sensor faults and the firmware's IMU check (the live vehicle: enable_fault_checks)"""
        self.imu_monitor: ImuMonitor | None = None
        self.mocap_rates = MocapRates()

    def enable_fault_checks(self, monitor: bool = True) -> None:
        """Accept injected faults and (``monitor``) check every IMU sample as the bundled firmware
        does (the MAVLink vehicle; the offline simulator, which flies thousands of fault-free
        vehicles, skips this; a real autopilot flying the plant does its own checks)."""
        self.faults = SensorFaults()
        self.imu_monitor = ImuMonitor() if monitor else None

    _degraded = False
    DEGRADED_OMEGA_C_RAD_S = 6.0
    """the attitude loop without a gyro: its rates come from 60 Hz tracking, ~35 ms late, so the
    loop is slowed to half its crossover (and plain PD: the observers would learn the delay)"""

    def _degrade(self) -> None:
        sc = self.scenario
        gains = dataclasses.replace(sc.attitude, omega_c_rad_s=self.DEGRADED_OMEGA_C_RAD_S)
        self.scenario = dataclasses.replace(sc, attitude=gains)
        self.set_attitude_controller("pd")
        self._degraded = True

    @property
    def imu_failed(self) -> str | None:
        return self.imu_monitor.failed if self.imu_monitor is not None else None

    @property
    def estimate_offset_ned_m(self) -> Vec3:
        """What the reported position estimate adds to the tracked position (injected estimator
        resets, :class:`SensorFaults`); the vehicle's own loops fly the tracked one, re-anchored
        as a real autopilot's are after its own reset."""
        return self.faults.position_offset_ned_m if self.faults is not None else ZERO3

    @property
    def estimator_resets(self) -> int:
        """Position-estimate resets announced so far (ODOMETRY's reset_counter)."""
        return self.faults.position_resets if self.faults is not None else 0

    @property
    def position_age_s(self) -> float:
        """Time since the newest tracking sample was taken."""
        return self.t - self.mocap.latest.time_s

    # --- run-time changes (parameters, fault injection) -------------------------------

    def set_wind(self, params: WindParams) -> None:
        self.wind = Wind(params, self.seeds, self.dt)

    def set_plant_vehicle(self, vehicle: VehicleParams) -> None:
        """Change the true mass/inertia in flight (the controller's model is unchanged)."""
        self.plant.vehicle = vehicle
        self.plant.__post_init__()

    def set_attitude_controller(self, attitude: str) -> None:
        sc = self.scenario
        self.onboard = OnboardAttitudeLoop.create(attitude, sc.vehicle, sc.attitude, sc.airframe.rotor_command_levels)

    def set_attitude_gains(self, scenario: Scenario) -> None:
        kind = self.onboard.controller.kind
        self.scenario = scenario
        self.set_attitude_controller(kind)

    # --- stepping ----------------------------------------------------------------------

    def step(self, setpoint: AttitudeSetpoint) -> None:
        """Advance one plant step with the firmware tracking ``setpoint`` (motors on)."""
        est = self.estimator
        if self.imu_monitor is not None and self.imu_monitor.failed:
            self.omega_est = self.mocap_rates.omega_rad_s  # no gyro: rates from the tracking system
        else:
            self.omega_est = est.predict(self.imu_sample.gyro_rad_s, self.dt)
        if self.motors_on:
            cmd = self.onboard.update(est.q, self.omega_est, setpoint, self.dt)
        else:
            cmd = self.onboard.stop()
        tracked = self.advance(cmd)
        if tracked is not None:
            if self.imu_monitor is not None and self.imu_monitor.failed:
                est.q = tracked.q
                self.mocap_rates.update(tracked.time_s, tracked.q)
            else:
                est.correct(tracked.q)

    def advance(self, rotor_cmd_rad_s: tuple[Real, Real, Real, Real]) -> MocapSample | None:
        """One plant step with the rotors commanded to ``rotor_cmd_rad_s``: wind and external
        forces at ``t``, the body, the IMU (faults injected) and the tracking system. Returns the
        tracking sample that became available, if any. (:meth:`step` puts the onboard loop in
        front; a real autopilot's firmware flying this plant calls it directly.)"""
        dt = self.dt
        t = self.t
        wind_ned = self.wind.step()
        self.wind_ned = wind_ned
        force = evaluate(self.forces, t)
        if self.extra_force_ned_n is not ZERO3:
            e = self.extra_force_ned_n
            force = (force[0] + e[0], force[1] + e[1], force[2] + e[2])
        torque = evaluate(self.torques, t)
        if self.extra_torque_nm is not ZERO3:
            e = self.extra_torque_nm
            torque = (torque[0] + e[0], torque[1] + e[1], torque[2] + e[2])
        plant = self.plant
        self.wrench = plant.step(rotor_cmd_rad_s, wind_ned, force, torque, dt)
        sample = self.imu.sample(plant.state, self.wrench)
        if self.faults is not None:
            sample = self._faulty_imu(sample, t + dt)
            if self.imu_monitor is not None and self.imu_monitor.failed and not self._degraded:
                self._degrade()
        self.imu_sample = sample
        sf = sample.specific_force_body_m_s2
        acc = self._sf_sum
        acc[0] += sf[0]
        acc[1] += sf[1]
        acc[2] += sf[2]
        self._sf_count += 1
        self.t = t + dt
        if self.faults is not None and SensorFaults.active(self.faults.mocap_dropout, self.t):
            self.mocap.drop_out(self.t)
            return None
        return self.mocap.update(self.t, plant.state)

    def _faulty_imu(self, sample: ImuSample, t: float) -> ImuSample:
        """Inject the active IMU faults, then the firmware's check (:class:`ImuMonitor`) where
        this vehicle's own firmware flies it."""
        f = self.faults
        assert f is not None
        if SensorFaults.active(f.imu_nan, t):
            nan = float("nan")
            sample = ImuSample((nan, nan, nan), (nan, nan, nan))
        elif SensorFaults.active(f.imu_frozen, t):
            sample = self.imu_sample if self.imu_sample is not None else sample
        return self.imu_monitor.check(sample, t) if self.imu_monitor is not None else sample

    def mean_specific_force_body(self) -> Vec3:
        """Mean accelerometer reading since the last call (what a slower consumer should use)."""
        k = 1.0 / max(self._sf_count, 1)
        s = self._sf_sum
        out = (s[0] * k, s[1] * k, s[2] * k) if self._sf_count else self.imu_sample.specific_force_body_m_s2
        self._sf_sum = [0.0, 0.0, 0.0]
        self._sf_count = 0
        return out

    @property
    def state(self) -> RigidBodyState:
        return self.plant.state

    @property
    def tracked(self) -> MocapSample:
        return self.mocap.latest

    @property
    def hover_thrust_n(self) -> Real:
        return self.scenario.vehicle.weight_n
