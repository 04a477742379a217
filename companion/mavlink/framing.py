"""MAVLink 2 frames, unsigned, built without pymavlink's per-frame objects.

pymavlink's ``msg.pack(mav)`` builds a header object and a growing buffer for every frame (about
19 us); the bundled vehicle streams some 400 frames a simulated second, so that alone was a quarter
of its CPU. :func:`pack_message` frames a pymavlink message from what its class declares (the
payload's struct, the fields in wire order, the arrays, CRC_EXTRA) in a few microseconds, bit for
bit what ``msg.pack`` sends (tests/companion/test_framing.py); :func:`frame` is the framing alone,
for a payload packed elsewhere (EVENT, which the dialect lacks). Signed links keep pymavlink's
``pack``: the signature needs the link's key, timestamp and state.
"""

from __future__ import annotations

import operator
import struct
from typing import Any, Callable, NamedTuple

from pymavlink.generator.mavcrc import x25crc

__all__ = ["STX_V2", "Payload", "frame", "pack_message", "pack_payload"]

STX_V2 = 0xFD
"""the first byte of every MAVLink 2 frame"""
_HEADER = struct.Struct("<BBBBBBBHB")
"""STX, payload length, incompat and compat flags, sequence, system, component, message id (24 bits)"""


def frame(msg_id: int, crc_extra: int, payload: bytes, seq: int, sysid: int, compid: int) -> bytes:
    """``payload`` framed as MAVLink 2, unsigned: trailing zero bytes trimmed (one byte at least, as
    MAVLink 2 sends them), the CRC over the header after STX, the payload and the message's CRC_EXTRA."""
    payload = payload.rstrip(b"\x00") or payload[:1]
    header = _HEADER.pack(STX_V2, len(payload), 0, 0, seq & 0xFF, sysid, compid, msg_id & 0xFFFF, msg_id >> 16)
    crc = x25crc(header[1:] + payload + bytes((crc_extra,))).crc
    return header + payload + crc.to_bytes(2, "little")


_Plan = tuple[Any, Callable[[Any], tuple[Any, ...]], tuple[int, ...], int, int]
_PLANS: dict[type, _Plan] = {}


def _plan(cls: type) -> _Plan:
    """(payload struct, the fields' getter in wire order, the positions of the numeric arrays among
    them, message id, CRC_EXTRA) of a pymavlink message class."""
    c: Any = cls
    chars = {name for name, kind in zip(c.fieldnames, c.fieldtypes) if kind == "char"}
    names = tuple(c.ordered_fieldnames)
    arrays = tuple(i for i, (name, length) in enumerate(zip(names, c.array_lengths)) if length and name not in chars)
    # a char array packs as one bytes value, which pymavlink keeps beside the text it shows
    getter = operator.attrgetter(*(f"_{name}_raw" if name in chars else name for name in names))
    get = getter if len(names) > 1 else (lambda m: (getter(m),))
    plan = (c.unpacker, get, arrays, int(c.id), int(c.crc_extra))
    _PLANS[cls] = plan
    return plan


def pack_message(msg: Any, seq: int, sysid: int, compid: int) -> bytes:
    """The unsigned MAVLink 2 frame of pymavlink message ``msg`` (what ``msg.pack`` sends from a link
    with this sequence number, system and component)."""
    cls = type(msg)
    plan = _PLANS.get(cls) or _plan(cls)
    return _framed(plan, plan[1](msg), seq, sysid, compid)


class Payload(NamedTuple):
    """A message not yet built: its pymavlink class and its fields in the order that class's
    ``*_encode`` takes them (char arrays as bytes). :meth:`message` builds pymavlink's object (a
    signed link packs that; a reader reads its fields)."""

    cls: type
    values: tuple[Any, ...]

    def message(self) -> Any:
        return self.cls(*self.values)

    def get_type(self) -> str:
        return str(self.cls.msgname)  # type: ignore[attr-defined]


_VALUE_PLANS: dict[type, _Plan] = {}


def _value_plan(cls: type) -> _Plan:
    """:func:`_plan` for fields given in declared order: the getter picks them in wire order."""
    c: Any = cls
    chars = {name for name, kind in zip(c.fieldnames, c.fieldtypes) if kind == "char"}
    names = tuple(c.ordered_fieldnames)
    arrays = tuple(i for i, (name, length) in enumerate(zip(names, c.array_lengths)) if length and name not in chars)
    getter = operator.itemgetter(*(list(c.fieldnames).index(name) for name in names))
    get = getter if len(names) > 1 else (lambda v: (getter(v),))
    plan = (c.unpacker, get, arrays, int(c.id), int(c.crc_extra))
    _VALUE_PLANS[cls] = plan
    return plan


def pack_payload(p: Payload, seq: int, sysid: int, compid: int) -> bytes:
    """The unsigned MAVLink 2 frame of ``p`` (what ``p.message().pack`` sends from such a link)."""
    plan = _VALUE_PLANS.get(p.cls) or _value_plan(p.cls)
    return _framed(plan, plan[1](p.values), seq, sysid, compid)


def _framed(plan: _Plan, values: tuple[Any, ...], seq: int, sysid: int, compid: int) -> bytes:
    unpacker, _, arrays, msg_id, crc_extra = plan
    if arrays:
        flat: list[Any] = []
        start = 0
        for i in arrays:
            flat.extend(values[start:i])
            flat.extend(values[i])
            start = i + 1
        flat.extend(values[start:])
        values = tuple(flat)
    return frame(msg_id, crc_extra, unpacker.pack(*values), seq, sysid, compid)
