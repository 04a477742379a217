"""MAVLink 2 frames, unsigned, built and read without pymavlink's per-frame machinery.

pymavlink's ``msg.pack(mav)`` builds a header object and a growing buffer for every frame (about
19 us); the bundled vehicle streams some 400 frames a simulated second, so that alone was a quarter
of its CPU. :func:`pack_message` frames a pymavlink message from what its class declares (the
payload's struct, the fields in wire order, the arrays, CRC_EXTRA) in a few microseconds, bit for
bit what ``msg.pack`` sends (tests/companion/test_framing.py); :func:`frame` is the framing alone,
for a payload packed elsewhere (EVENT, which the dialect lacks). Signed links keep pymavlink's
``pack``: the signature needs the link's key, timestamp and state. :func:`decode_frame` is the way
back: pymavlink's ``decode`` of an unsigned frame, the same message object, in one generated
function per class (companion/mavlink/wire.py reads clean datagrams with it).
"""

from __future__ import annotations

import struct
from typing import Any, Callable, NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pymavlink.generator.mavcrc import x25crc

try:  # pymavlink's own CRC backend (it requires it): CRC-16/MCRF4XX from 0xFFFF in one C call, no object
    from fastcrc.crc16 import mcrf4xx as _crc
except ImportError:  # pragma: no cover - pymavlink without fastcrc
    def _crc(data: bytes) -> int:
        """CRC-16/MCRF4XX of ``data`` (MAVLink's X.25 checksum)."""
        return int(x25crc(data).crc)

__all__ = ["STX_V2", "Payload", "frame", "pack_message", "pack_payload", "decode_frame"]

STX_V2 = 0xFD
"""the first byte of every MAVLink 2 frame"""


_BODY = struct.Struct("<BBBBBBHB")
"""the header after STX: payload length, incompat and compat flags, sequence, system, component, message id"""
_BYTE = tuple(bytes((i,)) for i in range(256))


def frame(msg_id: int, crc_extra: int, payload: bytes, seq: int, sysid: int, compid: int) -> bytes:
    """``payload`` framed as MAVLink 2, unsigned: trailing zero bytes trimmed (one byte at least, as
    MAVLink 2 sends them), the CRC over the header after STX, the payload and the message's CRC_EXTRA."""
    payload = payload.rstrip(b"\x00") or payload[:1]
    body = _BODY.pack(len(payload), 0, 0, seq & 0xFF, sysid, compid, msg_id & 0xFFFF, msg_id >> 16) + payload
    crc = _crc(body + _BYTE[crc_extra])
    return b"\xfd" + body + _BYTE[crc & 0xFF] + _BYTE[crc >> 8]


_Framer = Callable[[Any, int, int, int], bytes]
"""(the message or its fields, sequence, system, component) -> the frame"""
_FROM_MESSAGE: dict[type, _Framer] = {}
_FROM_VALUES: dict[type, _Framer] = {}


def _framer(cls: type, from_values: bool) -> _Framer:
    """The framing of pymavlink message class ``cls`` as one function (generated once per class, as a
    compiled codec is): its fields read in wire order from the message object, or from the values in
    the order its ``*_encode`` takes them (``from_values``), numeric arrays spread, char arrays as
    the one bytes value pymavlink keeps beside the text it shows; packed with the class's own struct
    and framed by :func:`frame`."""
    c: Any = cls
    chars = {name for name, kind in zip(c.fieldnames, c.fieldtypes) if kind == "char"}
    declared = list(c.fieldnames)
    parts = []
    for name, length in zip(c.ordered_fieldnames, c.array_lengths):
        ref = (f"v[{declared.index(name)}]" if from_values
               else f"v._{name}_raw" if name in chars else f"v.{name}")
        parts.append(f"*{ref}" if length and name not in chars else ref)
    src = (f"def framed(v, seq, sysid, compid):\n"
           f"    return frame(MSG_ID, EXTRA, pack({', '.join(parts)}), seq, sysid, compid)\n")
    scope: dict[str, Any] = {"pack": c.unpacker.pack, "frame": frame, "MSG_ID": int(c.id), "EXTRA": int(c.crc_extra)}
    exec(compile(src, f"<framing of {c.msgname}>", "exec"), scope)  # noqa: S102
    framed: _Framer = scope["framed"]
    (_FROM_VALUES if from_values else _FROM_MESSAGE)[cls] = framed
    return framed


def pack_message(msg: Any, seq: int, sysid: int, compid: int) -> bytes:
    """The unsigned MAVLink 2 frame of pymavlink message ``msg`` (what ``msg.pack`` sends from a link
    with this sequence number, system and component)."""
    cls = type(msg)
    framed = _FROM_MESSAGE.get(cls) or _framer(cls, False)
    return framed(msg, seq, sysid, compid)


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


def pack_payload(p: Payload, seq: int, sysid: int, compid: int) -> bytes:
    """The unsigned MAVLink 2 frame of ``p`` (what ``p.message().pack`` sends from such a link)."""
    cls = p.cls
    framed = _FROM_VALUES.get(cls) or _framer(cls, True)
    return framed(p.values, seq, sysid, compid)


_Reader = Callable[[bytes], Any]
"""a frame -> pymavlink's message, or None (pymavlink's own decode is to judge it)"""
_READERS: dict[int, _Reader] = {}


def decode_frame(buf: bytes) -> Any:
    """The message of an unsigned MAVLink 2 frame, as pymavlink's ``decode`` builds it (its fields,
    ``_header``, ``_msgbuf``, ``_payload``, ``_crc``; tests/companion/test_framing.py), from one function
    generated per class (:func:`_reader`); None for anything else: MAVLink 1, signed, an id the dialect
    lacks, a length or CRC that does not check (pymavlink's ``decode`` then judges it, and raises)."""
    if len(buf) < 12 or buf[0] != STX_V2 or buf[2] or buf[1] != len(buf) - 12:
        return None
    msg_id = buf[7] | buf[8] << 8 | buf[9] << 16
    read = _READERS.get(msg_id)
    if read is None:
        cls = mavlink.mavlink_map.get(msg_id)
        if cls is None:
            return None
        read = _reader(cls)
    return read(buf)


def _reader(cls: type) -> _Reader:
    """pymavlink's ``decode`` for one class as one function: CRC, the payload padded with the zeros
    MAVLink 2 trimmed, unpacked with the class's struct, fields in declared order (arrays as lists,
    char arrays as bytes without their trailing zeros), the header and buffers pymavlink keeps."""
    c: Any = cls
    args = []
    for i, kind in enumerate(c.fieldtypes):
        order = c.orders[i]
        length, tip = c.lengths[order], sum(c.lengths[:order])
        if kind == "char":
            args.append(f"t[{tip}].rstrip(ZERO)")
        elif length == 1:
            args.append(f"t[{tip}]")
        else:
            args.append(f"list(t[{tip}:{tip + length}])")
    size = c.unpacker.size
    src = (f"def read(buf):\n"
           f"    crc = buf[-2] | buf[-1] << 8\n"
           f"    if crc_of(buf[1:-2] + EXTRA) != crc:\n"
           f"        return None\n"
           f"    p = buf[10:-2]\n"
           f"    p = p + bytes({size} - len(p)) if len(p) < {size} else p[:{size}]\n"
           f"    t = unpack(p)\n"
           f"    m = cls({', '.join(args)})\n"
           f"    mlen, incompat, compat, seq, sysid, compid, low, high = header(buf, 1)\n"
           f"    m._signed = False\n"
           f"    m._msgbuf = b = bytearray(buf)\n"
           f"    m._payload = b[6:-2]\n"
           f"    m._crc = crc\n"
           f"    m._header = Header(low | high << 16, incompat, compat, mlen, seq, sysid, compid)\n"
           f"    return m\n")
    scope: dict[str, Any] = {"crc_of": _crc, "EXTRA": _BYTE[int(c.crc_extra)], "unpack": c.unpacker.unpack,
                             "cls": cls, "ZERO": b"\x00", "header": _BODY.unpack_from,
                             "Header": mavlink.MAVLink_header}
    exec(compile(src, f"<reading of {c.msgname}>", "exec"), scope)  # noqa: S102
    read: _Reader = scope["read"]
    _READERS[int(c.id)] = read
    return read
