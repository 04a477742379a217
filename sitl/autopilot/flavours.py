"""What differs between the simulated PX4 and the simulated ArduCopter: one rules object per flavour
behind one interface, so that :class:`~sitl.autopilot.logic.Autopilot` asks instead of branching.

Each rule is a pure answer about modes, take-off and what the vehicle reports; the autopilot keeps
the state and steps the physics. A new flavour is a new subclass of :class:`FlavourRules` and an
entry in :data:`RULES`.
"""

from __future__ import annotations

import enum
import math

from companion.mavlink import modes

__all__ = ["Mode", "PX4_NAMES", "COPTER_NAMES", "FlavourRules", "Px4Rules", "CopterRules", "RULES", "rules_for"]


class Mode(enum.Enum):
    """The firmware's modes; what each flavour calls them is in PX4_NAMES and COPTER_NAMES."""

    MANUAL = "manual"
    ALTCTL = "altctl"
    POSCTL = "posctl"
    TAKEOFF = "takeoff"
    HOLD = "hold"
    MISSION = "mission"
    RTL = "rtl"
    LAND = "land"
    OFFBOARD = "offboard"
    GUIDED = "guided"
    """ArduPilot: flies attitude targets while they are fresh, otherwise holds position"""


PX4_NAMES = {
    Mode.MANUAL: "MANUAL", Mode.ALTCTL: "ALTCTL", Mode.POSCTL: "POSCTL", Mode.TAKEOFF: "TAKEOFF", Mode.HOLD: "HOLD",
    Mode.MISSION: "MISSION", Mode.RTL: "RTL", Mode.LAND: "LAND", Mode.OFFBOARD: "OFFBOARD",
}
"""each mode's PX4 name; the numbers are in companion.mavlink.modes, shared with the companion"""

COPTER_NAMES = {
    Mode.MANUAL: "STABILIZE", Mode.ALTCTL: "ALT_HOLD", Mode.MISSION: "AUTO", Mode.GUIDED: "GUIDED",
    Mode.HOLD: "LOITER", Mode.RTL: "RTL", Mode.LAND: "LAND", Mode.POSCTL: "POSHOLD", Mode.TAKEOFF: "GUIDED",
}
"""each mode's ArduCopter name (take-off runs in GUIDED); GUIDED_NOGPS and BRAKE are accepted as GUIDED
and LOITER"""
_COPTER_ALIASES = {"GUIDED_NOGPS": Mode.GUIDED, "BRAKE": Mode.HOLD}

TAKEOFF_HEIGHT_M = (0.5, 100.0)
"""the take-off heights either flavour accepts, above home [m]"""


class FlavourRules:
    """The interface: what the autopilot asks its flavour."""

    name = ""
    initial_mode = Mode.HOLD
    """the mode at boot"""
    position_after_s = 0.0
    """when a position estimate exists after boot, unless the parameters say otherwise [s]"""
    after_takeoff = Mode.HOLD
    """the mode a finished take-off leaves the vehicle in"""
    takeoff_is_a_mode = True
    """a mode change to TAKEOFF takes off (PX4); otherwise only the command does"""
    disarmed_offboard_is_intention = False
    """OFFBOARD while disarmed is accepted as the mode to arm into (PX4)"""
    attitude_with_rates = False
    """an attitude target may carry roll and pitch rates too (ArduPilot flies both)"""
    learns_hover_throttle = False
    """the reported hover throttle is learnt in flight from a stale saved value (ArduCopter)"""

    def custom_mode(self, mode: Mode) -> int:
        """The heartbeat's custom_mode for ``mode``."""
        raise NotImplementedError

    def mode_from_command(self, p2: int, p3: int) -> Mode | None:
        """The mode a DO_SET_MODE asks for (param2, param3), in this flavour's numbering."""
        raise NotImplementedError

    def has_mode(self, mode: Mode) -> bool:
        return True

    def mode_after_disarm(self, user_mode: Mode) -> Mode:
        """After landing in LAND, TAKEOFF or RTL and disarming."""
        return user_mode

    def reported_mode(self, mode: Mode, offboard_loss_descending: bool) -> Mode:
        """The mode the heartbeat shows."""
        return mode

    def takeoff_height(self, mode: Mode, altitude_param: float, origin_alt_m: float,
                       default_m: float) -> float | str:
        """The take-off height above home for MAV_CMD_NAV_TAKEOFF's altitude (param7), or why the
        command is denied."""
        raise NotImplementedError


class Px4Rules(FlavourRules):
    """PX4 v1.16: OFFBOARD, TAKEOFF as a mode, POSCTL shown during the offboard-loss descent."""

    name = "px4"
    disarmed_offboard_is_intention = True

    def custom_mode(self, mode: Mode) -> int:
        return modes.px4_custom_mode(PX4_NAMES[mode]) if mode in PX4_NAMES else 0

    def mode_from_command(self, p2: int, p3: int) -> Mode | None:
        name = modes.px4_mode_name((p2 << 16) | (p3 << 24)) if 0 <= p2 < 256 and 0 <= p3 < 256 else ""
        return next((m for m, n in PX4_NAMES.items() if n == name), None)

    def has_mode(self, mode: Mode) -> bool:
        return mode != Mode.GUIDED

    def reported_mode(self, mode: Mode, offboard_loss_descending: bool) -> Mode:
        """PX4 v1.16 shows POSCTL while its offboard-loss failsafe descends without RC."""
        return Mode.POSCTL if offboard_loss_descending else mode

    def takeoff_height(self, mode: Mode, altitude_param: float, origin_alt_m: float,
                       default_m: float) -> float | str:
        """param7 is AMSL (NaN: MIS_TAKEOFF_ALT)."""
        if not math.isfinite(altitude_param):
            return default_m
        h = altitude_param - origin_alt_m
        lo, hi = TAKEOFF_HEIGHT_M
        return h if lo <= h <= hi else f"Takeoff denied: altitude {h:.1f} m above home"


class CopterRules(FlavourRules):
    """ArduCopter: GUIDED (take-off only there, by command, param7 above home), a GPS-like position
    only after the EKF's warm-up, a learnt hover throttle."""

    name = "ardupilot"
    initial_mode = Mode.MANUAL
    position_after_s = 40.0
    after_takeoff = Mode.GUIDED
    takeoff_is_a_mode = False
    attitude_with_rates = True
    learns_hover_throttle = True

    def custom_mode(self, mode: Mode) -> int:
        return modes.COPTER_MODES[COPTER_NAMES.get(mode, "STABILIZE")]

    def mode_from_command(self, p2: int, p3: int) -> Mode | None:
        name = modes.copter_mode_name(p2)
        found = next((m for m, n in COPTER_NAMES.items() if n == name and m != Mode.TAKEOFF), None)
        return found or _COPTER_ALIASES.get(name)

    def has_mode(self, mode: Mode) -> bool:
        return mode != Mode.OFFBOARD

    def mode_after_disarm(self, user_mode: Mode) -> Mode:
        """GUIDED, as after a GUIDED take-off."""
        return Mode.GUIDED

    def takeoff_height(self, mode: Mode, altitude_param: float, origin_alt_m: float,
                       default_m: float) -> float | str:
        """Only in GUIDED; param7 is the height above home."""
        if mode not in (Mode.GUIDED, Mode.TAKEOFF):
            return "Takeoff denied: not in GUIDED"
        lo, hi = TAKEOFF_HEIGHT_M
        if not (math.isfinite(altitude_param) and lo <= altitude_param <= hi):
            return f"Takeoff denied: altitude {altitude_param!r}"
        return altitude_param


RULES: dict[str, FlavourRules] = {r.name: r for r in (Px4Rules(), CopterRules())}
"""the rules of each flavour, by the name ``--flavour`` and AutopilotParams.flavour use"""


def rules_for(flavour: str) -> FlavourRules:
    """The rules of ``flavour`` ("px4", "ardupilot"; the paper's vehicle flies PX4's)."""
    return RULES.get(flavour, RULES["px4"])
