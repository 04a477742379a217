"""QGroundControl ``.plan`` import: take-off, waypoints (relative altitude) and land/RTL items."""

from __future__ import annotations

import json
import math
from pathlib import Path

from companion.config import ConfigError
from companion.control.vector import Vec3

from .model import Mission, Step

__all__ = ["load_plan"]


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
