"""One simulated vehicle stepped at the plant rate: physics, environment, sensors, firmware.

Everything below the setpoint: external forces and wind at ``t``, the onboard attitude
estimate and attitude loop, the mixer, the plant, the IMU and the tracking system. The offline
simulator and the MAVLink vehicle both step this object, so the wiring exists once.
"""

from __future__ import annotations

import dataclasses
import math
import operator
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
        self.steps = 0
        """plant steps so far (the counter of the compiled chunks' noise draws)"""
        self.mocap_taken = 0
        """tracking samples the compiled chunks took (the counter of their tracking noise)"""
        self.compiled_chunks = False
        """:meth:`step_many` on the compiled kernel where it fits (:meth:`compile_chunks`)"""
        self.chunk_counts = {"compiled": 0, "objects": 0, "refused": 0}
        """plant steps taken by each path; chunks the compiled call refused (unexpected types)"""
        self._chunk_key: tuple = ()
        self._chunk_const: tuple = ()
        self._row: np.ndarray | None = None
        self._row_mark: tuple = ()

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
        self.steps += 1
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

    def compile_chunks(self) -> bool:
        """Step :meth:`step_many`'s chunks on the compiled kernel (:mod:`sitl.plant.chunk`) from now
        on; False (and the objects step on) where numba is not installed."""
        from companion.control.jit import numba_available

        from . import chunk

        if self.batch or not numba_available():
            return False
        chunk.warm_up(self)
        chunk.advance_compiled.disable_compile()  # a call of unforeseen types falls back, never compiles mid-flight
        self.compiled_chunks = True
        return True

    def step_many(self, setpoint: AttitudeSetpoint, steps: int) -> None:
        """Advance ``steps`` plant steps tracking one ``setpoint``: in compiled chunks where they fit
        (:meth:`compile_chunks`), else (and for the steps a chunk leaves) one by one."""
        while steps > 0:
            if self.compiled_chunks:
                done = self._compiled_chunk(setpoint, steps)
                steps -= done
                if steps == 0:
                    return
            self.step(setpoint)
            self.chunk_counts["objects"] += 1
            steps -= 1

    def _compiled_chunk(self, setpoint: AttitudeSetpoint, steps: int) -> int:
        """Up to ``steps`` plant steps on the compiled kernel (:mod:`.chunk`); how many it took. The
        state stays in a row of numbers between chunks while nothing else changed the objects."""
        from . import chunk

        if not chunk.fits(self, steps):
            return 0
        mon = self.imu_monitor
        key = (self.scenario, self.plant.vehicle, self.plant.airframe, self.wind, self.forces, self.torques,
               self.onboard, self.onboard.controller.const(self.dt), self.estimator.gains, self.imu)
        if len(key) != len(self._chunk_key) or not all(map(operator.is_, key, self._chunk_key)):
            self._chunk_key, self._chunk_const = key, chunk.const_rows(chunk.const_of(self))
        row = self._row
        if row is None or self._row_mark != self._mark():
            self._row = row = chunk.state_row(chunk.state_of(self), row)
        else:  # the position loop read the accelerometer's mean since, and restarted it
            chunk.write_specific_force_sum(row, self._sf_sum, self._sf_count)
        max_gyro, max_accel = (mon.max_gyro_rad_s, mon.max_accel_m_s2) if mon is not None else (math.inf, math.inf)
        const, forces, torques = self._chunk_const
        try:
            done = chunk.advance_compiled(const, forces, torques, row, setpoint, self.motors_on, self.extra_force_ned_n,
                                          self.extra_torque_nm, steps, max_gyro, max_accel)
        except TypeError:  # a value of a type the kernel was not compiled for: the objects step
            self.chunk_counts["refused"] += 1
            return 0
        if done:
            chunk.put_back(self, chunk.state_from(row.tolist()))
            self.chunk_counts["compiled"] += done
        self._row_mark = self._mark()
        return done

    def _mark(self) -> tuple:
        """What the objects hold (compared by identity first, then value): a changed one (a step of the
        objects, a fault, a guard restoring the world, a parameter) means the row of
        :meth:`_compiled_chunk` is no longer the vehicle's state."""
        m, o, e = self.mocap, self.onboard, self.estimator
        return (self.steps, self.t, self.plant.state, self.wrench, self.wind, self.wind_ned, self.imu_sample,
                self.omega_est, m.latest, m._next_t, len(m._pending), self.mocap_taken, e.q, e.gyro_bias, o,
                o.controller.state, o.torque_applied_nm, o.rotor_cmd_rad_s)

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
