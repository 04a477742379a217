"""The companion's link read frame by frame without decoding: MAVLink 1 and 2 frames split out of a
byte stream, the stamps at the start of setpoints and telemetry, the target component of parameter
messages, the armed bit of a heartbeat. The relay (:mod:`.relay`) and the signing end
(:mod:`.signed_link`) both read the link this way; neither alters a frame here.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["Frame", "frames", "stamps", "armed", "for_component", "SETPOINTS", "CLOCKS_MS", "CLOCKS_US",
           "COMMANDS"]

SETPOINTS = frozenset({mavlink.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET, mavlink.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED,
                       mavlink.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT})
"""setpoints: time_boot_ms first"""
CLOCKS_MS = frozenset({mavlink.MAVLINK_MSG_ID_ATTITUDE, mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
                       mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT})
"""telemetry with time_boot_ms first"""
CLOCKS_US = frozenset({mavlink.MAVLINK_MSG_ID_HIGHRES_IMU, mavlink.MAVLINK_MSG_ID_ODOMETRY})
"""telemetry with time_usec first"""
COMMANDS = frozenset({mavlink.MAVLINK_MSG_ID_COMMAND_INT, mavlink.MAVLINK_MSG_ID_COMMAND_LONG})
"""a companion that commands (a landing, a mode) may stop streaming"""
TARGET_COMPONENT = {mavlink.MAVLINK_MSG_ID_PARAM_REQUEST_READ: 3, mavlink.MAVLINK_MSG_ID_PARAM_REQUEST_LIST: 1,
                    mavlink.MAVLINK_MSG_ID_PARAM_SET: 5}
"""PARAM_REQUEST_READ, PARAM_REQUEST_LIST, PARAM_SET: where target_component sits in the payload"""
HEARTBEAT_BASE_MODE = 6
"""base_mode's byte in a HEARTBEAT payload (after custom_mode uint32_t, type, autopilot)"""
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")


class Frame(NamedTuple):
    msgid: int
    payload: bytes
    compid: int
    """the sending component"""
    sysid: int = 0
    raw: bytes = b""
    """the whole frame as it came"""


def frames(buf: bytes | bytearray) -> tuple[list[Frame], int]:
    """The MAVLink frames at the start of ``buf`` and how many bytes they (and any garbage between
    them) take; an incomplete frame at the end is left."""
    out = []
    i, n = 0, len(buf)
    while i < n:
        magic = buf[i]
        if magic == 0xFD:
            if n - i < 10:
                break
            length, flags = buf[i + 1], buf[i + 2]
            end = i + 12 + length + (13 if flags & 1 else 0)
            if end > n:
                break
            msgid = buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16
            out.append(Frame(msgid, bytes(buf[i + 10:i + 10 + length]), buf[i + 6], buf[i + 5], bytes(buf[i:end])))
            i = end
        elif magic == 0xFE:
            if n - i < 6:
                break
            length = buf[i + 1]
            end = i + 8 + length
            if end > n:
                break
            out.append(Frame(buf[i + 5], bytes(buf[i + 6:i + 6 + length]), buf[i + 4], buf[i + 3], bytes(buf[i:end])))
            i = end
        else:
            i += 1  # not a frame start: skip
    return out, i


def stamps(msgs: list[Frame], kinds_ms: frozenset[int], kinds_us: frozenset[int] = frozenset()) -> float:
    """The newest stamp [s] among ``msgs`` of the given kinds (time_boot_ms or time_usec first in
    the payload; MAVLink 2 trims trailing zeros, so a short payload is padded); 0 if none."""
    newest = 0.0
    for m in msgs:
        msgid, payload = m.msgid, m.payload
        if msgid in kinds_ms:
            t = _U32.unpack((payload + b"\0\0\0\0")[:4])[0] * 1e-3
        elif msgid in kinds_us:
            t = _U64.unpack((payload + bytes(8))[:8])[0] * 1e-6
        else:
            continue
        newest = max(newest, t)
    return newest


def for_component(buf: bytes | bytearray, compid: int) -> tuple[bytes, bytes]:
    """Split whole frames into those addressed to component ``compid`` (parameter messages with
    that target_component) and the rest, each in its original bytes and order."""
    mine, rest = bytearray(), bytearray()
    i, n = 0, len(buf)
    while i < n:
        magic = buf[i]
        if magic == 0xFD and n - i >= 10:
            length, flags = buf[i + 1], buf[i + 2]
            end, msgid, start = i + 12 + length + (13 if flags & 1 else 0), buf[i + 7] | buf[i + 8] << 8, i + 10
        elif magic == 0xFE and n - i >= 6:
            length = buf[i + 1]
            end, msgid, start = i + 8 + length, buf[i + 5], i + 6
        else:
            rest += buf[i:]
            break
        if end > n:
            rest += buf[i:]
            break
        offset = TARGET_COMPONENT.get(msgid)
        payload = bytes(buf[start:start + length]) + bytes(8)
        (mine if offset is not None and payload[offset] == compid else rest).extend(buf[i:end])
        i = end
    return bytes(mine), bytes(rest)


def armed(msgs: list[Frame]) -> bool | None:
    """Whether the newest HEARTBEAT of the autopilot (component 1) among ``msgs`` says armed; None
    if there is none."""
    found = None
    for m in msgs:
        if m.msgid == mavlink.MAVLINK_MSG_ID_HEARTBEAT and m.compid == mavlink.MAV_COMP_ID_AUTOPILOT1:
            found = bool((m.payload + bytes(9))[HEARTBEAT_BASE_MODE] & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    return found
