"""What differs between PX4 and ArduPilot on the wire (../shared/MAVLINK.md)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Flavour", "PX4", "ARDUPILOT", "flavour_for"]

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12

_PX4_MODES = {
    (1, 0): "MANUAL", (2, 0): "ALTCTL", (3, 0): "POSCTL", (4, 2): "TAKEOFF", (4, 3): "HOLD", (4, 4): "MISSION",
    (4, 5): "RTL", (4, 6): "LAND", (6, 0): "OFFBOARD", (5, 0): "ACRO", (7, 0): "STABILIZED",
}
_COPTER_MODES = {
    0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL", 9: "LAND",
    16: "POSHOLD", 17: "BRAKE", 20: "GUIDED_NOGPS",
}


@dataclass(frozen=True)
class Flavour:
    name: str
    offboard_mode: tuple[int, int]
    """DO_SET_MODE param2, param3 of the mode that flies attitude setpoints"""
    hold_mode: tuple[int, int]
    land_mode: tuple[int, int]
    offboard_names: tuple[str, ...]

    def mode_name(self, custom_mode: int) -> str:
        if self.name == "px4":
            main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
            return _PX4_MODES.get((main, sub), f"PX4_{main}_{sub}")
        return _COPTER_MODES.get(custom_mode, f"MODE_{custom_mode}")


PX4 = Flavour("px4", (6, 0), (4, 3), (4, 6), ("OFFBOARD",))
ARDUPILOT = Flavour("ardupilot", (4, 0), (5, 0), (9, 0), ("GUIDED", "GUIDED_NOGPS"))


def flavour_for(autopilot: int) -> Flavour | None:
    return {MAV_AUTOPILOT_PX4: PX4, MAV_AUTOPILOT_ARDUPILOTMEGA: ARDUPILOT}.get(autopilot)
