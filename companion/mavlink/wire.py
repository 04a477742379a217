"""MAVLink datagram parsing shared by both ends (the companion's link and the simulated vehicle).

A UDP datagram carries whole MAVLink frames. Each datagram is parsed on its own, from a clean
parser state, so that a truncated or corrupt one cannot swallow the start of the next; frames
that fail their CRC (or signature) come back as counts, never as exceptions.

Most datagrams are a few clean frames. Those are cut at their stated lengths and decoded one by
one (:func:`~companion.mavlink.framing.decode_frame`, pymavlink's ``decode`` for unsigned MAVLink 2
frames in one generated function per message, the same object; pymavlink's own ``decode`` for the
rest), without pymavlink's byte-stream state machine, which costs as much again per frame.
Anything else (a byte that starts no frame, a datagram that ends inside one, a frame ``decode``
refuses, pymavlink's own signing check) is parsed again from the start by pymavlink's robust
parser, which alone decides what is bad.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .framing import decode_frame

__all__ = ["Parsed", "new_parser", "parse_datagram", "frames"]

_INITIAL_EXPECTED_LENGTH = mavlink.MAVLink(None).expected_length
_V1, _V2, _SIGNED = mavlink.PROTOCOL_MARKER_V1, mavlink.PROTOCOL_MARKER_V2, mavlink.MAVLINK_IFLAG_SIGNED
_SIGNATURE_LEN = mavlink.MAVLINK_SIGNATURE_BLOCK_LEN
_V1_OVERHEAD, _V2_OVERHEAD = mavlink.HEADER_LEN_V1 + 2, mavlink.HEADER_LEN_V2 + 2


class Parsed(NamedTuple):
    messages: list[Any]
    """good messages, in order"""
    bad: int
    """frames that failed (bad CRC, bad signature, garbage the parser could not frame)"""
    truncated: bool
    """bytes were left over: the datagram ended inside a frame"""


def new_parser() -> mavlink.MAVLink:
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    return parser


def parse_datagram(parser: mavlink.MAVLink, data: bytes) -> Parsed:
    clean = _clean_frames(parser, data)
    if clean is not None:
        return Parsed(clean, 0, False)
    return _robust(parser, data)


def frames(data: bytes) -> list[bytes] | None:
    """The frames of ``data`` cut at their stated lengths, or None unless it is whole frames and
    nothing else (what a frame holds is not checked here)."""
    end, i, out = len(data), 0, []
    while i < end:
        magic = data[i]
        if magic == _V2 and i + 2 < end:
            flags = data[i + 2]
            if flags & ~_SIGNED:
                return None
            j = i + data[i + 1] + _V2_OVERHEAD + (_SIGNATURE_LEN if flags & _SIGNED else 0)
        elif magic == _V1 and i + 1 < end:
            j = i + data[i + 1] + _V1_OVERHEAD
        else:
            return None
        if j > end:
            return None
        out.append(data[i:j])
        i = j
    return out


def _clean_frames(parser: mavlink.MAVLink, data: bytes) -> list[Any] | None:
    """The messages of a datagram made of whole frames that all decode, or None (then the robust
    parser reads it). pymavlink's signing state changes as it checks, so a parser that checks
    signatures always takes the robust path: a datagram is never checked twice."""
    if parser.signing.secret_key is not None:
        return None
    cut = frames(data)
    if cut is None:
        return None
    messages = []
    for frame in cut:
        msg = decode_frame(frame)  # the same message as decode's, at a third of the cost (unsigned MAVLink 2)
        if msg is None:
            try:
                msg = parser.decode(bytearray(frame))
            except Exception:  # noqa: BLE001 - the robust parser counts it
                return None
        messages.append(msg)
    parser.total_bytes_received += len(data)
    parser.total_packets_received += len(messages)
    return messages


def _robust(parser: mavlink.MAVLink, data: bytes) -> Parsed:
    parser.buf = bytearray()
    parser.buf_index = 0
    parser.expected_length = _INITIAL_EXPECTED_LENGTH
    parser.have_prefix_error = False
    try:
        frames = parser.parse_buffer(data) or []
    except Exception:  # pymavlink raises on some malformed input even in robust mode
        return Parsed([], 1, False)
    good = [m for m in frames if m.get_type() not in ("BAD_DATA", "BAD_SIGNATURE")]
    return Parsed(good, len(frames) - len(good), parser.buf_len() > 0)
