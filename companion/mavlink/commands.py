"""Commands and their answers: what pymavlink's generated constants leave out.

``MAV_CMD_COMPONENT_ARM_DISARM`` param2 "21196: force arming/disarming" is named in common.xml's
prose only (PX4 and ArduPilot both check for exactly this number), and a MAV_RESULT is reported to
the user in words (one that this pymavlink lacks, CANCELLED, is named here); a command is named
as the dialect spells it.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["FORCE_ARM_DISARM", "MAV_RESULT_CANCELLED", "result_text", "command_name"]

FORCE_ARM_DISARM = 21196
"""MAV_CMD_COMPONENT_ARM_DISARM param2: arm or disarm regardless of the safety checks (disarm in the air)"""

MAV_RESULT_CANCELLED = 6
"""in common.xml (a long-running command cancelled), not in pymavlink 2.4's generated dialect"""

_RESULT_PREFIX = "MAV_RESULT_"


def result_text(result: int) -> str:
    """A MAV_RESULT in words (``MAV_RESULT_TEMPORARILY_REJECTED`` -> "temporarily rejected"), or
    "MAV_RESULT n" for a number the dialect does not know."""
    if result == MAV_RESULT_CANCELLED:
        return "cancelled"
    entry = mavlink.enums["MAV_RESULT"].get(result)
    if entry is None or not entry.name.startswith(_RESULT_PREFIX) or entry.name.endswith("_ENUM_END"):
        return f"MAV_RESULT {result}"
    return entry.name[len(_RESULT_PREFIX):].lower().replace("_", " ")


def command_name(command: int) -> str:
    """A MAV_CMD as the dialect names it, without the prefix (``MAV_CMD_DO_JUMP`` -> "DO_JUMP"); ""
    for a number it does not know."""
    entry = mavlink.enums["MAV_CMD"].get(command)
    return entry.name.removeprefix("MAV_CMD_") if entry is not None and not entry.name.endswith("_ENUM_END") else ""
