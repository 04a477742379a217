"""MAVLink datagram parsing shared by both ends (the companion's link and the simulated vehicle).

A UDP datagram carries whole MAVLink frames. Each datagram is parsed on its own, from a clean
parser state, so that a truncated or corrupt one cannot swallow the start of the next; frames
that fail their CRC (or signature) come back as counts, never as exceptions.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["Parsed", "new_parser", "parse_datagram"]

_INITIAL_EXPECTED_LENGTH = mavlink.MAVLink(None).expected_length


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
