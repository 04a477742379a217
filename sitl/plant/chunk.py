"""The live vehicle's plant steps between two decisions of its rules, on the compiled kernel.

The MAVLink vehicle's rules decide a setpoint at least at the position loop's rate (100 Hz); the
plant steps between two decisions (1 kHz: disturbances, wind, the onboard estimator and attitude
loop, the mixer, the body, the IMU, the tracking system) are :func:`~sitl.plant.kernel.vehicle_step`,
the lab's one copy, run ``steps`` times by :func:`advance_chunk` in one compiled call.

:class:`~sitl.plant.vehicle.SimVehicle`'s objects stay the vehicle's state: :func:`state_of` reads
them into a :class:`~sitl.plant.kernel.VehicleState`, :func:`put_back` writes the chunk's end state
back. A chunk runs only where the kernel flies what the objects would (:func:`fits`): one vehicle,
no fault injected in it, the IMU healthy; and it stops before a step whose IMU sample the firmware's
check would reject (out of range, non-finite, repeated exactly), so the objects take that step and
the check sees it. The kernel draws its noise from the counter-based streams (:mod:`sitl.plant.rng`,
keyed by the vehicle's seed and step count), the objects from their blocks: which steps each takes
is decided by the flight itself, so a seeded flight is the same flight each time.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
from numpy.typing import NDArray

from companion.control.allocation import RotorModel
from companion.control.jit import compile_once, depends_on, jitable, kernel
from companion.control.outer_loop import AttitudeSetpoint
from companion.control.vector import ZERO3, Vec3

from .body import Forces, plant_const
from .codec import codec
from .dynamics import Wrench
from .kernel import (
    PENDING,
    MocapState,
    Pending,
    VehicleConst,
    VehicleState,
    profiles_array,
    sensor_const,
    vehicle_step,
    wind_const,
    WindState,
)
from .sensors import ImuSample

SimVehicle = Any
"""a :class:`~sitl.plant.vehicle.SimVehicle` (which imports this module: not imported here)"""

depends_on(__file__)

__all__ = ["advance_chunk", "advance_rows", "advance_compiled", "const_of", "const_rows", "state_of", "state_row",
           "state_from", "put_back", "fits", "warm_up"]


@jitable
def advance_chunk(c: VehicleConst, st: VehicleState, sp: AttitudeSetpoint, motors_on: bool, extra_force_ned_n: Vec3,
                  extra_torque_nm: Vec3, steps: int, max_gyro_rad_s: float, max_accel_m_s2: float
                  ) -> tuple[VehicleState, int]:
    """Up to ``steps`` plant steps tracking ``sp``; (the state after them, how many were taken).
    Stops before a step whose IMU sample is out of range, non-finite or the previous one repeated
    exactly (the firmware's check, :class:`~sitl.plant.faults.ImuMonitor`, is to see it)."""
    done = 0
    while done < steps:
        nxt = vehicle_step(c, st, sp, motors_on, extra_force_ned_n, extra_torque_nm)
        g, a = nxt.gyro_rad_s, nxt.specific_force_body_m_s2
        mg, ma = max_gyro_rad_s, max_accel_m_s2
        plausible = (-mg <= g[0] <= mg and -mg <= g[1] <= mg and -mg <= g[2] <= mg
                     and -ma <= a[0] <= ma and -ma <= a[1] <= ma and -ma <= a[2] <= ma)
        g0, a0 = st.gyro_rad_s, st.specific_force_body_m_s2
        repeated = g == g0 and a == a0
        if not plausible or repeated:
            break
        st = nxt
        done += 1
    return st, done


def _example_const() -> VehicleConst:
    from .scenario import Scenario
    from .kernel import vehicle_const
    return vehicle_const(Scenario(name="codec"), "ism_do", 1)


def _example_state(c: VehicleConst) -> VehicleState:
    from .kernel import vehicle_init
    return vehicle_init(c, ZERO3, 0.0, False)


_CONST = codec(_example_const())
_STATE = codec(_example_state(_example_const()))
_unpack_const, _unpack_state, _write_state = _CONST.unpack, _STATE.unpack, _STATE.write
STATE_SIZE = _STATE.size


@jitable
def advance_rows(const_row: NDArray[np.float64], forces: NDArray[np.float64], torques: NDArray[np.float64],
                 state_row: NDArray[np.float64], sp: AttitudeSetpoint, motors_on: bool, extra_force_ned_n: Vec3,
                 extra_torque_nm: Vec3, steps: int, max_gyro_rad_s: float, max_accel_m_s2: float) -> int:
    """:func:`advance_chunk` on a state kept in ``state_row`` (read, then written back) with the
    constants in ``const_row`` and the profiles' arrays (:mod:`.codec`): numbers in arrays cross into
    compiled code at the cost of a pointer, where the tuples would be converted one by one."""
    c = _unpack_const(const_row, forces, torques)
    st, done = advance_chunk(c, _unpack_state(state_row), sp, motors_on, extra_force_ned_n, extra_torque_nm, steps,
                             max_gyro_rad_s, max_accel_m_s2)
    _write_state(state_row, st)
    return done


advance_compiled = kernel(advance_rows)
""":func:`advance_rows` compiled (cached on disk), or as it is without numba"""


def const_rows(c: VehicleConst) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The constants as :func:`advance_rows` takes them: the row, then the force and torque profiles."""
    forces, torques = _CONST.arrays(c)
    return (np.array(_CONST.pack(c), dtype=np.float64), np.ascontiguousarray(forces, dtype=np.float64),
            np.ascontiguousarray(torques, dtype=np.float64))


def state_row(st: VehicleState, out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """The state as a row (into ``out`` if given)."""
    values = _STATE.pack(st)
    if out is None:
        return np.array(values, dtype=np.float64)
    out[:] = values
    return out


def _sf_columns() -> tuple[int, int]:
    """Where the accelerometer's running sum and its count sit in a state row."""
    ex = _example_state(_example_const())._replace(sf_sum=(-1e300, -2e300, -3e300), sf_count=987654321)
    values = _STATE.pack(ex)
    return values.index(-1e300), values.index(987654321.0)


_SF_SUM, _SF_COUNT = _sf_columns()


def write_specific_force_sum(row: NDArray[np.float64], sf_sum: list[float], count: int) -> None:
    """The accelerometer's running sum and count into a state row (the position loop restarts them)."""
    i = _SF_SUM  # element by element: a slice assigned from a list costs a conversion
    row[i], row[i + 1], row[i + 2] = sf_sum
    row[_SF_COUNT] = count


def state_from(values: list[float]) -> VehicleState:
    """The state from a row's numbers (``row.tolist()``), in Python."""
    return _STATE.unpack_py(values)  # type: ignore[no-any-return]


def const_of(v: SimVehicle) -> VehicleConst:
    """What the kernel needs besides the state, from the vehicle's objects as they are now (the
    plant's true mass and inertia, its wind, its profiles, its firmware's loop and estimator)."""
    sc, dt, seed = v.scenario, v.dt, int(v.seeds)  # type: ignore[arg-type]
    onboard = v.onboard
    sensors = sensor_const(sc.sensors, seed, dt)._replace(gyro_bias_rad_s=v.imu.gyro_bias,
                                                           accel_bias_m_s2=v.imu.accel_bias)
    g = v.estimator.gains
    return VehicleConst(dt, plant_const(v.plant.vehicle, v.plant.airframe, dt), sensors,
                        wind_const(v.wind.params, seed, dt), profiles_array(v.forces), profiles_array(v.torques),
                        onboard.controller.const(dt), RotorModel.of(onboard.vehicle), onboard._w_min,
                        onboard._w_max, onboard._step, float(g.attitude_gain), float(g.bias_gain))


_EMPTY = Pending(0.0, 0.0, ZERO3, (1.0, 0.0, 0.0, 0.0))


def state_of(v: SimVehicle) -> VehicleState:
    """The vehicle's objects as one kernel state."""
    m = v.mocap
    queue = tuple(Pending(*p) for p in m._pending)
    n = len(queue)
    pending = (_EMPTY,) * (PENDING - n) + queue
    prev = m._pos_prev
    mocap = MocapState(m._next_t, v.mocap_taken, pending, n, m.latest, prev is not None,  # type: ignore[arg-type]
                       prev if prev is not None else ZERO3)
    w = v.wind
    wind = WindState(w._xu, w._xv, w._xw) if w.enabled else WindState(0.0, (0.0, 0.0), (0.0, 0.0))
    f = v.wrench
    forces = (Forces(f.specific_force_body_m_s2, f.thrust_n, ZERO3, f.disturbance_force_ned_n, f.disturbance_torque_nm)
              if f is not None else Forces(v.imu_sample.specific_force_body_m_s2, 0.0, ZERO3, ZERO3, ZERO3))
    s = v._sf_sum
    o = v.onboard
    return VehicleState(v.steps, v.t, v.plant.state, forces, wind, v.wind_ned, v.imu_sample.gyro_rad_s,
                        v.imu_sample.specific_force_body_m_s2, (s[0], s[1], s[2]), v._sf_count, mocap,
                        v.estimator.q, v.estimator.gyro_bias, v.omega_est, o.controller.state, o.torque_applied_nm,
                        0.0, o.rotor_cmd_rad_s)


def put_back(v: SimVehicle, st: VehicleState) -> None:
    """The chunk's end state into the vehicle's objects."""
    v.steps, v.t = st.k, st.t_s
    v.plant.state = st.body
    f = st.forces
    v.wrench = Wrench(f.specific_force_body_m_s2, f.thrust_n, f.disturbance_force_ned_n, f.disturbance_torque_nm)
    w = v.wind
    if w.enabled:
        w._xu, w._xv, w._xw = st.wind_state.xu, st.wind_state.xv, st.wind_state.xw
    v.wind_ned = st.wind_ned_m_s
    v.imu_sample = sample = ImuSample(st.gyro_rad_s, st.specific_force_body_m_s2)
    v._sf_sum = list(st.sf_sum)
    v._sf_count = st.sf_count
    ms, m = st.mocap, v.mocap
    m._next_t, v.mocap_taken = ms.next_s, ms.taken
    m._pending = deque(tuple(p) for p in ms.pending[PENDING - ms.n_pending:])  # type: ignore[misc]
    m.latest = ms.latest
    m._pos_prev = ms.pos_prev if ms.has_prev else None
    v.estimator.q, v.estimator.gyro_bias = st.q_est, st.gyro_bias_est
    v.omega_est = st.omega_est
    o = v.onboard
    o.controller.state = st.attitude
    o.torque_applied_nm, o.rotor_cmd_rad_s = st.torque_applied_nm, st.rotor_cmd_rad_s
    mon = v.imu_monitor
    if mon is not None:  # every sample of the chunk passed the check
        mon.last_good = mon._previous = sample
        mon.bad_since = math.nan


def fits(v: SimVehicle, steps: int) -> bool:
    """Whether the kernel flies the next ``steps`` as the objects would: one vehicle, the IMU healthy
    (not the gyro-less loop of a failed one) and no fault injected in the window."""
    if v.batch or v._degraded or (v.imu_monitor is not None and v.imu_monitor.failed):
        return False
    f = v.faults
    if f is None:
        return True
    t0, t1 = v.t, v.t + (steps + 1) * v.dt
    return all(not (a <= t1 and b > t0) for a, b in (f.mocap_dropout, f.imu_frozen, f.imu_nan))


def warm_up(v: SimVehicle) -> None:
    """Have :data:`advance_compiled` compiled (or loaded from the disk cache) for this vehicle's types."""
    sp = AttitudeSetpoint((1.0, 0.0, 0.0, 0.0), ZERO3, 0.0)
    compile_once(advance_compiled, *const_rows(const_of(v)), state_row(state_of(v)), sp, True, ZERO3, ZERO3, 1, 1.0,
                 1.0)

