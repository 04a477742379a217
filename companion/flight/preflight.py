"""The pre-flight report: the autopilot's failsafe settings, read before anything arms, with a
warning for each one that makes offboard flight unsafe. Pure: values in, lines out.

What each setting decides when the companion stops streaming, the ground link is lost or the
pilot's RC is absent — the cases the companion cannot handle itself because it is the thing that
failed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Check", "PX4_CHECKS", "ARDUPILOT_CHECKS", "report", "checks_for"]


@dataclass(frozen=True)
class Check:
    name: str
    meaning: str
    unsafe: Callable[[float], str | None]
    """why the value is unsafe for offboard flight, or None"""


def _none(_: float) -> None:
    return None


PX4_CHECKS = (
    Check("COM_OF_LOSS_T", "offboard stream silent this long [s] -> failsafe",
          lambda v: f"{v:g} s: a dead companion is noticed late (1 s is PX4's default)" if v > 2.0 else None),
    Check("COM_OBL_RC_ACT", "offboard loss action with RC (0 position, 1 altitude, 2 manual, 3 return, 4 land, "
          "5 hold, 6 terminate, 7 disarm)",
          lambda v: f"{v:g}: terminates or disarms in the air" if int(v) in (6, 7) else None),
    Check("NAV_DLL_ACT", "ground link loss action (0 off, 1 hold, 2 return, 3 land, 5 terminate, 6 disarm)",
          lambda v: "0: nothing happens when the ground station is lost" if int(v) == 0 else
          (f"{v:g}: terminates or disarms in the air" if int(v) in (5, 6) else None)),
    Check("COM_DL_LOSS_T", "ground link silent this long [s] -> NAV_DLL_ACT", _none),
    Check("NAV_RCL_ACT", "RC loss action (0 off, 1 hold, 2 return, 3 land, 5 terminate, 6 disarm)",
          lambda v: f"{v:g}: terminates or disarms in the air" if int(v) in (5, 6) else None),
    Check("COM_RCL_EXCEPT", "modes exempt from the RC-loss failsafe (bit 2: offboard)",
          lambda v: "offboard exempt from RC loss: an RC failure in offboard goes unanswered" if int(v) & 4 else None),
    Check("COM_RC_IN_MODE", "RC input (0 RC, 1 joystick, 2 either, 3 both, 4 none)", _none),
    Check("COM_DISARM_LAND", "disarm this long after landing [s]",
          lambda v: "negative: never disarms after landing" if v < 0 else None),
)

ARDUPILOT_CHECKS = (
    Check("GUID_TIMEOUT", "GUIDED: a silent companion's last attitude target is flown this long [s]",
          lambda v: f"{v:g} s: a dead companion's last target is flown that long" if v > 1.0 else None),
    Check("FS_GCS_ENABLE", "ground station loss failsafe (0 off)",
          lambda v: "0: nothing happens when the ground station (or the companion) link is lost" if int(v) == 0
          else None),
    Check("FS_GCS_TIMEOUT", "ground station silent this long [s] -> FS_GCS_ENABLE", _none),
    Check("FS_THR_ENABLE", "RC throttle failsafe (0 off)", _none),
    Check("FS_EKF_ACTION", "EKF failsafe action (1 land, 2 alt-hold, 3 land even in stabilize)",
          lambda v: "0: nothing happens when the position estimate fails" if int(v) == 0 else None),
    Check("FS_OPTIONS", "failsafe options bitmask (bit 3, 8: continue in GUIDED on GCS loss)",
          lambda v: "continues GUIDED on a lost ground link: a dead companion flies on" if int(v) & 8 else None),
    Check("DISARM_DELAY", "disarm this long after landing [s]", _none),
)


def checks_for(autopilot: str) -> tuple[Check, ...]:
    return ARDUPILOT_CHECKS if autopilot == "ardupilot" else PX4_CHECKS


def report(autopilot: str, values: dict[str, float | None]) -> tuple[list[str], list[str]]:
    """The report's lines (one per setting) and its warnings."""
    lines, warnings = [], []
    for c in checks_for(autopilot):
        v = values.get(c.name)
        if v is None:
            lines.append(f"  {c.name:<16} {'-':>8}  {c.meaning} (not on this vehicle)")
            continue
        why = c.unsafe(v)
        lines.append(f"  {c.name:<16} {v:>8g}  {c.meaning}{'  <- WARNING' if why else ''}")
        if why:
            warnings.append(f"{c.name} {why}")
    return lines, warnings
