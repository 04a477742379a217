"""Missions: what the companion flies, as data (TOML), checked completely before anything arms.

A mission file names the controller and its gains, the vehicle model, and a list of steps::

    name = "hover45"
    [controller]
    position = "ism_do"           # pid | aibc | pd_do | ism_do
    rate_hz = 100
    [[steps]]
    action = "takeoff"            # the autopilot's own take-off
    altitude_m = 1.5
    [[steps]]
    action = "offboard"           # stream setpoints, then switch to offboard holding here
    [[steps]]
    action = "hold"
    duration_s = 10
    position_ned_m = [0, 0, -1.5]
    [[steps]]
    action = "land"

Actions: ``takeoff``, ``offboard``, ``hold``, ``goto`` (waypoints through the velocity-limited
reference), ``set_param`` (e.g. the simulated vehicle's suspended weight, ``SIM_FORCE_X``),
``wait``, ``land``. Errors name the file, the line, the key and what was expected.

A ``set_param`` step names its parameter with ``param`` (``param = "SIM_FORCE_X"``).
QGroundControl ``.plan`` files are imported by :func:`load_plan`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from companion.config import ConfigError, load_dataclass, load_toml, locate
from companion.control.params import PositionGains, ReferenceParams, TrajectoryParams, VehicleParams
from companion.control.position import POSITION_CONTROLLERS
from companion.control.vector import Vec3

__all__ = ["ACTIONS", "Step", "ControllerConfig", "ThrustConfig", "SafetyConfig", "Mission", "load_mission",
           "load_plan"]

ACTIONS = ("takeoff", "offboard", "hold", "goto", "set_param", "wait", "land")

# which keys each action needs and accepts
_REQUIRED = {
    "takeoff": ("altitude_m",),
    "offboard": (),
    "hold": ("duration_s",),
    "goto": ("waypoints",),
    "set_param": ("param", "value"),
    "wait": ("duration_s",),
    "land": (),
}
_ALLOWED = {
    "takeoff": ("altitude_m", "timeout_s"),
    "offboard": ("timeout_s",),
    "hold": ("duration_s", "position_ned_m", "yaw_deg"),
    "goto": ("waypoints", "speed_m_s", "tolerance_m", "hold_s", "timeout_s"),
    "set_param": ("param", "value", "sim_only"),
    "wait": ("duration_s",),
    "land": ("timeout_s",),
}


@dataclass(frozen=True)
class Step:
    action: str
    name: str = ""
    """shown in the summary; defaults to the action and its index"""
    altitude_m: float = 0.0
    duration_s: float = 0.0
    position_ned_m: Vec3 | None = None
    """hold here (None: where the previous step left the reference)"""
    yaw_deg: float | None = None
    waypoints: tuple[Vec3, ...] = ()
    speed_m_s: float | None = None
    tolerance_m: float = 0.15
    hold_s: float = 0.0
    """how long to stay at each waypoint once reached"""
    param: str = ""
    value: float = 0.0
    sim_only: bool = False
    """skip (with a warning) if the vehicle has no such parameter, e.g. a real vehicle"""
    timeout_s: float = 60.0


@dataclass(frozen=True)
class ControllerConfig:
    position: str = "ism_do"
    rate_hz: float = 100.0

    def __post_init__(self) -> None:
        if self.position not in POSITION_CONTROLLERS:
            raise ValueError(f"position: expected one of {', '.join(POSITION_CONTROLLERS)}, got {self.position!r}")
        if not 10.0 <= self.rate_hz <= 250.0:
            raise ValueError(f"rate_hz: expected 10..250, got {self.rate_hz}")


@dataclass(frozen=True)
class ThrustConfig:
    """Newtons to normalised thrust: ``u = T / thrust_max_n``.

    ``thrust_max_n = 0`` takes it from the vehicle: the simulated vehicle's SIM_THRUST_MAX, else
    ``m g / MPC_THR_HOVER`` (PX4) or ``m g / MOT_THST_HOVER`` (ArduPilot), else ``hover_throttle``.
    The scale is also estimated online from the force observer's vertical estimate.
    """

    thrust_max_n: float = 0.0
    hover_throttle: float = 0.0
    estimate: bool = True
    adapt: bool = True
    """let the online estimate correct the scale (slowly, within +-40%)"""


@dataclass(frozen=True)
class SafetyConfig:
    telemetry_timeout_s: float = 0.3
    """vehicle-clock age of position/attitude beyond which setpoints stop (at a speed-up, the streams
    must also have been silent for at least 0.15 s of wall time); they resume when it is fresh again"""
    stale_hold_s: float = 1.0
    """vehicle seconds of stale telemetry after which the companion also commands hold (PX4's
    COM_OF_LOSS_T default); a shorter outage only pauses the setpoints and the flight goes on"""
    link_lost_s: float = 3.0
    """wall seconds without any telemetry after which the companion gives up and exits with an error"""
    max_tilt_deg: float = 60.0
    max_rate_deg_s: float = 250.0


@dataclass(frozen=True)
class Mission:
    name: str
    description: str = ""
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    gains: PositionGains = field(default_factory=PositionGains)
    reference: ReferenceParams = field(default_factory=ReferenceParams)
    trajectory: TrajectoryParams = field(default_factory=TrajectoryParams)
    thrust: ThrustConfig = field(default_factory=ThrustConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    steps: tuple[Step, ...] = ()


def _step_from_table(raw: dict, index: int, path: Path, text: str) -> Step:
    key = f"steps[{index}]"

    def fail(field_name: str, reason: str) -> ConfigError:
        kp = f"{key}.{field_name}" if field_name else key
        return ConfigError(path, locate(text, kp), kp, reason)

    action = raw.get("action")
    if action not in ACTIONS:
        raise fail("action", f"expected one of {', '.join(ACTIONS)}, got {action!r}")
    allowed = set(_ALLOWED[action]) | {"action", "name"}
    for k in raw:
        if k not in allowed:
            raise fail(k, f"not a key of a {action!r} step; expected one of: {', '.join(sorted(allowed))}")
    for k in _REQUIRED[action]:
        if k not in raw:
            raise fail("action", f"a {action!r} step needs {k!r}")
    step = load_dataclass(Step, raw, path, text, key)
    if not step.name:
        step = _replace(step, name=f"{index + 1}: {action}")
    _check_step(step, fail)
    return step


def _replace(step: Step, **changes: object) -> Step:
    import dataclasses

    return dataclasses.replace(step, **changes)  # type: ignore[arg-type]


def _check_step(s: Step, fail) -> None:  # type: ignore[no-untyped-def]
    if s.action == "takeoff" and not 0.3 <= s.altitude_m <= 100.0:
        raise fail("altitude_m", f"expected 0.3..100 m, got {s.altitude_m}")
    if s.action in ("hold", "wait") and not 0.0 < s.duration_s <= 3600.0:
        raise fail("duration_s", f"expected a duration in (0, 3600] s, got {s.duration_s}")
    if s.action == "goto":
        if not s.waypoints:
            raise fail("waypoints", "expected at least one [north, east, down] waypoint")
        for i, wp in enumerate(s.waypoints):
            if wp[2] > 0.0:
                raise fail(f"waypoints[{i}]", f"down = {wp[2]} m is below the ground (NED: up is negative)")
        if s.speed_m_s is not None and not 0.1 <= s.speed_m_s <= 10.0:
            raise fail("speed_m_s", f"expected 0.1..10 m/s, got {s.speed_m_s}")
    if s.position_ned_m is not None and s.position_ned_m[2] > 0.0:
        raise fail("position_ned_m", f"down = {s.position_ned_m[2]} m is below the ground (NED: up is negative)")
    if s.timeout_s <= 0.0:
        raise fail("timeout_s", f"expected a positive timeout, got {s.timeout_s}")


def load_mission(path: str | Path) -> Mission:
    """A mission from a TOML file (or a QGroundControl ``.plan``); every error names the line."""
    p = Path(path)
    if p.suffix == ".plan":
        return load_plan(p)
    data, text = load_toml(p)
    data.setdefault("name", p.stem)
    steps_raw = data.pop("steps", None)
    if not isinstance(steps_raw, list) or not steps_raw:
        raise ConfigError(p, None, "steps", "expected at least one [[steps]] table")
    mission = load_dataclass(Mission, data, p, text)
    steps = []
    for i, raw in enumerate(steps_raw):
        if not isinstance(raw, dict):
            raise ConfigError(p, locate(text, f"steps[{i}]"), f"steps[{i}]", "expected a table")
        steps.append(_step_from_table(raw, i, p, text))
    _check_sequence(steps, p, text)
    import dataclasses

    return dataclasses.replace(mission, steps=tuple(steps))


def _check_sequence(steps: list[Step], path: Path, text: str) -> None:
    """Order rules: offboard flying needs an 'offboard' step first, which needs to be airborne."""
    airborne = offboard = False
    for i, s in enumerate(steps):
        key = f"steps[{i}]"
        if s.action == "takeoff":
            airborne = True
        elif s.action == "offboard":
            if not airborne:
                raise ConfigError(path, locate(text, key), key, "an 'offboard' step needs a 'takeoff' step before it")
            offboard = True
        elif s.action in ("hold", "goto") and not offboard:
            raise ConfigError(path, locate(text, key), key, f"a {s.action!r} step needs an 'offboard' step before it")
        elif s.action == "land":
            airborne = offboard = False


def _is_number(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _is_coordinate(lat: object, lon: object) -> bool:
    return _is_number(lat) and _is_number(lon) and abs(lat) <= 90.0 and abs(lon) <= 180.0  # type: ignore[operator]


def load_plan(path: str | Path) -> Mission:
    """A QGroundControl ``.plan``: take-off, waypoints (relative altitude) and land/RTL items,
    converted to local NED around the plan's home position by a flat-earth projection."""
    p = Path(path)
    try:
        plan = json.loads(p.read_text(encoding="utf-8"))
        items = plan["mission"]["items"]
        home_lat, home_lon, _ = plan["mission"]["plannedHomePosition"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(p, None, "mission", f"not a QGroundControl plan: {exc}") from None
    if not _is_coordinate(home_lat, home_lon):
        raise ConfigError(p, None, "mission.plannedHomePosition",
                          f"expected [latitude, longitude, altitude] in degrees, got {[home_lat, home_lon]!r}")
    if not isinstance(items, list):
        raise ConfigError(p, None, "mission.items", "expected a list of mission items")
    r = 6378137.0
    steps: list[Step] = []
    waypoints: list[Vec3] = []
    takeoff_alt = 2.5
    for n, item in enumerate(items):
        key = f"mission.items[{n}]"
        if not isinstance(item, dict):
            raise ConfigError(p, None, key, "expected a mission item (an object)")
        cmd, params = item.get("command"), item.get("params", [])
        if item.get("type") != "SimpleItem" or not isinstance(params, list) or len(params) < 7:
            raise ConfigError(p, None, key, "only simple items (with 7 params) are supported")
        lat, lon, alt = params[4], params[5], params[6]
        if cmd in (22, 16) and not (_is_number(alt) and -100.0 <= alt <= 10_000.0):
            raise ConfigError(p, None, f"{key}.params[6]", f"expected an altitude in -100..10000 m, got {alt!r}")
        if cmd == 22:
            takeoff_alt = float(alt)
            if not 0.3 <= takeoff_alt <= 100.0:
                raise ConfigError(p, None, f"{key}.params[6]", f"expected a take-off altitude of 0.3..100 m, "
                                  f"got {takeoff_alt}")
        elif cmd == 16:
            if not _is_coordinate(lat, lon):
                raise ConfigError(p, None, f"{key}.params[4:6]", f"expected latitude and longitude in degrees, "
                                  f"got {[lat, lon]!r}")
            north = math.radians(lat - home_lat) * r
            east = math.radians(lon - home_lon) * r * math.cos(math.radians(home_lat))
            if math.hypot(north, east) > 10_000.0:
                raise ConfigError(p, None, key, f"waypoint {math.hypot(north, east) / 1000:.0f} km from home; "
                                  "expected within 10 km")
            waypoints.append((north, east, -float(alt)))
        elif cmd in (20, 21):
            break
        else:
            raise ConfigError(p, None, f"{key}.command", f"command {cmd!r} is not supported "
                              "(expected 16 waypoint, 22 take-off, 20 RTL or 21 land)")
    steps.append(Step("takeoff", "take-off", altitude_m=takeoff_alt))
    steps.append(Step("offboard", "offboard"))
    if waypoints:
        steps.append(Step("goto", "waypoints", waypoints=tuple(waypoints), hold_s=1.0))
    steps.append(Step("land", "land"))
    return Mission(name=p.stem, description=f"imported from {p.name}", steps=tuple(steps))
