"""MAVLink FTP (FILE_TRANSFER_PROTOCOL, id 110): the packets of a read-only file download.

Enough of the protocol to read one file: OpenFileRO, ReadFile at increasing offsets, then
TerminateSession. The payload is 251 bytes: seq (u16), session, opcode, size, req_opcode,
burst_complete, padding (u8 each), offset (u32), data (239). Pure: the link sends and waits.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = ["Packet", "encode", "decode", "reply", "burst", "TERMINATE_SESSION", "OPEN_FILE_RO", "READ_FILE",
           "ACK", "NAK",
           "ERR_EOF", "ERR_FAIL", "ERR_UNKNOWN_COMMAND", "ERR_FILE_NOT_FOUND", "DATA_MAX", "BURST_READ_FILE"]

TERMINATE_SESSION, RESET_SESSIONS, OPEN_FILE_RO, READ_FILE, BURST_READ_FILE = 1, 2, 4, 5, 15
ACK, NAK = 128, 129
ERR_FAIL, ERR_EOF, ERR_UNKNOWN_COMMAND, ERR_FILE_NOT_FOUND = 1, 6, 7, 10
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


def encode(seq: int, session: int, opcode: int, offset: int = 0, data: bytes = b"", size: int | None = None,
           req_opcode: int = 0, burst_complete: bool = False) -> bytes:
    data = data[:DATA_MAX]
    head = _HEAD.pack(seq & 0xFFFF, session, opcode, len(data) if size is None else size, req_opcode,
                      int(burst_complete), 0, offset)
    return (head + data).ljust(251, b"\x00")


def reply(request: Packet, opcode: int, session: int | None = None, offset: int = 0, data: bytes = b"",
          seq_ahead: int = 1, burst_complete: bool = False) -> bytes:
    """An ACK or NAK to ``request``: the next sequence number (``seq_ahead`` further into a burst)
    and, as the protocol requires (clients match replies by it), the request's opcode in
    ``req_opcode``."""
    return encode(request.seq + seq_ahead, request.session if session is None else session, opcode, offset, data,
                  req_opcode=request.opcode, burst_complete=burst_complete)


def burst(request: Packet, blob: bytes, most: int = 64) -> list[bytes]:
    """The answer to a BurstReadFile: ACKs carrying ``blob`` from the request's offset in chunks of
    its size, the last marked complete (at most ``most`` packets: the client asks again from
    where it got to), or a NAK at the end of the file."""
    size = min(request.size or DATA_MAX, DATA_MAX)
    start = request.offset
    if start >= len(blob):
        return [reply(request, NAK, None, start, bytes([ERR_EOF]))]
    offsets = list(range(start, len(blob), size))[:most]
    return [reply(request, ACK, None, o, blob[o:o + size], seq_ahead=k + 1, burst_complete=k == len(offsets) - 1)
            for k, o in enumerate(offsets)]


def decode(payload: bytes) -> Packet:
    raw = bytes(payload).ljust(251, b"\x00")
    seq, session, opcode, size, req_opcode, _burst, _pad, offset = _HEAD.unpack_from(raw)
    return Packet(seq, session, opcode, size, req_opcode, offset, raw[12:12 + min(size, DATA_MAX)])
