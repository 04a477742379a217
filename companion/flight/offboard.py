"""One tick of offboard control: telemetry in, a checked SET_ATTITUDE_TARGET out.

The position loop of the control core (:class:`~companion.control.PositionLoop`: position
controller, force limits, (32)-(34)) runs on the newest telemetry; the reference comes from the
velocity-limited waypoint filter; newtons become normalised thrust through the (online
estimated) thrust scale; the guard checks the result. No I/O here: the app sends it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

from companion.control import quaternion as quat
from companion.control.outer_loop import AttitudeSetpoint, PositionLoop, PositionMeasurement
from companion.control.params import PositionGains, ReferenceParams, TrajectoryParams, VehicleParams
from companion.control.trajectory import PositionReference, ReferenceFilter
from companion.control.vector import Vec3, add, scale

from .control_time import ControllerTime, default_lead_s
from .guard import SetpointGuard
from .output import Output
from companion.link.state import VehicleState
from .thrust_scale import ThrustScaleEstimator

__all__ = ["Setpoint", "PositionTarget", "Tick", "OffboardController", "propagate", "MAX_PROPAGATION_S", "AUTOPILOT",
           "MAX_POSITION_ERROR_M", "bounded_position"]

MAX_PROPAGATION_S = 0.1
"""the longest a position sample is propagated forward (beyond, it is stale anyway)"""
MAX_POSITION_ERROR_M = 5.0
"""the largest position error the controller is shown [m]: a position that jumps (an estimator
reset too small or too slow to be found, link/resets.py) commands at most what 5 m does. Above
the errors the controllers really fly: ISM+DO's 45 deg hover peaks at 0.7 m, but the baselines'
at 3.3 m (PID) and 4.8 m (the autopilot's own, on PX4); at 1 m PID's hover45 was carried out of
its 10 m volume, the comparison no longer the paper's."""


def bounded_position(pos_ned_m: Vec3, ref_ned_m: Vec3, max_error_m: float) -> Vec3:
    """``pos_ned_m`` moved towards ``ref_ned_m`` until it is at most ``max_error_m`` from it."""
    d = (pos_ned_m[0] - ref_ned_m[0], pos_ned_m[1] - ref_ned_m[1], pos_ned_m[2] - ref_ned_m[2])
    n = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if not n > max_error_m:
        return pos_ned_m
    k = max_error_m / n
    return (ref_ned_m[0] + k * d[0], ref_ned_m[1] + k * d[1], ref_ned_m[2] + k * d[2])


def propagate(pos_ned_m: Vec3, vel_ned_m_s: Vec3, specific_force_ned_m_s2: Vec3 | None, gravity_m_s2: float,
              dt_s: float) -> tuple[Vec3, Vec3]:
    """Position and velocity measured ``dt_s`` ago, carried forward to now at the measured
    acceleration ``f + g e3`` (constant velocity without an IMU).

    Telemetry is 10-40 ms old when a tick uses it. Compared with the reference *now*, a vehicle
    flying 2 m/s would show 2-8 cm of error that is only latency; the integral terms then learn
    to fly that far ahead of the reference. Carried forward, the controller compares like with
    like."""
    f = specific_force_ned_m_s2
    a = (0.0, 0.0, 0.0) if f is None else (f[0], f[1], f[2] + gravity_m_s2)
    pos = add(add(pos_ned_m, scale(dt_s, vel_ned_m_s)), scale(0.5 * dt_s * dt_s, a))
    vel = add(vel_ned_m_s, scale(dt_s, a))
    return pos, vel


class VelocityDifferentiator:
    """Specific force ``a - g e3`` [m/s^2, NED] from the velocity telemetry, when no IMU reaches us:
    a backward difference between velocity samples (at their own stamps, each used once), low-passed
    with ``time_constant_s`` (0.15 s: position telemetry at 60 Hz, differenced twice on the way, is noisy). None
    until two samples have arrived."""

    def __init__(self, time_constant_s: float = 0.15) -> None:
        self.time_constant_s = time_constant_s
        self._last: tuple[float, Vec3] | None = None
        self._accel: Vec3 | None = None

    def update(self, vel_ned_m_s: Vec3, t_s: float, gravity_m_s2: float) -> Vec3 | None:
        last = self._last
        if last is None or t_s > last[0]:
            if last is not None and t_s - last[0] < 1.0:
                dt = t_s - last[0]
                raw = scale(1.0 / dt, (vel_ned_m_s[0] - last[1][0], vel_ned_m_s[1] - last[1][1],
                                       vel_ned_m_s[2] - last[1][2]))
                k = 1.0 - math.exp(-dt / self.time_constant_s)
                a0 = self._accel if self._accel is not None else raw
                self._accel = add(a0, scale(k, (raw[0] - a0[0], raw[1] - a0[1], raw[2] - a0[2])))
            self._last = (t_s, vel_ned_m_s)
        if self._accel is None:
            return None
        a = self._accel
        return (a[0], a[1], a[2] - gravity_m_s2)


class Setpoint(NamedTuple):
    """What goes on the wire: attitude (body to NED), body rates, normalised thrust."""

    q: tuple[float, float, float, float]
    body_rates_rad_s: Vec3
    thrust: float


class PositionTarget(NamedTuple):
    """The reference itself, for the autopilot's own position controller (controller "autopilot")."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    accel_ned_m_s2: Vec3
    yaw_rad: float


AUTOPILOT = "autopilot"
"""the controller name that flies the reference with the autopilot's own position control: the
same mission, reference and record, the comparison every companion figure is bounded against"""

_NAN3 = (math.nan, math.nan, math.nan)


class Tick(NamedTuple):
    """Everything one control tick computed, for the flight record."""

    t: float
    reference: PositionReference
    attitude: AttitudeSetpoint
    force_n: Vec3
    estimate_n: Vec3
    setpoint: Setpoint | PositionTarget
    rejected: str | None


@dataclass
class OffboardController:
    controller: str
    vehicle: VehicleParams
    gains: PositionGains
    reference: ReferenceParams
    trajectory: TrajectoryParams
    thrust: ThrustScaleEstimator
    guard: SetpointGuard
    output: Output = Output("attitude_rates", "")
    """what of the setpoint goes on the wire (flight/output.py); the guard judges that"""
    estimate_thrust: bool = True
    period_s: float = 0.01
    max_error_m: float = MAX_POSITION_ERROR_M

    def __post_init__(self) -> None:
        self.differentiator = VelocityDifferentiator()
        self.acceleration_source = ""
        self.passthrough = self.controller == AUTOPILOT
        self.loop = PositionLoop.create("pid" if self.passthrough else self.controller, self.vehicle, self.gains,
                                        self.reference)
        self.time = ControllerTime(self.period_s, default_lead_s(self.period_s))
        self.last: Tick | None = None
        self.filter: ReferenceFilter | None = None
        self.target: Vec3 = (0.0, 0.0, 0.0)
        self.target_yaw = 0.0
        self.speed_m_s = self.trajectory.max_speed_m_s

    def start(self, state: VehicleState) -> None:
        """Begin where the vehicle is, moving as it moves, with its current thrust as the observer's
        'applied' thrust (hover)."""
        yaw = float(quat.to_euler(state.q)[2])
        self.filter = ReferenceFilter(self.trajectory, state.pos_ned_m, yaw, state.vel_ned_m_s)
        self.target, self.target_yaw = state.pos_ned_m, yaw
        self.loop.reset()
        self.loop.thrust_n = self.vehicle.weight_n
        self.time.restart()
        self.last = None

    def set_target(self, pos_ned_m: Vec3, yaw_rad: float | None = None, speed_m_s: float | None = None) -> None:
        self.target = pos_ned_m
        if yaw_rad is not None:
            self.target_yaw = yaw_rad
        speed = speed_m_s if speed_m_s is not None else self.trajectory.max_speed_m_s
        if self.filter is not None and speed != self.filter.params.max_speed_m_s:
            self.filter.params = dataclasses.replace(self.filter.params, max_speed_m_s=speed)

    @property
    def reference_at_target(self) -> bool:
        f = self.filter
        if f is None:
            return False
        d = math.dist(f.pos_ned_m, self.target)
        return d < 1e-3 and math.hypot(*f.vel_ned_m_s) < 1e-3

    def update(self, state: VehicleState, t_line_s: float) -> tuple[Tick | None, bool]:
        """Advance to the controller's time (see :mod:`companion.flight.control_time`) on the newest
        state: ``(tick, True)`` if it moved, ``(the previous tick, False)`` if there was no new
        vehicle time to step (its setpoint is to be re-sent)."""
        steps = self.time.advance(t_line_s, state.t)
        for dt_s in steps:
            self.last = self.step(state, self.time.t_s, dt_s)
        return self.last, bool(steps)

    def step(self, state: VehicleState, t: float, dt_s: float) -> Tick:
        assert self.filter is not None, "start() first"
        ref = self.filter.update(self.target, self.target_yaw, dt_s)
        if self.passthrough:
            target = PositionTarget(ref.pos_ned_m, ref.vel_ned_m_s, ref.accel_ned_m_s2, float(ref.yaw_rad))
            hover = AttitudeSetpoint(quat.from_yaw(float(ref.yaw_rad)), (0.0, 0.0, 0.0), math.nan)
            return Tick(t, ref, hover, _NAN3, _NAN3, target, None)
        sf = state.specific_force_body_m_s2 if self.gains.observer_uses_imu else None
        if sf is not None:
            sf_ned: Vec3 | None = quat.rotate(state.q, sf)
            self.acceleration_source = "imu"
        else:  # no IMU: differentiated velocity (the paper's own path), once it has two samples
            sf_ned = self.differentiator.update(state.vel_ned_m_s, state.t_pos, self.vehicle.gravity_m_s2)
            self.acceleration_source = "differentiated velocity"
        pos, vel = propagate(state.pos_ned_m, state.vel_ned_m_s, sf_ned, self.vehicle.gravity_m_s2,
                             min(max(t - state.t_pos, 0.0), MAX_PROPAGATION_S))
        pos = bounded_position(pos, ref.pos_ned_m, self.max_error_m)
        meas = PositionMeasurement(pos, vel, state.q, sf_ned)
        att = self.loop.update(meas, ref, dt_s)
        estimate = self.loop.controller.estimate_n
        if self.estimate_thrust and sf_ned is not None:
            self.thrust.update(estimate, state.q, float(att.thrust_n), dt_s)
        u = min(max(self.thrust.normalise(float(att.thrust_n)), 0.0), 1.0)
        q = tuple(float(c) for c in quat.positive_scalar(att.q_d))
        rates = self.output.wire_rates(state.q, q, att.omega_d_rad_s, self.guard.max_rate_rad_s)  # type: ignore[arg-type]
        sp = Setpoint(q, rates, u)  # type: ignore[arg-type]
        rejected = self.guard.check(sp.q, sp.body_rates_rad_s, sp.thrust)
        return Tick(t, ref, att, self.loop.force_n, estimate, sp, rejected)
