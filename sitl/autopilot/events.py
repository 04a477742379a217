"""The simulated PX4's events: what it reports as MAVLink EVENTs (as PX4 v1.16 does) instead of
STATUSTEXT, and the catalogue it serves over MAVLink FTP so that clients can read them.

The texts are this simulator's own (its refusals and failsafes); each event's id is the text's
CRC-32 (24 bits) under component 1, so the catalogue and the events always agree. A text that is
not in the catalogue (one with values in it) goes out as STATUSTEXT, as PX4's mavlink_log does.
"""

from __future__ import annotations

import zlib

from companion.mavlink.events import catalogue_json

__all__ = ["EVENT_TEXTS", "event_id", "catalogue"]

EVENT_TEXTS = (
    "Arming denied: not on the ground",
    "Arming denied: estimator settling",
    "Arming denied: No offboard signal",
    "Disarming denied: in the air",
    "Takeoff denied: disarmed",
    "Offboard denied: another system has control",
    "Offboard denied: No offboard signal",
    "Mission denied: no mission loaded",
    "RTL denied: not flying",
    "mode change: non-finite parameters",
    "mode change: base mode lacks the custom flag",
    "Failsafe: offboard lost, descending",
    "Failsafe: offboard lost, holding",
    "Failsafe: landing",
    "Takeoff complete",
    "Armed",
    "Disarmed",
    "Landed, disarmed",
    "Disarmed: no take-off",
)


def event_id(text: str) -> int | None:
    """The event id of a catalogued text (component 1), or None."""
    if text not in _IDS:
        return None
    return (1 << 24) | _IDS[text]


_IDS = {text: zlib.crc32(text.encode()) & 0xFFFFFF for text in EVENT_TEXTS}


def catalogue() -> bytes:
    """all_events.json.xz as PX4 serves it (libevents format)."""
    return catalogue_json("sitl", {sub: (f"sitl_{sub:06x}", text) for text, sub in _IDS.items()})
