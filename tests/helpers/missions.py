"""Missions for the tests, written once: the hold mission the integration tests fly (take off to
1.5 m, offboard, hold over the take-off point, land; with a safety volume, a controller table and
extra steps before the hold where a test needs them), and loading a mission text from a file as
a user's would be loaded, or the refusal it gets."""

from __future__ import annotations

from pathlib import Path

import pytest

from companion.config import ConfigError
from companion.mission import Mission, load_mission

HOLD_NED_M = (0.0, 0.0, -1.5)

TAKEOFF_AND_OFFBOARD = """[[steps]]
action = "takeoff"
altitude_m = 1.5

[[steps]]
action = "offboard"

"""
GOTO = """[[steps]]
action = "goto"
waypoints = [[1, 0, -1.5], [1, 1, -1.5]]

"""
LAND = """[[steps]]
action = "land"
"""


def goto_mission(header: str = "", before_land: str = "") -> str:
    """The small mission the file tests load (take off, offboard, two waypoints, land) as a user writes
    it: ``header`` (TOML tables) after its name, ``before_land`` (steps) between the goto and the land."""
    return f'name = "m"\n{header}\n' + TAKEOFF_AND_OFFBOARD + GOTO + before_land + LAND


def toml_value(value: object) -> str:
    """``value`` as a TOML value: a string quoted, a bool lower case, a sequence as an array."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


def step(action: str, name: str | None = None, **fields: object) -> str:
    """One ``[[steps]]`` table of a mission."""
    lines = ["[[steps]]", *([f'name = "{name}"'] if name else []), f'action = "{action}"']
    return "\n".join(lines + [f"{k} = {toml_value(v)}" for k, v in fields.items()]) + "\n"


def sim_param(name: str | None, param: str, value: float) -> str:
    """A step that sets one of the bundled vehicle's SIM_* parameters (a disturbance, a fault)."""
    return step("set_param", name, param=param, value=value, sim_only=True)


def flight_mission(name: str, *steps: str, position: str | None = "ism_do", rate_hz: float | None = None,
                   volume: tuple[float, float] | None = None) -> str:
    """A mission's TOML text: a ``position`` controller table (none if None; at ``rate_hz`` if given),
    a safety ``volume`` (max distance, max altitude [m]) if given, take-off to 1.5 m, offboard, then
    ``steps``."""
    parts = [f'name = "{name}"\n']
    if position is not None:
        parts.append(f'[controller]\nposition = "{position}"\n' + (f"rate_hz = {rate_hz:g}\n" if rate_hz else ""))
    if volume is not None:
        parts.append(f"[safety.volume]\nmax_distance_m = {volume[0]:.1f}\nmax_altitude_m = {volume[1]:.1f}\n")
    return "".join(parts) + step("takeoff", altitude_m=1.5) + step("offboard") + "".join(steps)


def hold_mission(name: str, hold_s: float, *, controller: bool = True, volume: tuple[float, float] | None = None,
                 before_hold: str = "", hold_name: str | None = "hold") -> str:
    """The hold mission: an ISM+DO table at 100 Hz unless not ``controller``, the ``volume`` if
    given, ``before_hold`` (steps) between offboard and the hold over the take-off point, land."""
    steps = (before_hold, step("hold", hold_name, duration_s=hold_s, position_ned_m=HOLD_NED_M), step("land"))
    return flight_mission(name, *steps, position="ism_do" if controller else None, rate_hz=100, volume=volume)


def load_text(tmp_path: Path, text: str, name: str = "m.toml") -> Mission:
    """``text`` written to ``tmp_path / name`` and loaded as the companion loads a mission file."""
    p = tmp_path / name
    p.write_text(text)
    return load_mission(p)


def refusal(tmp_path: Path, text: str, name: str = "m.toml") -> ConfigError:
    """The ConfigError ``text`` gets when loaded from a file (the test fails if it loads)."""
    with pytest.raises(ConfigError) as e:
        load_text(tmp_path, text, name)
    return e.value
