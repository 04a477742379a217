"""Parameters on the wire: names and values as PARAM_VALUE / PARAM_SET carry them.

``param_value`` is a float32 in every message, but what it holds depends on ``param_type`` and on
the autopilot: PX4 (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE) puts an integer parameter's
*bits* into it — COM_RC_IN_MODE = 1 arrives as 1.4e-45 — while ArduPilot (C_CAST) sends the
integer's value as a float. Reading or writing an integer parameter of PX4 as a plain float gets
it wrong both ways.
"""

from __future__ import annotations

import math
import struct

__all__ = ["param_name", "decode_value", "encode_value", "INTEGER_TYPES", "MAV_PARAM_TYPE_REAL32",
           "MAV_PARAM_TYPE_INT32", "PLANT_COMPID"]

PLANT_COMPID = 25
"""MAV_COMP_ID_USER1: the simulated plant as a component of its own when a real autopilot's
firmware flies it (``sitl --firmware``); it serves the SIM_* parameters (wind, external forces,
faults) that the autopilot does not have. A parameter the autopilot has is always the
autopilot's: the plant never serves one of the same name."""

MAV_PARAM_TYPE_UINT8, MAV_PARAM_TYPE_INT8, MAV_PARAM_TYPE_UINT16, MAV_PARAM_TYPE_INT16 = 1, 2, 3, 4
MAV_PARAM_TYPE_UINT32, MAV_PARAM_TYPE_INT32, MAV_PARAM_TYPE_REAL32 = 5, 6, 9
INTEGER_TYPES = {
    MAV_PARAM_TYPE_UINT8: "<B", MAV_PARAM_TYPE_INT8: "<b", MAV_PARAM_TYPE_UINT16: "<H",
    MAV_PARAM_TYPE_INT16: "<h", MAV_PARAM_TYPE_UINT32: "<I", MAV_PARAM_TYPE_INT32: "<i",
}


def param_name(raw: object) -> str:
    """A param_id as text: pymavlink gives str or bytes, NUL-padded to 16 characters."""
    text = raw if isinstance(raw, str) else bytes(raw).decode("ascii", "replace")  # type: ignore[arg-type]
    return text.split("\x00", 1)[0]


def decode_value(value: float, param_type: int, bytewise: bool) -> float:
    """The parameter's value as a number."""
    fmt = INTEGER_TYPES.get(param_type)
    if fmt is None or not bytewise:
        return float(value)
    raw = struct.pack("<f", value)
    size = struct.calcsize(fmt)
    return float(struct.unpack(fmt, raw[:size])[0])


def encode_value(value: float, param_type: int, bytewise: bool) -> float:
    """What to put in PARAM_SET's ``param_value`` for ``value`` (ValueError if an integer parameter
    is given a fraction or a value outside its type)."""
    fmt = INTEGER_TYPES.get(param_type)
    if fmt is None:
        return float(value)
    if not math.isfinite(value) or value != int(value):
        raise ValueError(f"{value!r} is not an integer")
    try:
        packed = struct.pack(fmt, int(value))
    except struct.error:
        raise ValueError(f"{value:g} does not fit the parameter's type") from None
    if not bytewise:
        return float(int(value))
    return float(struct.unpack("<f", packed.ljust(4, b"\x00"))[0])
