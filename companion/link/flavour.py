"""What differs between PX4 and ArduPilot on the wire."""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.modes import COPTER_MODES, PX4_MODES, copter_mode_name, px4_mode_name

__all__ = ["Flavour", "PX4", "ARDUPILOT", "flavour_for"]


@dataclass(frozen=True)
class Flavour:
    name: str
    offboard_mode: tuple[int, int]
    """DO_SET_MODE param2, param3 of the mode that flies attitude setpoints"""
    hold_mode: tuple[int, int]
    land_mode: tuple[int, int]
    offboard_names: tuple[str, ...]

    def mode_name(self, custom_mode: int) -> str:
        return px4_mode_name(custom_mode) if self.name == "px4" else copter_mode_name(custom_mode)


PX4 = Flavour("px4", PX4_MODES["OFFBOARD"], PX4_MODES["HOLD"], PX4_MODES["LAND"], ("OFFBOARD",))
ARDUPILOT = Flavour("ardupilot", (COPTER_MODES["GUIDED"], 0), (COPTER_MODES["BRAKE"], 0), (COPTER_MODES["LAND"], 0),
                    ("GUIDED", "GUIDED_NOGPS"))
"""hold is BRAKE: it stops and holds position by itself. LOITER follows the pilot's throttle stick, and
with no RC (throttle low) it descended at 2.2 m/s after a 2 s telemetry outage and hit the ground"""


def flavour_for(autopilot: int) -> Flavour | None:
    return {mavlink.MAV_AUTOPILOT_PX4: PX4, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA: ARDUPILOT}.get(autopilot)
