"""Offline closed-loop flight: plant, sensors, onboard 1 kHz attitude loop, position loop.

No sockets and no clocks: the same objects the MAVLink vehicle and the companion run, wired
directly and stepped as fast as Python allows. One vehicle runs on floats; passing a list of
seeds runs a batch of vehicles on arrays (one per seed, identical to the one-vehicle runs).

Per plant step (1 kHz): disturbances and wind at ``t`` -> (every position period) position loop
on the latest tracking sample, estimated attitude and mean IMU specific force -> onboard
attitude estimate and controller -> mixer -> plant -> IMU and tracking system.

Two engines fly the same laws (the control core's step functions; ``SITL_ENGINE`` or the
``engine`` argument chooses): ``compiled`` (the default when numba is installed, the simulator's
``sim`` extra) runs :func:`sitl.plant.kernel.fly_batch`, one compiled loop per vehicle, the
vehicles in parallel on every core; ``objects`` runs the objects below (``SimVehicle``, the
companion's ``PositionLoop``), the path the live MAVLink vehicle takes, in plain Python. With
noise and turbulence off they fly the same flight to the last bits (tests/sitl/test_compiled.py
holds them within 1e-12 for E1-E5 and every controller); with noise on they draw different but
equally distributed numbers (the kernel's counter-based streams,
:mod:`sitl.plant.rng`; the objects' pre-drawn blocks, :mod:`sitl.plant.noise`).
"""

from __future__ import annotations

import gzip
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from companion.control import quaternion as quat
from companion.control.outer_loop import AttitudeSetpoint, PositionLoop, PositionMeasurement
from companion.control.trajectory import PositionReference, ReferenceFilter

from ..plant import kernel
from ..plant.kernel import LOG_COLUMNS
from ..plant.scenario import Scenario
from ..plant.engine import ENGINES, default_engine
from ..plant.vehicle import SimVehicle

__all__ = ["LOG_COLUMNS", "ENGINES", "FlightLog", "Simulation", "default_engine", "simulate", "simulate_compiled"]

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
        """One vehicle of a batch log (with its own gains, where the batch had per-vehicle gains)."""
        cols = {k: (v if v.ndim == 1 else v[:, i]) for k, v in self.columns.items()}
        seeds = self.seeds[i] if isinstance(self.seeds, tuple) else self.seeds
        return FlightLog(cols, _scenario_of_vehicle(self.scenario, i), self.position, self.attitude, seeds)

    def to_csv(self, path: str) -> None:
        if any(v.ndim != 1 for v in self.columns.values()):
            raise ValueError("write one vehicle at a time (FlightLog.vehicle(i))")
        data = np.column_stack([self.columns[c] for c in LOG_COLUMNS])
        # gzip at level 1: 6x faster than NumPy's default 9 for a 13 % larger file (0.05 s against
        # 0.33 s for a 45 s flight); at 9 the compression was two thirds of `make experiments`
        with (gzip.open(path, "wt", compresslevel=1) if str(path).endswith(".gz") else open(path, "w")) as f:
            np.savetxt(f, data, delimiter=",", header=",".join(LOG_COLUMNS), comments="", fmt="%.7g")


def _scenario_of_vehicle(sc: Scenario, i: int) -> Scenario:
    """``sc`` with every per-vehicle gain array (sweeps, tuning) replaced by vehicle i's value."""
    import dataclasses

    def pick(v: object) -> object:
        if isinstance(v, np.ndarray):
            return float(v.reshape(-1)[i]) if v.size > 1 else float(v.reshape(-1)[0])
        if isinstance(v, tuple):
            return tuple(pick(x) for x in v)
        return v

    changes = {}
    for table in ("attitude", "position"):
        sub = getattr(sc, table)
        fields = {f.name: pick(getattr(sub, f.name)) for f in dataclasses.fields(sub)}
        if any(fields[k] is not getattr(sub, k) for k in fields):
            changes[table] = dataclasses.replace(sub, **fields)
    return sc.with_changes(**changes) if changes else sc


class Simulation:
    """A :class:`~sitl.plant.vehicle.SimVehicle` flown by the position loop of the control core."""

    def __init__(self, scenario: Scenario, position: str, attitude: str, seeds: int | Sequence[int]) -> None:
        self.scenario = sc = scenario
        self.position_kind, self.attitude_kind = position, attitude
        pos0, yaw0 = sc.setpoint.target_at(0.0)
        self.vehicle = SimVehicle(sc, attitude, seeds, pos0, yaw0, hovering=True)
        self.batch, self.seeds, self.n = self.vehicle.batch, self.vehicle.seeds, self.vehicle.n
        self.dt = self.vehicle.dt
        self.pos_div = int(round(sc.plant_rate_hz / sc.position_rate_hz))
        self.pos_dt = self.pos_div * self.dt
        self.log_div = max(1, int(round(sc.plant_rate_hz / sc.log_rate_hz)))
        self.outer = PositionLoop.create(position, sc.vehicle, sc.position, sc.reference)
        hover = sc.vehicle.weight_n
        self.outer.thrust_n = hover
        self.setpoint = AttitudeSetpoint(self.vehicle.state.q, (0.0, 0.0, 0.0), hover)
        self.ref_filter = ReferenceFilter(sc.trajectory, pos0, yaw0) if sc.setpoint.waypoints else None
        self.ref = PositionReference(pos0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), yaw0)

    def _reference(self, t: float) -> PositionReference:
        target, yaw = self.scenario.setpoint.target_at(t)
        if self.ref_filter is None:
            return PositionReference(target, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), yaw)
        return self.ref_filter.update(target, yaw, self.pos_dt)

    def _position_step(self, t: float) -> None:
        sc, v = self.scenario, self.vehicle
        ms = v.tracked
        q_est = v.estimator.q
        sf_body = v.mean_specific_force_body()
        if sc.position.observer_uses_imu:
            sf_ned = quat.rotate(q_est, sf_body)
        else:
            a = ms.accel_ned_m_s2
            sf_ned = (a[0], a[1], a[2] - sc.vehicle.gravity_m_s2)
        self.ref = self._reference(t)
        meas = PositionMeasurement(ms.pos_ned_m, ms.vel_ned_m_s, q_est, sf_ned)
        self.setpoint = self.outer.update(meas, self.ref, self.pos_dt)

    def run(self, duration_s: float | None = None) -> FlightLog:
        steps = int(round((duration_s or self.scenario.duration_s) / self.dt))
        vehicle = self.vehicle
        rows: list[tuple[object, ...]] = []
        for k in range(steps):
            if k % self.pos_div == 0:
                self._position_step(vehicle.t)
            vehicle.step(self.setpoint)
            if k % self.log_div == 0:
                rows.append(self._row(vehicle.t))
        return self._log(rows)

    def _row(self, t: float) -> tuple[object, ...]:
        v = self.vehicle
        s, wrench = v.state, v.wrench
        ref, sp, outer, att = self.ref, self.setpoint, self.outer, v.onboard.controller
        ctrl = outer.controller
        return (
            t, *s.pos_ned_m, *s.vel_ned_m_s, *ref.pos_ned_m, *ref.vel_ned_m_s, ref.yaw_rad,
            *s.q, *sp.q_d, *s.omega_rad_s, *sp.omega_d_rad_s, sp.thrust_n, *outer.force_n,
            *ctrl.estimate_n, *wrench.disturbance_force_ned_n,  # type: ignore[union-attr]
            *att.disturbance_estimate_nm, *wrench.disturbance_torque_nm,  # type: ignore[union-attr]
            *att.s, *ctrl.s, *v.wind_ned,
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
             duration_s: float | None = None, engine: str | None = None) -> FlightLog:
    """Fly ``scenario`` with the named controllers, one vehicle per seed (see the module's
    docstring for ``engine``, :func:`default_engine` when None)."""
    engine = engine or default_engine()
    if engine == "compiled":
        return simulate_compiled(scenario, position, attitude, seeds, duration_s)
    if engine != "objects":
        raise ValueError(f"engine {engine!r}: expected one of {ENGINES}")
    return Simulation(scenario, position, attitude, seeds).run(duration_s)


def simulate_compiled(scenario: Scenario, position: str, attitude: str, seeds: int | Sequence[int] = 1,
                      duration_s: float | None = None) -> FlightLog:
    """:func:`simulate` on the compiled kernel: every vehicle (per-vehicle gains as in a sweep's
    batch) is a row of constants, all flown by :func:`sitl.plant.kernel.fly_batch`."""
    sc = scenario
    batch = not isinstance(seeds, (int, np.integer))
    seed_list = [int(s) for s in seeds] if batch else [int(seeds)]  # type: ignore[union-attr]
    consts = [kernel.flight_const(_scenario_of_vehicle(sc, i) if batch else sc, position, attitude, s)
              for i, s in enumerate(seed_list)]
    family = kernel.position_family(consts[0])
    codec = kernel.flight_codec(family)
    arrays = codec.arrays(consts[0])
    if any(not all(np.array_equal(a, b) for a, b in zip(arrays, codec.arrays(c))) for c in consts[1:]):
        raise ValueError("a batch shares its force and torque profiles and waypoints")
    rows = np.array([codec.pack(c) for c in consts], dtype=np.float64)
    steps = int(round((duration_s or sc.duration_s) * sc.plant_rate_hz))
    n_log = -(-steps // consts[0].log_div)
    logs = np.empty((len(consts), n_log, len(LOG_COLUMNS)))
    final = np.empty((len(consts), 3))
    kernel.fly_batch(family, rows, *arrays, steps, logs, final)
    if batch:
        cols = {name: logs[:, :, i].T.copy() for i, name in enumerate(LOG_COLUMNS)}
        cols["t"] = logs[0, :, 0].copy()
        return FlightLog(cols, sc, position, attitude, tuple(seed_list))
    cols = {name: logs[0, :, i].copy() for i, name in enumerate(LOG_COLUMNS)}
    return FlightLog(cols, sc, position, attitude, seed_list[0])


