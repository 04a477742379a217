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


def hold_mission(name: str, hold_s: float, *, controller: bool = True, volume: tuple[float, float] | None = None,
                 before_hold: str = "", hold_name: str | None = "hold") -> str:
    """A mission's TOML text. ``controller``: an ISM+DO table at 100 Hz; ``volume``: (max distance,
    max altitude) [m]; ``before_hold``: steps (TOML) between offboard and the hold."""
    parts = [f'name = "{name}"\n']
    if controller:
        parts.append('[controller]\nposition = "ism_do"\nrate_hz = 100\n')
    if volume is not None:
        parts.append(f"[safety.volume]\nmax_distance_m = {volume[0]:.1f}\nmax_altitude_m = {volume[1]:.1f}\n")
    parts.append('[[steps]]\naction = "takeoff"\naltitude_m = 1.5\n[[steps]]\naction = "offboard"\n')
    parts.append(before_hold)
    parts.append("[[steps]]\n" + (f'name = "{hold_name}"\n' if hold_name else "")
                 + f'action = "hold"\nduration_s = {hold_s:.1f}\nposition_ned_m = [0.0, 0.0, -1.5]\n')
    parts.append('[[steps]]\naction = "land"\n')
    return "".join(parts)


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
