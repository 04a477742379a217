"""One simulated vehicle as a pure step function, and the flight loop around it, compiled with numba.

Everything below the setpoint at the plant rate (1 kHz) -- disturbances and wind at ``t``, the
onboard attitude estimate and attitude loop, the mixer with its quantisation, the rigid body,
the IMU and the 60 Hz tracking system -- is :func:`vehicle_step` on a :class:`VehicleState`
(NamedTuples of floats, immutable), with everything that does not change in flight in a
:class:`VehicleConst`. :func:`fly_loop` adds the position loop of the control core at its own
rate and writes the log; :func:`fly_many` runs it for many vehicles, :data:`fly_compiled` is
that loop compiled (releasing the GIL), and :func:`fly_batch` runs it on every core, a share of
the vehicles per thread.
The laws are the control core's own functions (``companion.control``), compiled where a kernel
calls them; noise is drawn in the loop from counter-based streams (:mod:`.rng`).

A batch flies in lanes (:mod:`.lanes`): the same :func:`fly_loop`, compiled a second time with
every per-vehicle number a SIMD register of W vehicles (structure of arrays, W wide), so each
instruction of a law steps W vehicles; the clock and everything else the batch shares stay plain
numbers. Each group of W vehicles runs its whole flight with its state in registers and on the
stack (the time loop inside the group loop: a 4000-vehicle state stepped in memory would stream
~5 MB per step through the caches). A vehicle flies in a lane bit for bit as it flies alone.

Built from a :class:`~sitl.plant.scenario.Scenario` by :func:`vehicle_const` (in Python, once).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from companion.control import quaternion as quat
from companion.control.allocation import Rotors4, RotorModel, rotor_speeds_sq_for, wrench_from_rotor_speeds
from companion.control.attitude import (
    AttitudeConst,
    AttitudeState,
    attitude_const,
    attitude_disturbance_estimate,
    attitude_init,
    attitude_step,
)
from companion.control.jit import chosen_by_type, compile_once, depends_on, jitable, kernel, numba_available
from companion.control.outer_loop import (
    AttitudeSetpoint,
    LoopConst,
    LoopState,
    loop_const,
    position_loop_step,
)
from companion.control.position import STEPS, PositionConst, position_const, position_init
from companion.control.quaternion import Quat
from companion.control.reference import rate_const, rate_init
from companion.control.trajectory import PositionReference, ReferenceState, TrajectoryConst, reference_filter_step
from companion.control.vector import ZERO3, Vec3, lowpass_alpha

from . import lanes, rng
from .body import Forces, PlantConst, RigidBody, plant_const, plant_step
from .codec import Codec, codec
from .disturbances import PROFILE_KINDS, profile_factor
from .onboard import command_level, estimator_correct
from .sensors import MocapSample, differentiated, imu_reading, tracked_pose
from .wind import dryden_advance, dryden_gust, wind_ned

depends_on(__file__)

__all__ = [
    "PlantConst", "RigidBody", "Forces", "plant_const", "plant_step",
    "SensorConst", "MocapState", "imu_sample", "mocap_step",
    "WindConst", "WindState", "wind_const", "wind_init", "wind_step",
    "profiles_array", "profiles_at",
    "VehicleConst", "VehicleState", "vehicle_const", "vehicle_init", "vehicle_step",
    "FlightConst", "flight_const", "LOG_COLUMNS", "fly_loop", "position_family", "flight_codec", "fly_many",
    "fly_compiled",
    "fly_batch", "fly_one_by_one", "fly_lanes", "fly_lanes_compiled", "lanes_apply", "PER_VEHICLE", "cores",
]

# --- sensors: IMU at the plant rate, 60 Hz tracking with delay -----------------------------------------

PENDING = 4
"""Tracking samples in transit at most (the delay is under three sample periods)."""


class SensorConst(NamedTuple):
    gyro_noise_rad_s: float
    accel_noise_m_s2: float
    gyro_bias_rad_s: Vec3
    accel_bias_m_s2: Vec3
    gyro_keys: tuple[int, int, int]
    accel_keys: tuple[int, int, int]
    mocap_keys: tuple[int, int, int, int, int, int]
    mocap_period_s: float
    mocap_delay_s: float
    mocap_pos_noise_m: float
    mocap_att_noise_rad: float
    velocity_alpha: float
    accel_alpha: float


class Pending(NamedTuple):
    due_s: float
    taken_s: float
    pos_ned_m: Vec3
    q: Quat


class MocapState(NamedTuple):
    next_s: float
    """when the next sample is taken"""
    taken: int
    """samples taken so far (the noise counter)"""
    pending: tuple[Pending, Pending, Pending, Pending]
    """in transit, oldest at index PENDING - n_pending"""
    n_pending: int
    latest: MocapSample
    has_prev: bool
    pos_prev: Vec3


def sensor_const(params: object, seed: int, dt_s: float) -> SensorConst:
    p = params
    b = rng.normals(seed, "bias", 6, 0)
    gb, ab = p.gyro_bias_rad_s, p.accel_bias_m_s2  # type: ignore[attr-defined]
    period = 1.0 / p.mocap_rate_hz  # type: ignore[attr-defined]
    if p.mocap_delay_s > (PENDING - 1) * period:  # type: ignore[attr-defined]
        raise ValueError(f"mocap_delay_s: at most {PENDING - 1} sample periods")
    g, a, m = rng.STREAMS["gyro"], rng.STREAMS["accel"], rng.STREAMS["mocap"]
    return SensorConst(
        float(p.gyro_noise_rad_s), float(p.accel_noise_m_s2),  # type: ignore[attr-defined]
        (gb * b[0], gb * b[1], gb * b[2]), (ab * b[3], ab * b[4], ab * b[5]),
        (rng.key(seed, g, 0), rng.key(seed, g, 1), rng.key(seed, g, 2)),
        (rng.key(seed, a, 0), rng.key(seed, a, 1), rng.key(seed, a, 2)),
        tuple(rng.key(seed, m, i) for i in range(6)),  # type: ignore[arg-type]
        period, float(p.mocap_delay_s), float(p.mocap_pos_noise_m), float(p.mocap_att_noise_rad),  # type: ignore[attr-defined]
        float(lowpass_alpha(2.0 * math.pi * p.velocity_filter_hz, period)),  # type: ignore[attr-defined]
        float(lowpass_alpha(2.0 * math.pi * p.accel_filter_hz, period)))  # type: ignore[attr-defined]


@jitable
def imu_sample(c: SensorConst, body: RigidBody, forces: Forces, k: int) -> tuple[Vec3, Vec3]:
    """Gyro [rad/s] and accelerometer [m/s^2] readings at step ``k`` (:func:`imu_reading`)."""
    gk, ak = c.gyro_keys, c.accel_keys
    return imu_reading(body.omega_rad_s, c.gyro_bias_rad_s, c.gyro_noise_rad_s,
                       (rng.normal(gk[0], k), rng.normal(gk[1], k), rng.normal(gk[2], k)),
                       forces.specific_force_body_m_s2, c.accel_bias_m_s2, c.accel_noise_m_s2,
                       (rng.normal(ak[0], k), rng.normal(ak[1], k), rng.normal(ak[2], k)))


@jitable
def mocap_init(body: RigidBody) -> MocapState:
    empty = Pending(0.0, 0.0, ZERO3, quat.IDENTITY)
    return MocapState(0.0, 0, (empty, empty, empty, empty), 0,
                      MocapSample(0.0, body.pos_ned_m, ZERO3, ZERO3, body.q), False, ZERO3)


@jitable
def mocap_step(c: SensorConst, st: MocapState, t_s: float, body: RigidBody) -> tuple[MocapState, bool]:
    """Take a sample when one is due, deliver those whose delay has passed; (state, delivered).

    The queue is read at fixed positions only (a position chosen at run time would copy the whole
    queue, which in lanes is 36 registers): the samples in transit are the last ``n_pending``,
    oldest first, their due times increasing."""
    next_s, taken, pending, n = st.next_s, st.taken, st.pending, st.n_pending
    due = t_s + 1e-9
    if due < next_s and _head_due_s(pending, n) > due:
        return st, False  # 15 of 16 steps: nothing to take or deliver, the state is not rebuilt
    if due >= next_s:
        k = c.mocap_keys
        pos, q = tracked_pose(body.pos_ned_m, body.q, c.mocap_pos_noise_m, c.mocap_att_noise_rad,
                              (rng.normal(k[0], taken), rng.normal(k[1], taken), rng.normal(k[2], taken)),
                              (rng.normal(k[3], taken), rng.normal(k[4], taken), rng.normal(k[5], taken)))
        pending = pending[1:] + (Pending(t_s + c.mocap_delay_s, t_s, pos, q),)
        n = min(n + 1, PENDING)
        taken += 1
        next_s += c.mocap_period_s
    m = (st.latest, st.has_prev, st.pos_prev, n, False)
    m = _deliver_if_due(c, m, pending[0], PENDING - 4, due)
    m = _deliver_if_due(c, m, pending[1], PENDING - 3, due)
    m = _deliver_if_due(c, m, pending[2], PENDING - 2, due)
    m = _deliver_if_due(c, m, pending[3], PENDING - 1, due)
    latest, has_prev, pos_prev, n, fresh = m
    return MocapState(next_s, taken, pending, n, latest, has_prev, pos_prev), fresh


@jitable
def _head_due_s(pending: tuple[Pending, Pending, Pending, Pending], n: int) -> float:
    """When the oldest sample in transit is due (infinity when none is)."""
    if n == 0:
        return math.inf
    if n == 4:
        return pending[0].due_s
    if n == 3:
        return pending[1].due_s
    if n == 2:
        return pending[2].due_s
    return pending[3].due_s


@jitable
def _deliver_if_due(c: SensorConst, m: tuple[MocapSample, bool, Vec3, int, bool], sample: Pending, j: int,
                    due: float) -> tuple[MocapSample, bool, Vec3, int, bool]:
    """Deliver ``sample``, at position ``j`` of the queue, if it is in transit and due:
    ``m`` is (latest, has_prev, pos_prev, n_pending, delivered)."""
    latest, has_prev, pos_prev, n, fresh = m
    if j < PENDING - n or sample.due_s > due:
        return m
    latest, has_prev, pos_prev = _deliver(c, latest, has_prev, pos_prev, sample.taken_s, sample.pos_ned_m, sample.q)
    return latest, has_prev, pos_prev, n - 1, True


@jitable
def _deliver(c: SensorConst, latest: MocapSample, has_prev: bool, prev: Vec3, taken_s: float, pos: Vec3,
             q: Quat) -> tuple[MocapSample, bool, Vec3]:
    """The delivered sample differentiated against the one before (:func:`differentiated`)."""
    if not has_prev:
        return MocapSample(taken_s, pos, ZERO3, ZERO3, q), True, pos
    return differentiated(latest, prev, taken_s, pos, q, c.velocity_alpha, c.accel_alpha), True, pos


# --- wind: mean + Dryden turbulence ---------------------------------------------------------------------


class WindConst(NamedTuple):
    mean_ned_m_s: Vec3
    enabled: bool
    u: tuple[float, float]
    v: tuple[float, float, float, float, float]
    w: tuple[float, float, float, float, float]
    cv: tuple[float, float]
    cw: tuple[float, float]
    sigma: Vec3
    cos_heading: float
    sin_heading: float
    keys: tuple[int, int, int]
    init_keys: tuple[int, int, int, int, int, int]
    chol_v: tuple[float, float, float]
    chol_w: tuple[float, float, float]


class WindState(NamedTuple):
    xu: float
    xv: tuple[float, float]
    xw: tuple[float, float]


def wind_const(params: object, seed: int, dt_s: float) -> WindConst:
    """The Dryden forming filters of :mod:`sitl.plant.wind` for ``params``, with the vehicle's keys."""
    from .wind import _first_order, _second_order, dryden_low_altitude

    p = params
    tp = p.turbulence  # type: ignore[attr-defined]
    m = tuple(float(x) for x in p.mean_ned_m_s)  # type: ignore[attr-defined]
    s = rng.STREAMS["wind"]
    keys = (rng.key(seed, s, 0), rng.key(seed, s, 1), rng.key(seed, s, 2))
    init_keys = tuple(rng.key(seed, s, 3 + i) for i in range(6))
    if not tp.enabled:
        z5 = (0.0, 0.0, 0.0, 0.0, 0.0)
        return WindConst(m, False, (0.0, 0.0), z5, z5, (0.0, 0.0), (0.0, 0.0), ZERO3, 1.0, 0.0, keys,  # type: ignore[arg-type]
                         init_keys, ZERO3, ZERO3)  # type: ignore[arg-type]
    horiz = math.hypot(m[0], m[1])
    airspeed = max(math.sqrt(horiz**2 + m[2] ** 2), tp.min_airspeed_m_s)
    heading = math.atan2(m[1], m[0]) if horiz > 1e-9 else 0.0
    if any(x > 0.0 for x in tp.sigma_m_s):
        sigma = tp.sigma_m_s
        _, lengths = dryden_low_altitude(tp.altitude_m, 1.0)
    else:
        sigma, lengths = dryden_low_altitude(tp.altitude_m, tp.w20_m_s)
    u = _first_order(dt_s, lengths[0] / airspeed)
    v, cv, chol_v = _second_order(dt_s, lengths[1] / airspeed)
    w, cw, chol_w = _second_order(dt_s, lengths[2] / airspeed)
    return WindConst(m, True, u, v, w, cv, cw, tuple(float(x) for x in sigma), math.cos(heading),  # type: ignore[arg-type]
                     math.sin(heading), keys, init_keys,  # type: ignore[arg-type]
                     (float(chol_v[0, 0]), float(chol_v[1, 0]), float(chol_v[1, 1])),
                     (float(chol_w[0, 0]), float(chol_w[1, 0]), float(chol_w[1, 1])))


@jitable
def wind_init(c: WindConst) -> WindState:
    """Every forming filter started in its stationary distribution, not in calm air."""
    k = c.init_keys
    n0 = (rng.normal(k[0], 0), rng.normal(k[1], 0), rng.normal(k[2], 0))
    n1v, n1w = rng.normal(k[4], 0), rng.normal(k[5], 0)
    cv, cw = c.chol_v, c.chol_w
    return WindState(n0[0], (cv[0] * n0[1], cv[1] * n0[1] + cv[2] * n1v), (cw[0] * n0[2], cw[1] * n0[2] + cw[2] * n1w))


@jitable
def wind_step(c: WindConst, st: WindState, k: int) -> tuple[WindState, Vec3]:
    """The NED wind [m/s] at step ``k``: the mean plus the turbulence rotated from the wind axes."""
    m = c.mean_ned_m_s
    if not c.enabled:
        return st, m
    keys = c.keys
    xu, xv, xw = dryden_advance(c.u, c.v, c.w, st.xu, st.xv, st.xw,
                                rng.normal(keys[0], k), rng.normal(keys[1], k), rng.normal(keys[2], k))
    gust = dryden_gust(c.sigma, c.cv, c.cw, xu, xv, xw)
    return WindState(xu, xv, xw), wind_ned(m, c.cos_heading, c.sin_heading, gust)


# --- external forces and torques ----------------------------------------------------------------------

def profiles_array(profiles: object) -> NDArray[np.float64]:
    """Profiles (:class:`sitl.plant.disturbances.Profile`) as rows ``kind, value (3), start, stop,
    rise, f0, f1, end_scale`` (at least one row, all zero for none: a step that never starts)."""
    rows = [[PROFILE_KINDS.index(p.kind), *p.value, p.start_s, p.stop_s, p.rise_s, p.f0_hz, p.f1_hz, p.end_scale]
            for p in profiles]  # type: ignore[attr-defined]
    arr = np.array(rows, dtype=np.float64).reshape(-1, 10)
    return arr


@jitable
def profiles_at(rows: NDArray[np.float64], t_s: float) -> Vec3:
    """Sum of the profiles at ``t_s``."""
    x = 0.0
    y = 0.0
    z = 0.0
    for i in range(rows.shape[0]):
        r = rows[i]
        k = profile_factor(int(r[0]), r[4], r[5], r[6], r[7], r[8], r[9], t_s)
        if k != 0.0:
            x = x + k * rows[i, 1]
            y = y + k * rows[i, 2]
            z = z + k * rows[i, 3]
    return (x, y, z)


# --- the vehicle: plant + environment + sensors + onboard 1 kHz loop -------------------------------------------


class VehicleConst(NamedTuple):
    dt_s: float
    plant: PlantConst
    sensors: SensorConst
    wind: WindConst
    forces: NDArray[np.float64]
    torques: NDArray[np.float64]
    attitude: AttitudeConst
    rotors: RotorModel
    """the firmware's nominal rotors (the mixer)"""
    command_min_rad_s: float
    command_max_rad_s: float
    command_step_rad_s: float
    estimator_attitude_gain: float
    estimator_bias_gain: float


class VehicleState(NamedTuple):
    k: int
    """plant steps so far (the noise counter of the per-step draws)"""
    t_s: float
    body: RigidBody
    forces: Forces
    wind_state: WindState
    wind_ned_m_s: Vec3
    gyro_rad_s: Vec3
    """last IMU sample"""
    specific_force_body_m_s2: Vec3
    sf_sum: Vec3
    """sum of the accelerometer samples since the position loop last read them"""
    sf_count: int
    mocap: MocapState
    q_est: Quat
    gyro_bias_est: Vec3
    omega_est: Vec3
    """bias-corrected gyro rate the firmware uses"""
    attitude: AttitudeState
    torque_applied_nm: Vec3
    thrust_applied_n: float
    rotor_cmd_rad_s: Rotors4


def vehicle_const(sc: object, attitude_kind: str, seed: int) -> VehicleConst:
    """Everything about one vehicle that does not change in flight (``sc`` a Scenario)."""
    dt = 1.0 / sc.plant_rate_hz  # type: ignore[attr-defined]
    v, af = sc.vehicle, sc.airframe  # type: ignore[attr-defined]
    levels = af.rotor_command_levels
    w_min, w_max = v.rotor_speed_min_rad_s, v.rotor_speed_max_rad_s
    est = sc.estimator  # type: ignore[attr-defined]
    return VehicleConst(
        dt, plant_const(sc.plant_vehicle, af, dt), sensor_const(sc.sensors, seed, dt),  # type: ignore[attr-defined]
        wind_const(sc.wind, seed, dt), profiles_array(sc.forces), profiles_array(sc.torques),  # type: ignore[attr-defined]
        attitude_const(attitude_kind, sc.attitude, v.inertia_kg_m2, dt), RotorModel.of(v),  # type: ignore[attr-defined]
        w_min, w_max, (w_max - w_min) / (levels - 1), float(est.attitude_gain), float(est.bias_gain))


@jitable
def vehicle_init(c: VehicleConst, pos_ned_m: Vec3, yaw_rad: float, hovering: bool) -> VehicleState:
    """At ``pos_ned_m``, level, rotors at hover speed (or stopped on the ground)."""
    p = c.plant
    w = math.sqrt(p.weight_n / (4.0 * p.rotors.k_thrust_n_s2)) if hovering else 0.0
    q = quat.from_yaw(yaw_rad)
    body = RigidBody(pos_ned_m, ZERO3, q, ZERO3, (w, w, w, w))
    sf0 = (0.0, 0.0, -p.gravity_m_s2)
    return VehicleState(0, 0.0, body, Forces(sf0, 0.0, ZERO3, ZERO3, ZERO3), wind_init(c.wind), c.wind.mean_ned_m_s,
                        ZERO3, sf0, ZERO3, 0, mocap_init(body), q, ZERO3, ZERO3, attitude_init(), ZERO3, 0.0,
                        (0.0, 0.0, 0.0, 0.0))


@jitable
def quantise(c: VehicleConst, w_sq: Rotors4) -> Rotors4:
    """Rotor speed commands [rad/s] for squared speeds: clipped to range, then quantised (8 bit)."""
    lo, hi, step = c.command_min_rad_s, c.command_max_rad_s, c.command_step_rad_s
    return (command_level(w_sq[0], lo, hi, step), command_level(w_sq[1], lo, hi, step),
            command_level(w_sq[2], lo, hi, step), command_level(w_sq[3], lo, hi, step))


@jitable
def vehicle_step(c: VehicleConst, st: VehicleState, sp: AttitudeSetpoint, motors_on: bool,
                 extra_force_ned_n: Vec3, extra_torque_nm: Vec3) -> VehicleState:
    """One plant step with the firmware tracking ``sp``."""
    dt, t = c.dt_s, st.t_s
    b = st.gyro_bias_est
    g = st.gyro_rad_s
    omega = (g[0] - b[0], g[1] - b[1], g[2] - b[2])
    q_est = quat.integrate(st.q_est, omega, dt)
    attitude = st.attitude
    if motors_on:
        attitude, tau = attitude_step(c.attitude, attitude, q_est, omega, sp.q_d, sp.omega_d_rad_s,
                                      st.torque_applied_nm, sp.omega_d_dot_rad_s2)
        cmd = quantise(c, rotor_speeds_sq_for(tau, sp.thrust_n, c.rotors))
        torque_applied, thrust_applied = wrench_from_rotor_speeds(cmd, c.rotors)
    else:
        cmd, torque_applied, thrust_applied = (0.0, 0.0, 0.0, 0.0), ZERO3, 0.0
    wind_state, wind = wind_step(c.wind, st.wind_state, st.k)
    f = profiles_at(c.forces, t)
    force = (f[0] + extra_force_ned_n[0], f[1] + extra_force_ned_n[1], f[2] + extra_force_ned_n[2])
    tq = profiles_at(c.torques, t)
    torque = (tq[0] + extra_torque_nm[0], tq[1] + extra_torque_nm[1], tq[2] + extra_torque_nm[2])
    body, forces = plant_step(c.plant, st.body, cmd, wind, force, torque, dt)
    gyro, sf = imu_sample(c.sensors, body, forces, st.k)
    s = st.sf_sum
    t = t + dt
    mocap, fresh = mocap_step(c.sensors, st.mocap, t, body)
    bias = b
    if fresh:
        q_est, bias = estimator_correct(c.estimator_attitude_gain, c.estimator_bias_gain, q_est, bias,
                                        mocap.latest.q)
    return VehicleState(st.k + 1, t, body, forces, wind_state, wind, gyro, sf,
                        (s[0] + sf[0], s[1] + sf[1], s[2] + sf[2]), st.sf_count + 1,
                        mocap, q_est, bias, omega, attitude, torque_applied, thrust_applied, cmd)


@jitable
def mean_specific_force(st: VehicleState) -> Vec3:
    """Mean accelerometer reading since the position loop last read it (the last one if none)."""
    n = st.sf_count
    if n == 0:
        return st.specific_force_body_m_s2
    k = 1.0 / n
    s = st.sf_sum
    return (s[0] * k, s[1] * k, s[2] * k)


# --- a flight: the vehicle flown by the position loop, logged --------------------------------------------------

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


class FlightConst(NamedTuple):
    vehicle: VehicleConst
    loop: LoopConst
    trajectory: TrajectoryConst
    waypoints: NDArray[np.float64]
    """rows ``at_s, x, y, z, yaw_rad`` (the first is the hover setpoint, at -inf)"""
    filtered: bool
    """the reference follows the waypoints through the filter (else it jumps to the setpoint)"""
    pos_div: int
    log_div: int
    observer_uses_imu: bool
    gravity_m_s2: float


def flight_const(sc: object, position_kind: str, attitude_kind: str, seed: int) -> FlightConst:
    v = vehicle_const(sc, attitude_kind, seed)
    pos_div = int(round(sc.plant_rate_hz / sc.position_rate_hz))  # type: ignore[attr-defined]
    pos_dt = pos_div * v.dt_s
    g = sc.position  # type: ignore[attr-defined]
    pc = position_const(position_kind, g, sc.vehicle.mass_kg, sc.vehicle.gravity_m_s2, pos_dt)  # type: ignore[attr-defined]
    lc = loop_const(pc, g, sc.vehicle, sc.reference, rate_const(sc.reference, pos_dt))  # type: ignore[attr-defined]
    sp = sc.setpoint  # type: ignore[attr-defined]
    rows = [[-math.inf, *sp.position_ned_m, math.radians(sp.yaw_deg)]]
    rows += [[w.at_s, *w.position_ned_m, math.radians(w.yaw_deg)] for w in sp.waypoints]
    return FlightConst(v, lc, TrajectoryConst.of(sc.trajectory), np.array(rows, dtype=np.float64),  # type: ignore[attr-defined]
                       bool(sp.waypoints), pos_div, max(1, int(round(sc.plant_rate_hz / sc.log_rate_hz))),  # type: ignore[attr-defined]
                       bool(g.observer_uses_imu), float(sc.vehicle.gravity_m_s2))  # type: ignore[attr-defined]


@jitable
def target_at(rows: NDArray[np.float64], t_s: float) -> tuple[Vec3, float]:
    """The setpoint's target and yaw at ``t_s``: the last waypoint whose time has come."""
    i = 0
    for j in range(1, rows.shape[0]):
        if t_s >= rows[j, 0]:
            i = j
    return (rows[i, 1], rows[i, 2], rows[i, 3]), rows[i, 4]


_widen = lanes.widener(frozenset({"t_s", "next_s", "due_s", "taken_s", "time_s"}))
"""The flight's state with lanes for every number but the clock's (the time, the tracking
system's schedule), which the vehicles of a batch share."""


@jitable
def fly_loop(c: FlightConst, steps: int, logs: NDArray[np.float64]) -> VehicleState:
    """Fly ``steps`` plant steps from a hover at the setpoint; log every ``log_div`` steps into
    ``logs[k]`` for the k-th vehicle of ``c`` (rows of LOG_COLUMNS, ``logs.shape[1]`` rows at most).
    Returns the final state. ``c`` is one vehicle's (``logs`` a block of one) or, with lanes for its
    per-vehicle numbers, W vehicles' (:func:`fly_lanes`): the same code flies both."""
    vc = c.vehicle
    pos0, yaw0 = target_at(c.waypoints, 0.0)
    hover = c.loop.position.mass_kg * c.gravity_m_s2  # the controller's nominal weight
    st = _widen(vehicle_init(vc, pos0, yaw0, True), hover)
    ls = _widen(LoopState(position_init(), ZERO3, hover, quat.IDENTITY, False, rate_init()), hover)
    sp = _widen(AttitudeSetpoint(st.body.q, ZERO3, hover, ZERO3), hover)
    ref_state = ReferenceState(pos0, ZERO3, ZERO3, yaw0)
    ref = PositionReference(pos0, ZERO3, ZERO3, yaw0)
    pos_dt = c.pos_div * vc.dt_s
    row = 0
    g = c.gravity_m_s2
    for k in range(steps):
        if k % c.pos_div == 0:
            target, yaw = target_at(c.waypoints, st.t_s)
            if c.filtered:
                ref_state = reference_filter_step(c.trajectory, ref_state, target, yaw, pos_dt)
                ref = PositionReference(ref_state.pos_ned_m, ref_state.vel_ned_m_s, ref_state.accel_ned_m_s2,
                                        ref_state.yaw_rad)
            else:
                ref = PositionReference(target, ZERO3, ZERO3, yaw)
            ms = st.mocap.latest
            if c.observer_uses_imu:
                sf_ned = quat.rotate(st.q_est, mean_specific_force(st))
            else:
                a = ms.accel_ned_m_s2
                sf_ned = (a[0], a[1], a[2] - g)
            st = _drained(st)
            ls, sp = position_loop_step(c.loop, ls, ms.pos_ned_m, ms.vel_ned_m_s, st.q_est, sf_ned, True, ref)
        st = vehicle_step(vc, st, sp, True, ZERO3, ZERO3)
        if k % c.log_div == 0 and row < logs.shape[1]:
            _write_row(logs, row, _log_values(vc, st, ref, sp, ls))
            row += 1
    return st


@jitable
def _drained(st: VehicleState) -> VehicleState:
    """``st`` with the accelerometer sum emptied (the position loop has read it)."""
    return VehicleState(st.k, st.t_s, st.body, st.forces, st.wind_state, st.wind_ned_m_s, st.gyro_rad_s,
                        st.specific_force_body_m_s2, ZERO3, 0, st.mocap, st.q_est, st.gyro_bias_est, st.omega_est,
                        st.attitude, st.torque_applied_nm, st.thrust_applied_n, st.rotor_cmd_rad_s)


@jitable
def _write_row(logs: NDArray[np.float64], row: int, vals: tuple[float, ...]) -> None:
    """``vals`` into row ``row`` of each vehicle's log (``logs[k]``: vehicle k's, lane k of ``vals``)."""
    for k in range(logs.shape[0]):
        v = lanes.lane(vals, k)
        for i in range(len(v)):
            logs[k, row, i] = v[i]


@jitable
def _log_values(vc: VehicleConst, st: VehicleState, ref: PositionReference, sp: AttitudeSetpoint,
                ls: LoopState) -> tuple[float, ...]:
    """The LOG_COLUMNS of the flight's present state."""
    b, f = st.body, st.forces
    h_att = attitude_disturbance_estimate(vc.attitude, st.attitude)
    vals = (st.t_s, b.pos_ned_m[0], b.pos_ned_m[1], b.pos_ned_m[2], b.vel_ned_m_s[0], b.vel_ned_m_s[1],
            b.vel_ned_m_s[2], ref.pos_ned_m[0], ref.pos_ned_m[1], ref.pos_ned_m[2], ref.vel_ned_m_s[0],
            ref.vel_ned_m_s[1], ref.vel_ned_m_s[2], ref.yaw_rad, b.q[0], b.q[1], b.q[2], b.q[3],
            sp.q_d[0], sp.q_d[1], sp.q_d[2], sp.q_d[3], b.omega_rad_s[0], b.omega_rad_s[1], b.omega_rad_s[2],
            sp.omega_d_rad_s[0], sp.omega_d_rad_s[1], sp.omega_d_rad_s[2], sp.thrust_n,
            ls.force_n[0], ls.force_n[1], ls.force_n[2],
            ls.position.estimate_n[0], ls.position.estimate_n[1], ls.position.estimate_n[2],
            f.disturbance_force_ned_n[0], f.disturbance_force_ned_n[1], f.disturbance_force_ned_n[2],
            h_att[0], h_att[1], h_att[2],
            f.disturbance_torque_nm[0], f.disturbance_torque_nm[1], f.disturbance_torque_nm[2],
            st.attitude.s[0], st.attitude.s[1], st.attitude.s[2],
            ls.position.s[0], ls.position.s[1], ls.position.s[2],
            st.wind_ned_m_s[0], st.wind_ned_m_s[1], st.wind_ned_m_s[2])
    return vals


def position_family(c: FlightConst) -> type:
    """The type of ``c``'s position constants (:data:`~companion.control.position.STEPS`): the
    controller family a batch's rows are packed for and its compiled loop is specialised on."""
    return type(c.loop.position)


PER_VEHICLE = ("vehicle.sensors.gyro_bias_rad_s", "vehicle.sensors.accel_bias_m_s2", "vehicle.attitude",
               "loop.position")
"""The numbers that differ between the vehicles of a batch, the lanes of :func:`fly_lanes`: what the
seed draws (the sensor biases; the noise keys, :data:`PER_VEHICLE_KEYS`) and the gains (a sweep's
``GAIN_TABLES``). Everything else a batch shares (:func:`fly_batch` checks that it does)."""
PER_VEHICLE_KEYS = ("vehicle.sensors.gyro_keys", "vehicle.sensors.accel_keys", "vehicle.sensors.mocap_keys",
                    "vehicle.wind.keys", "vehicle.wind.init_keys")


def _example(position_kind: str) -> FlightConst:
    from .scenario import Scenario

    return flight_const(Scenario(name="codec"), position_kind, "ism_do", 1)


_EXAMPLES = {position_family(c): c for c in map(_example, ("pid", "aibc", "ism_do"))}
assert set(_EXAMPLES) == set(STEPS), "an example flight for each family of position controllers"
_CODECS = {family: codec(c, PER_VEHICLE, PER_VEHICLE_KEYS) for family, c in _EXAMPLES.items()}


def flight_codec(family: type) -> Codec:
    """Per-vehicle rows of a batch whose position controllers are of ``family``
    (:func:`position_family`): every number of a :class:`FlightConst`; its arrays (the force and
    torque profiles, the waypoints: ``flight_codec(family).arrays(c)``) are the batch's."""
    return _CODECS[family]


def _marker(family: type) -> PositionConst:
    """The position constants that stand for ``family`` in a call of a compiled loop: only their
    type is read (it picks the codec), and always the same type, so each family compiles once."""
    return _EXAMPLES[family].loop.position


def _unpack_of(family: type) -> tuple[object, object]:
    """``family``'s unpack functions taking the family's marker first, as :func:`chosen_by_type` calls them."""
    unpack, unpack_lanes = _CODECS[family].unpack, _CODECS[family].unpack_lanes

    def one(position, row, forces, torques, waypoints):  # type: ignore[no-untyped-def]
        return unpack(row, forces, torques, waypoints)

    def in_lanes(position, cols, i0, forces, torques, waypoints):  # type: ignore[no-untyped-def]
        return unpack_lanes(cols, i0, forces, torques, waypoints)

    # a name of their own (see codec.py: compiled code keeps a function by its name and arguments)
    one.__qualname__, in_lanes.__qualname__ = unpack.__name__ + "_flight", unpack_lanes.__name__ + "_flight"
    return one, in_lanes


_UNPACK = {family: _unpack_of(family) for family in _CODECS}
_UNPACK_ONE = {family: u[0] for family, u in _UNPACK.items()}
_UNPACK_LANES = {family: u[1] for family, u in _UNPACK.items()}


@chosen_by_type(_UNPACK_ONE)
def _unpack_flight(position: PositionConst, row: NDArray[np.float64], forces: NDArray[np.float64],
                   torques: NDArray[np.float64], waypoints: NDArray[np.float64]) -> FlightConst:
    """One vehicle's :class:`FlightConst` from its row, by the codec of ``position``'s family."""
    return _UNPACK_ONE[type(position)](position, row, forces, torques, waypoints)  # type: ignore[operator,no-any-return]


@chosen_by_type(_UNPACK_LANES)
def _unpack_lanes(position: PositionConst, cols: NDArray[np.float64], i0: int, forces: NDArray[np.float64],
                  torques: NDArray[np.float64], waypoints: NDArray[np.float64]) -> FlightConst:
    """W vehicles' :class:`FlightConst` from their columns, by the codec of ``position``'s family."""
    return _UNPACK_LANES[type(position)](position, cols, i0, forces, torques,  # type: ignore[operator,no-any-return]
                                         waypoints)


def fly_many(position: PositionConst, rows: NDArray[np.float64], forces: NDArray[np.float64],
             torques: NDArray[np.float64], waypoints: NDArray[np.float64], steps: int, logs: NDArray[np.float64],
             final: NDArray[np.float64]) -> None:
    """:func:`fly_loop` for each vehicle (a row of ``flight_codec`` of ``position``'s family, with the
    batch's arrays), one after another; ``logs[i]`` gets vehicle i's log, ``final[i]`` its last
    position."""
    for i in range(rows.shape[0]):
        st = fly_loop(_unpack_flight(position, rows[i], forces, torques, waypoints), steps, logs[i:i + 1])
        p = st.body.pos_ned_m
        final[i, 0] = p[0]
        final[i, 1] = p[1]
        final[i, 2] = p[2]


def fly_lanes(position: PositionConst, cols: NDArray[np.float64], forces: NDArray[np.float64],
              torques: NDArray[np.float64], waypoints: NDArray[np.float64], steps: int, logs: NDArray[np.float64],
              final: NDArray[np.float64]) -> None:
    """:func:`fly_loop` for W vehicles at a time, each group's per-vehicle numbers in lanes
    (:mod:`.lanes`): ``cols`` is the ``flight_codec`` rows transposed (a column per vehicle), padded to
    a whole number of groups; ``logs`` and ``final`` have a row per real vehicle."""
    n = final.shape[0]
    for i0 in range(0, n, lanes.W):
        st = fly_loop(_unpack_lanes(position, cols, i0, forces, torques, waypoints), steps, logs[i0:i0 + lanes.W])
        for k in range(min(lanes.W, n - i0)):
            p = lanes.lane(st.body.pos_ned_m, k)
            final[i0 + k, 0] = p[0]
            final[i0 + k, 1] = p[1]
            final[i0 + k, 2] = p[2]


if numba_available():
    lanes.register()
fly_compiled = kernel(fly_many, nogil=True)
""":func:`fly_many` compiled (cached on disk) and free of the GIL while it runs, or as it is without
numba. One vehicle flies as a batch of one. Compiled once per family of position controllers (the
type of its first argument), on the family's first flight."""
fly_lanes_compiled = kernel(fly_lanes, nogil=True)
""":func:`fly_lanes` compiled (on its first call: a second compile of the laws, with lanes)."""


def cores() -> int:
    """Cores this process may run on (its CPU affinity)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def fly_batch(family: type, rows: NDArray[np.float64], forces: NDArray[np.float64], torques: NDArray[np.float64],
              waypoints: NDArray[np.float64], steps: int, logs: NDArray[np.float64],
              final: NDArray[np.float64], threads: int | None = None) -> None:
    """Fly every vehicle (a row of ``flight_codec(family)`` each, ``family`` the type of their
    position constants: :func:`position_family`) on every core: ``threads`` (default
    :func:`cores`) Python threads, each a contiguous share of the vehicles, the compiled loop
    releasing the GIL. A batch of at least W vehicles that differ only in :data:`PER_VEHICLE` flies
    in lanes (:data:`fly_lanes_compiled`, W vehicles per instruction); any other (one vehicle, a
    batch that differs elsewhere, numba absent or disabled) flies one vehicle after another
    (:data:`fly_compiled`). Each vehicle is computed alone either way, bit for bit the same, so
    neither the split nor the path changes a number. Threads rather than numba's ``parallel=True``:
    the same speed on this machine, ~4 s less to compile, and no threading layer (numba's OpenMP
    cannot survive a fork(); docs/benchmarks.md)."""
    if rows.shape[1] != flight_codec(family).size:
        raise ValueError(f"rows of {rows.shape[1]} numbers: {family.__name__}'s flights have "
                         f"{flight_codec(family).size} (rows packed for another family?)")
    if rows.shape[0] >= lanes.W and lanes_apply(family, rows):
        _fly_in_lanes(family, rows, forces, torques, waypoints, steps, logs, final, threads)
        return
    fly_one_by_one(family, rows, forces, torques, waypoints, steps, logs, final, threads)


def fly_one_by_one(family: type, rows: NDArray[np.float64], forces: NDArray[np.float64], torques: NDArray[np.float64],
                   waypoints: NDArray[np.float64], steps: int, logs: NDArray[np.float64],
                   final: NDArray[np.float64], threads: int | None = None) -> None:
    """:data:`fly_compiled` over the vehicles, one after another in each of ``threads`` contiguous
    shares: any batch, but no faster per core than one vehicle (``benchmarks/bench_kernel.py``
    measures it beside the lanes)."""
    n = rows.shape[0]
    shares = max(1, min(n, threads or cores()))
    edges = [n * k // shares for k in range(shares + 1)]
    position = _marker(family)
    _in_threads(fly_compiled, [(position, rows[a:b], forces, torques, waypoints, steps, logs[a:b], final[a:b])
                               for a, b in zip(edges[:-1], edges[1:])])


def lanes_apply(family: type, rows: NDArray[np.float64]) -> bool:
    """Whether vehicles ``rows`` can fly in lanes: compiled, and the same in every uniform column."""
    if not numba_available():
        return False
    import numba

    if numba.config.DISABLE_JIT:
        return False
    u = rows[:, list(flight_codec(family).uniform)]
    same = (u == u[0]) | (np.isnan(u) & np.isnan(u[0]))
    return bool(same.all())


def _fly_in_lanes(family: type, rows: NDArray[np.float64], forces: NDArray[np.float64], torques: NDArray[np.float64],
                  waypoints: NDArray[np.float64], steps: int, logs: NDArray[np.float64],
                  final: NDArray[np.float64], threads: int | None) -> None:
    """:data:`fly_lanes_compiled`, whole groups of W vehicles per thread (the last one padded with
    copies of the last vehicle, flown and not kept)."""
    n, w = rows.shape[0], lanes.W
    groups = -(-n // w)
    shares = max(1, min(groups, threads or cores()))
    edges = [min(n, w * (groups * k // shares)) for k in range(shares + 1)]
    jobs = []
    for a, b in zip(edges[:-1], edges[1:]):
        padded = -(-(b - a) // w) * w
        cols = np.empty((rows.shape[1], padded))
        cols[:, :b - a] = rows[a:b].T
        cols[:, b - a:] = rows[b - 1][:, None]
        jobs.append((_marker(family), cols, forces, torques, waypoints, steps, logs[a:b], final[a:b]))
    _in_threads(fly_lanes_compiled, jobs)


def _in_threads(fn: object, jobs: list[tuple[object, ...]]) -> None:
    """``fn(*job)`` for each job, each in its own thread (the caller's for a single job), ``fn``
    compiled first, once among the processes that need it at once (:func:`compile_once`)."""
    compile_once(fn, *jobs[0])
    if len(jobs) == 1:
        fn(*jobs[0])  # type: ignore[operator]
        return
    with ThreadPoolExecutor(len(jobs)) as pool:
        done = [pool.submit(fn, *job) for job in jobs]  # type: ignore[arg-type]
        for d in done:
            d.result()
