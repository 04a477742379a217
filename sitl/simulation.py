"""Offline closed-loop flight: plant, sensors, onboard 1 kHz attitude loop, position loop.

No sockets and no clocks: the same objects the MAVLink vehicle and the companion run, wired
directly and stepped as fast as Python allows. One vehicle runs on floats; passing a list of
seeds runs a batch of vehicles on arrays (one per seed, identical to the one-vehicle runs).

Per plant step (1 kHz): disturbances and wind at ``t`` -> (every position period) position loop
on the latest tracking sample, estimated attitude and mean IMU specific force -> onboard
attitude estimate and controller -> mixer -> plant -> IMU and tracking system.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from companion.control import quaternion as quat
from companion.control.outer_loop import AttitudeSetpoint, PositionLoop, PositionMeasurement
from companion.control.trajectory import PositionReference, ReferenceFilter
from companion.control.vector import Vec3

from .disturbances import evaluate
from .dynamics import Plant, RigidBodyState
from .onboard import AttitudeEstimator, OnboardAttitudeLoop
from .scenario import Scenario
from .sensors import Imu, Mocap
from .wind import Wind

__all__ = ["LOG_COLUMNS", "FlightLog", "Simulation", "simulate"]

LOG_COLUMNS = (
    "t",
    "x", "y", "z",
    "vx", "vy", "vz",
    "x_ref", "y_ref", "z_ref",
    "vx_ref", "vy_ref", "vz_ref",
    "yaw_ref",
    "qw", "qx", "qy", "qz",
    "qw_d", "qx_d", "qy_d", "qz_d",
    "p", "q", "r",
    "p_d", "q_d", "r_d",
    "thrust_sp",
    "fx", "fy", "fz",
    "hfx_hat", "hfy_hat", "hfz_hat",
    "hfx", "hfy", "hfz",
    "htx_hat", "hty_hat", "htz_hat",
    "htx", "hty", "htz",
    "sx_att", "sy_att", "sz_att",
    "sx_pos", "sy_pos", "sz_pos",
    "wind_x", "wind_y", "wind_z",
)
"""Logged signals. Position/velocity are true (NED, m, m/s); q is the true attitude; p, q, r
true body rates; *_d the setpoint; f the position loop's force [N]; hf* the force disturbance
(true lumped drag + external force, and the estimate) [N]; ht* the torque disturbance [N m]."""


@dataclass
class FlightLog:
    """Time series of :data:`LOG_COLUMNS`: arrays of shape (T,) or (T, N) for a batch."""

    columns: dict[str, NDArray[np.float64]]
    scenario: Scenario
    position: str
    attitude: str
    seeds: int | tuple[int, ...]

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        return self.columns[name]

    @property
    def t(self) -> NDArray[np.float64]:
        return self.columns["t"]

    def vehicle(self, i: int) -> FlightLog:
        """One vehicle of a batch log."""
        cols = {k: (v if v.ndim == 1 else v[:, i]) for k, v in self.columns.items()}
        seeds = self.seeds[i] if isinstance(self.seeds, tuple) else self.seeds
        return FlightLog(cols, self.scenario, self.position, self.attitude, seeds)

    def to_csv(self, path: str) -> None:
        if any(v.ndim != 1 for v in self.columns.values()):
            raise ValueError("write one vehicle at a time (FlightLog.vehicle(i))")
        data = np.column_stack([self.columns[c] for c in LOG_COLUMNS])
        np.savetxt(path, data, delimiter=",", header=",".join(LOG_COLUMNS), comments="", fmt="%.7g")


def _batched(x: object, n: int) -> object:
    """Broadcast the components of nested tuples of floats to arrays of length n."""
    if isinstance(x, tuple):
        return tuple(_batched(v, n) for v in x)
    return np.full(n, float(x))  # type: ignore[arg-type]


class Simulation:
    def __init__(self, scenario: Scenario, position: str, attitude: str, seeds: int | Sequence[int]) -> None:
        self.scenario = sc = scenario
        self.position_kind, self.attitude_kind = position, attitude
        self.batch = not isinstance(seeds, (int, np.integer))
        self.seeds: int | tuple[int, ...] = tuple(int(s) for s in seeds) if self.batch else int(seeds)  # type: ignore[union-attr]
        n = len(self.seeds) if isinstance(self.seeds, tuple) else 1
        self.n = n
        self.dt = 1.0 / sc.plant_rate_hz
        self.pos_div = int(round(sc.plant_rate_hz / sc.position_rate_hz))
        self.pos_dt = self.pos_div * self.dt
        self.log_div = max(1, int(round(sc.plant_rate_hz / sc.log_rate_hz)))

        pos0, yaw0 = sc.setpoint.target_at(0.0)
        plant = Plant.at_rest(sc.plant_vehicle, sc.airframe, pos0, yaw0, hovering=True)
        if self.batch:
            plant.state = RigidBodyState(*_batched(tuple(plant.state), n))  # type: ignore[arg-type]
        self.plant = plant
        self.imu = Imu(sc.sensors, self.seeds)
        self.mocap = Mocap(sc.sensors, self.seeds, plant.state)
        self.wind = Wind(sc.wind, self.seeds, self.dt)
        self.estimator = AttitudeEstimator(sc.estimator, plant.state.q)
        self.onboard = OnboardAttitudeLoop.create(attitude, sc.vehicle, sc.attitude, sc.airframe.rotor_command_levels)
        self.outer = PositionLoop.create(position, sc.vehicle, sc.position, sc.reference)
        hover = sc.vehicle.weight_n
        self.outer.thrust_n = hover
        self.setpoint = AttitudeSetpoint(plant.state.q, (0.0, 0.0, 0.0), hover)
        self.ref_filter = ReferenceFilter(sc.trajectory, pos0, yaw0) if sc.setpoint.waypoints else None
        self.ref = PositionReference(pos0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), yaw0)
        self._gyro = (0.0, 0.0, 0.0)
        self._sf_sum = [0.0, 0.0, 0.0]
        self._sf_count = 0

    def _reference(self, t: float) -> PositionReference:
        target, yaw = self.scenario.setpoint.target_at(t)
        if self.ref_filter is None:
            return PositionReference(target, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), yaw)
        return self.ref_filter.update(target, yaw, self.pos_dt)

    def _position_step(self, t: float) -> None:
        sc = self.scenario
        ms = self.mocap.latest
        q_est = self.estimator.q
        if sc.position.observer_uses_imu:
            k = 1.0 / max(self._sf_count, 1)
            s = self._sf_sum
            sf_ned = quat.rotate(q_est, (s[0] * k, s[1] * k, s[2] * k))
        else:
            a = ms.accel_ned_m_s2
            sf_ned = (a[0], a[1], a[2] - sc.vehicle.gravity_m_s2)
        self._sf_sum = [0.0, 0.0, 0.0]
        self._sf_count = 0
        self.ref = self._reference(t)
        meas = PositionMeasurement(ms.pos_ned_m, ms.vel_ned_m_s, q_est, sf_ned)
        self.setpoint = self.outer.update(meas, self.ref, self.pos_dt)

    def run(self, duration_s: float | None = None) -> FlightLog:
        sc = self.scenario
        steps = int(round((duration_s or sc.duration_s) / self.dt))
        dt = self.dt
        plant, imu, mocap, wind = self.plant, self.imu, self.mocap, self.wind
        est, onboard = self.estimator, self.onboard
        forces, torques = sc.forces, sc.torques
        rows: list[tuple[object, ...]] = []
        wrench = None
        for k in range(steps):
            t = k * dt
            if k % self.pos_div == 0:
                self._position_step(t)
            omega = est.predict(self._gyro, dt)
            cmd = onboard.update(est.q, omega, self.setpoint, dt)
            wind_ned = wind.step()
            wrench = plant.step(cmd, wind_ned, evaluate(forces, t), evaluate(torques, t), dt)
            sample = imu.sample(plant.state, wrench)
            self._gyro = sample.gyro_rad_s
            sf = sample.specific_force_body_m_s2
            acc = self._sf_sum
            acc[0] += sf[0]
            acc[1] += sf[1]
            acc[2] += sf[2]
            self._sf_count += 1
            tracked = mocap.update(t + dt, plant.state)
            if tracked is not None:
                est.correct(tracked.q)
            if k % self.log_div == 0:
                rows.append(self._row(t + dt, wrench, wind_ned))
        return self._log(rows)

    def _row(self, t: float, wrench: object, wind_ned: Vec3) -> tuple[object, ...]:
        s = self.plant.state
        ref, sp, outer, att = self.ref, self.setpoint, self.outer, self.onboard.controller
        ctrl = outer.controller
        return (
            t, *s.pos_ned_m, *s.vel_ned_m_s, *ref.pos_ned_m, *ref.vel_ned_m_s, ref.yaw_rad,
            *s.q, *sp.q_d, *s.omega_rad_s, *sp.omega_d_rad_s, sp.thrust_n, *outer.force_n,
            *ctrl.estimate_n, *wrench.disturbance_force_ned_n,  # type: ignore[attr-defined]
            *att.disturbance_estimate_nm, *wrench.disturbance_torque_nm,  # type: ignore[attr-defined]
            *att.s, *ctrl.s, *wind_ned,
        )

    def _log(self, rows: list[tuple[object, ...]]) -> FlightLog:
        n = self.n
        if self.batch:
            cols = {
                name: np.stack([np.broadcast_to(np.asarray(r[i], dtype=float), (n,)) for r in rows])
                for i, name in enumerate(LOG_COLUMNS)
            }
            cols["t"] = cols["t"][:, 0].copy()
        else:
            arr = np.asarray(rows, dtype=float)
            cols = {name: arr[:, i].copy() for i, name in enumerate(LOG_COLUMNS)}
        return FlightLog(cols, self.scenario, self.position_kind, self.attitude_kind, self.seeds)


def simulate(scenario: Scenario, position: str, attitude: str, seeds: int | Sequence[int] = 1,
             duration_s: float | None = None) -> FlightLog:
    """Fly ``scenario`` once with the named controllers; see :class:`Simulation`."""
    return Simulation(scenario, position, attitude, seeds).run(duration_s)


