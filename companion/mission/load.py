"""Mission files in TOML: what the companion flies, checked completely before anything arms.

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

from pathlib import Path

from companion.config import ConfigError, load_dataclass, load_toml, locate

from .model import ACTIONS, ALLOWED, REQUIRED, Mission, Step

__all__ = ["load_mission"]


def _step_from_table(raw: dict, index: int, path: Path, text: str) -> Step:
    key = f"steps[{index}]"

    def fail(field_name: str, reason: str) -> ConfigError:
        kp = f"{key}.{field_name}" if field_name else key
        return ConfigError(path, locate(text, kp), kp, reason)

    action = raw.get("action")
    if action not in ACTIONS:
        raise fail("action", f"expected one of {', '.join(ACTIONS)}, got {action!r}")
    allowed = set(ALLOWED[action]) | {"action", "name"}
    for k in raw:
        if k not in allowed:
            raise fail(k, f"not a key of a {action!r} step; expected one of: {', '.join(sorted(allowed))}")
    for k in REQUIRED[action]:
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
        from .plan import load_plan

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
