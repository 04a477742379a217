"""MAVLink FTP (FILE_TRANSFER_PROTOCOL, id 110): the packets of a read-only file download.

Enough of the protocol to read one file: OpenFileRO, ReadFile at increasing offsets, then
TerminateSession. The payload is 251 bytes: seq (u16), session, opcode, size, req_opcode,
burst_complete, padding (u8 each), offset (u32), data (239). Pure: the link sends and waits.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = ["Packet", "encode", "decode", "TERMINATE_SESSION", "OPEN_FILE_RO", "READ_FILE", "ACK", "NAK",
           "ERR_EOF", "DATA_MAX"]

TERMINATE_SESSION, RESET_SESSIONS, OPEN_FILE_RO, READ_FILE = 1, 2, 4, 5
ACK, NAK = 128, 129
ERR_FAIL, ERR_EOF = 1, 6
DATA_MAX = 239
_HEAD = struct.Struct("<HBBBBBBI")


@dataclass(frozen=True)
class Packet:
    seq: int
    session: int
    opcode: int
    size: int
    req_opcode: int
    offset: int
    data: bytes


def encode(seq: int, session: int, opcode: int, offset: int = 0, data: bytes = b"", size: int | None = None) -> bytes:
    data = data[:DATA_MAX]
    head = _HEAD.pack(seq & 0xFFFF, session, opcode, len(data) if size is None else size, 0, 0, 0, offset)
    return (head + data).ljust(251, b"\x00")


def decode(payload: bytes) -> Packet:
    raw = bytes(payload).ljust(251, b"\x00")
    seq, session, opcode, size, req_opcode, _burst, _pad, offset = _HEAD.unpack_from(raw)
    return Packet(seq, session, opcode, size, req_opcode, offset, raw[12:12 + min(size, DATA_MAX)])
