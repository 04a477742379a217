"""The flight modes of PX4 and ArduCopter as they appear on the wire, one copy for both ends.

PX4 packs a main and a sub mode into HEARTBEAT ``custom_mode`` as ``main << 16 | sub << 24``;
DO_SET_MODE carries them in param2 and param3 (param1 with MAV_MODE_FLAG_CUSTOM_MODE_ENABLED).
ArduCopter's ``custom_mode`` and DO_SET_MODE param2 are the mode number
(``ArduCopter/mode.h``; PX4 ``src/modules/commander/px4_custom_mode.h``).
"""

from __future__ import annotations

__all__ = ["PX4_MODES", "COPTER_MODES", "px4_custom_mode", "px4_mode_name", "copter_mode_name",
           "copter_mode_number"]

PX4_MODES: dict[str, tuple[int, int]] = {
    "MANUAL": (1, 0), "ALTCTL": (2, 0), "POSCTL": (3, 0), "ACRO": (5, 0), "OFFBOARD": (6, 0),
    "STABILIZED": (7, 0), "TAKEOFF": (4, 2), "HOLD": (4, 3), "MISSION": (4, 4), "RTL": (4, 5),
    "LAND": (4, 6), "PRECLAND": (4, 9),
}
"""name -> (main, sub); HOLD is AUTO.LOITER"""

COPTER_MODES: dict[str, int] = {
    "STABILIZE": 0, "ACRO": 1, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "CIRCLE": 7,
    "LAND": 9, "DRIFT": 11, "SPORT": 13, "FLIP": 14, "AUTOTUNE": 15, "POSHOLD": 16, "BRAKE": 17, "THROW": 18,
    "GUIDED_NOGPS": 20, "SMART_RTL": 21,
}

_PX4_BY_NUMBER = {v: k for k, v in PX4_MODES.items()}
_COPTER_BY_NUMBER = {v: k for k, v in COPTER_MODES.items()}


def px4_custom_mode(name: str) -> int:
    main, sub = PX4_MODES[name]
    return (main << 16) | (sub << 24)


def px4_mode_name(custom_mode: int) -> str:
    main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
    return _PX4_BY_NUMBER.get((main, sub), f"PX4_{main}_{sub}")


def copter_mode_name(custom_mode: int) -> str:
    return _COPTER_BY_NUMBER.get(custom_mode, f"MODE_{custom_mode}")


def copter_mode_number(name: str) -> int:
    return COPTER_MODES[name]
