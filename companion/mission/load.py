"""Mission files in TOML: what the companion flies, checked completely before anything arms.

A mission file names the controller and its gains, the vehicle model, where it may fly, and a
list of steps::

    name = "hover45"              # letters, digits, - _ . : it names the flight record's folder
    [controller]
    position = "ism_do"           # pid | aibc | pd_do | ism_do
    rate_hz = 100
    [safety.volume]               # around home, the take-off point (defaults: cylinder 50 m, 30 m high)
    max_distance_m = 10
    max_altitude_m = 5
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
``wait``, ``land``. A ``set_param`` step names its parameter with ``param``.

Instead of ``[[steps]]``, ``plan = "survey.plan"`` takes the steps (and the geofence) from a
QGroundControl plan next to the file, flown with this file's controller, failsafes and volume; a
plan with no mission items (a fence) gives its fence to this file's ``[[steps]]``.

:func:`load_mission` is the one way in, for ``companion check`` and ``companion fly`` alike: the
file is read within bounds (size, nesting, encoding: :func:`companion.config.read_text`), built into
the dataclasses, then checked whole (:func:`.validate.validate`: names, counts, the envelope, the
safety volume, the order of the steps). Every refusal is a :class:`ConfigError` naming the file,
the line, the key and what was expected. QGroundControl ``.plan`` files go to :func:`.plan.load_plan`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable

from companion.config import ConfigError, load_dataclass, load_toml, locate

from .envelope import MAX_FILE_BYTES, MAX_STEPS, MAX_WAYPOINTS, Problem, is_safe_component, safe_component
from .model import ACTIONS, ALLOWED, REQUIRED, Mission, Step
from .validate import validate

__all__ = ["load_mission"]


def load_mission(path: str | Path) -> Mission:
    """A mission from a TOML file (or a QGroundControl ``.plan``), checked whole; every refusal is
    a :class:`ConfigError` that names the file, the line and the key."""
    p = Path(path)
    if p.suffix == ".plan":
        from .plan import load_plan

        return load_plan(p)
    data, text = load_toml(p, MAX_FILE_BYTES)

    def fail(key: str, reason: str) -> ConfigError:
        return ConfigError(p, _line(text, key), key, reason)

    data.setdefault("name", safe_component(p.stem))
    steps_raw = data.pop("steps", None)
    if "plan" in data:
        return _with_plan(p, text, data, steps_raw, fail)
    mission = load_dataclass(Mission, data, p, text)
    mission = dataclasses.replace(mission, steps=_steps(steps_raw, fail, p, text))
    try:
        validate(mission)
    except Problem as exc:
        raise fail(exc.key, exc.reason) from None
    return mission


def _steps(steps_raw: object, fail: Fail, p: Path, text: str) -> tuple[Step, ...]:
    """The ``[[steps]]`` tables as steps, their count and waypoints bounded before they are built."""
    if not isinstance(steps_raw, list) or not steps_raw:
        raise ConfigError(p, locate(text, "steps"), "steps", "expected at least one [[steps]] table")
    if len(steps_raw) > MAX_STEPS:
        raise fail(f"steps[{MAX_STEPS}]", f"expected at most {MAX_STEPS} steps, got {len(steps_raw)}")
    steps = []
    waypoints = 0
    for i, raw in enumerate(steps_raw):
        if not isinstance(raw, dict):
            raise fail(f"steps[{i}]", "expected a table")
        wps = raw.get("waypoints")
        waypoints += len(wps) if isinstance(wps, list) else 0
        if waypoints > MAX_WAYPOINTS:  # before building thousands of tuples
            raise fail(f"steps[{i}].waypoints", f"expected at most {MAX_WAYPOINTS} waypoints in a mission, "
                       f"got {waypoints} by this step")
        steps.append(_step_from_table(raw, i, fail, p, text))
    return tuple(steps)


def _line(text: str, key: str) -> int | None:
    """The line of ``key``, or of the nearest enclosing key that is written out (a fence inside an
    inline array has no line of its own: the array's is given)."""
    while key:
        line = locate(text, key)
        if line is not None:
            return line
        cut = max(key.rfind("."), key.rfind("["))
        key = key[:cut] if cut > 0 else ""
    return None


Fail = Callable[[str, str], ConfigError]


def _with_plan(p: Path, text: str, data: dict[str, Any], steps_raw: object, fail: Fail) -> Mission:
    """A TOML mission whose steps (and fences) come from a QGroundControl plan next to it: the
    TOML sets the controller, the failsafes and the volume (e.g. a ceiling above a plan's 50 m).
    A plan without mission items (a fence, rally points) gives its fences to the TOML's
    ``[[steps]]``; a plan with items and ``[[steps]]`` as well is refused (which would fly?)."""
    from .plan import import_plan

    name = data.pop("plan")
    if not (isinstance(name, str) and is_safe_component(name) and name.endswith(".plan")):
        raise fail("plan", f"expected the file name of a .plan next to this file (letters, digits, '-', '_', '.'; "
                   f"no directories), got {str(name)[:80]!r}")
    imported = import_plan(p.parent / name)
    if steps_raw is not None and imported.steps:
        raise fail("steps", f"the steps come from {name}'s mission items; expected no [[steps]] with plan = ... "
                   "(or a plan with no mission items: a fence)")
    if steps_raw is None and not imported.steps:
        raise fail("plan", f"{name} has no mission items (a fence-only plan): expected [[steps]] in this file")
    mission = load_dataclass(Mission, data, p, text)
    steps = imported.steps or _steps(steps_raw, fail, p, text)
    vol = mission.safety.volume
    volume = dataclasses.replace(vol, circles=vol.circles + imported.circles, polygons=vol.polygons + imported.polygons)
    mission = dataclasses.replace(mission, description=mission.description or imported.description,
                                  safety=dataclasses.replace(mission.safety, volume=volume), steps=steps)
    try:
        validate(mission)
    except Problem as exc:
        raise imported.error(exc, len(vol.circles), len(vol.polygons)) or fail(exc.key, exc.reason) from None
    return mission


def _step_from_table(raw: dict[str, Any], index: int, fail: Fail, path: Path, text: str) -> Step:
    key = f"steps[{index}]"
    action = raw.get("action")
    if action not in ACTIONS:
        raise fail(f"{key}.action", f"expected one of {', '.join(ACTIONS)}, got {str(action)[:40]!r}")
    allowed = set(ALLOWED[action]) | {"action", "name"}
    for k in raw:
        if k not in allowed:
            raise fail(f"{key}.{k}", f"not a key of a {action!r} step; expected one of: {', '.join(sorted(allowed))}")
    for k in REQUIRED[action]:
        if k not in raw:
            raise fail(f"{key}.action", f"a {action!r} step needs {k!r}")
    step = load_dataclass(Step, raw, path, text, key)
    if not step.name:
        step = dataclasses.replace(step, name=f"{index + 1}: {action}")
    return step
