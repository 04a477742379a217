"""What 'check accepted it' must mean, judged independently of the loader's own checks:

- every number of the mission is within its envelope row (a walk over the dataclasses that fails
  on a number with no row, so a new parameter cannot slip in unchecked);
- the name is a safe file-name component;
- every position it flies to is inside its safety volume and above the ground;
- it can be flown by the step types: the velocity-limited reference reaches every waypoint within
  the step's timeout, staying inside the volume on the way, and the controller, built as the
  flight builds it and fed a vehicle that follows the reference, produces only finite setpoints
  that the setpoint guard passes.
"""

from __future__ import annotations

import dataclasses
import math
import re

from companion.control.trajectory import ReferenceFilter
from companion.mission import ENVELOPE, Mission
from companion.mission.model import ALLOWED
from companion.flight.offboard import OffboardController
from companion.flight.guard import SetpointGuard
from companion.link.state import VehicleState
from companion.flight.thrust_scale import ThrustScaleEstimator

DEDICATED = {"steps", "safety.volume.north_m", "safety.volume.east_m", "safety.volume.circles",
             "safety.volume.polygons"}
"""numbers the envelope bounds through the volume and step rules rather than one row each"""
SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,63}")
STEP_NUMBERS = {"altitude_m", "duration_s", "speed_m_s", "tolerance_m", "hold_s", "timeout_s", "yaw_deg", "value"}


def _within(key: str, value: float) -> None:
    assert key in ENVELOPE, f"{key}: a number with no envelope row"
    assert ENVELOPE[key].accepts(value), f"{key} = {value!r} outside {ENVELOPE[key].text()}"


def _walk(obj: object, prefix: str) -> None:
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        key = prefix + f.name
        v = getattr(obj, f.name)
        if key in DEDICATED or isinstance(v, bool | str) or v is None:
            continue
        if dataclasses.is_dataclass(v):
            _walk(v, key + ".")
        elif isinstance(v, tuple):
            for x in v:
                _within(key, x)
        else:
            _within(key, v)


def assert_in_envelope(m: Mission) -> None:
    _walk(m, "")
    assert SAFE_NAME.fullmatch(m.name) and ".." not in m.name, m.name
    vol = m.safety.volume
    assert vol.breach((0.0, 0.0, 0.0)) is None
    for c in vol.circles:
        _within("safety.volume.circles[].radius_m", c.radius_m)
    for i, s in enumerate(m.steps):
        for k in ALLOWED[s.action]:
            if k in STEP_NUMBERS and getattr(s, k) is not None:
                _within(f"steps[].{k}", getattr(s, k))
        for p in list(s.waypoints) + ([s.position_ned_m] if s.position_ned_m is not None else []):
            assert vol.breach(p) is None and p[2] <= -0.3, (i, p, vol.breach(p))
        if s.action == "takeoff":
            assert vol.breach((0.0, 0.0, -s.altitude_m)) is None


def _controller(m: Mission) -> OffboardController:
    """As Flight._make_controller builds it (companion/flight/runner.py), without a vehicle to ask."""
    guard = SetpointGuard(math.radians(m.safety.max_tilt_deg), math.radians(m.safety.max_rate_deg_s))
    reference = dataclasses.replace(
        m.reference,
        tilt_max_rad=min(m.reference.tilt_max_rad, math.radians(m.safety.max_tilt_deg - 1.0)),
        rate_limit_rad_s=min(m.reference.rate_limit_rad_s, 0.99 * math.radians(m.safety.max_rate_deg_s)),
    )
    t_max = m.thrust.thrust_max_n or m.vehicle.weight_n / (m.thrust.hover_throttle or 0.5)
    return OffboardController(m.controller.position, m.vehicle, m.gains, reference, m.trajectory,
                              ThrustScaleEstimator(t_max, adapt=m.thrust.adapt), guard,
                              estimate_thrust=m.thrust.estimate, period_s=1.0 / m.controller.rate_hz)


def assert_flyable(m: Mission, controller_ticks: int = 40, hold_cap_s: float = 300.0) -> None:
    """Fly ``m`` dry. A reference filter follows the mission as the flight's would (one filter,
    its speed set per step): every goto waypoint must settle within its timeout and the reference
    must stay inside the volume throughout (stepped at the control period, or 20 ms if that is
    shorter: a longer step is the harder one for the filter); for the first ``controller_ticks``
    ticks of each target the controller runs on a vehicle that follows its reference exactly."""
    ref_dt_s = max(1.0 / m.controller.rate_hz, 0.02)
    assert_in_envelope(m)
    c = _controller(m)
    vol = m.safety.volume
    st = VehicleState()
    ref: ReferenceFilter | None = None
    t = 0.0

    def control(target: tuple, yaw_rad: float | None, speed: float | None) -> None:
        nonlocal t
        assert ref is not None and c.filter is not None
        c.filter = ReferenceFilter(c.filter.params, ref.pos_ned_m, c.filter.yaw_rad, ref.vel_ned_m_s,
                                   ref.accel_ned_m_s2)
        c.set_target(target, yaw_rad, speed_m_s=speed)
        dt = 1.0 / m.controller.rate_hz
        saved = st.pos_ned_m, st.vel_ned_m_s
        for _ in range(controller_ticks):
            tick = c.step(st, t, dt)
            sp = tick.setpoint
            assert all(math.isfinite(x) for x in (*sp.q, *sp.body_rates_rad_s, sp.thrust)), tick
            assert tick.rejected is None, tick.rejected
            st.pos_ned_m, st.vel_ned_m_s = tick.reference.pos_ned_m, tick.reference.vel_ned_m_s
            t += dt
            st.t_pos = st.t_att = t
        st.pos_ned_m, st.vel_ned_m_s = saved

    def follow(target: tuple, speed: float | None, limit_s: float, settle: bool) -> None:
        assert ref is not None
        ref.params = dataclasses.replace(ref.params, max_speed_m_s=speed or m.trajectory.max_speed_m_s)
        elapsed = 0.0
        while elapsed < limit_s:
            ref.update(target, 0.0, ref_dt_s)
            elapsed += ref_dt_s
            assert vol.margin_m(ref.pos_ned_m) > -0.01, ("the reference left the volume", ref.pos_ned_m,
                                                         vol.breach(ref.pos_ned_m))
            if math.dist(ref.pos_ned_m, target) < 1e-3 and math.hypot(*ref.vel_ned_m_s) < 1e-3:
                break
        else:
            assert not settle, f"the reference did not settle at {target} within {limit_s:g} s"
        st.pos_ned_m, st.vel_ned_m_s = ref.pos_ned_m, ref.vel_ned_m_s

    target: tuple = (0.0, 0.0, 0.0)
    for s in m.steps:
        if s.action == "takeoff":
            st.pos_ned_m = (st.pos_ned_m[0], st.pos_ned_m[1], -s.altitude_m)
        elif s.action == "offboard":
            st.t_pos = st.t_att = t
            c.start(st)
            ref = ReferenceFilter(m.trajectory, st.pos_ned_m)
            target = st.pos_ned_m
        elif s.action == "hold":
            target = s.position_ned_m if s.position_ned_m is not None else target
            control(target, math.radians(s.yaw_deg) if s.yaw_deg is not None else None, None)
            follow(target, None, min(s.duration_s, hold_cap_s), settle=False)
        elif s.action == "goto":
            for wp in s.waypoints:
                target = wp
                control(wp, None, s.speed_m_s)
                follow(wp, s.speed_m_s, s.timeout_s, settle=True)
        elif s.action == "land":
            st.pos_ned_m, st.vel_ned_m_s = (st.pos_ned_m[0], st.pos_ned_m[1], 0.0), (0.0, 0.0, 0.0)
            ref = None
