"""companion/mavlink/framing.py frames every message of the dialect bit for bit as pymavlink does."""

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.events import EVENT_CRC_EXTRA, MSG_ID_EVENT, encode_event_frame
from companion.mavlink.framing import Payload, frame, pack_message, pack_payload


def _value(kind: str, length: int, k: int) -> object:
    """A value of a field's type that is not zero (so trimming and field order both show)."""
    if kind == "char":
        return (b"abcdefghijklmnopqrstuvwxyz" * 10)[:max(length - 1, 1)]
    number = float(k % 7 + 1) if kind in ("float", "double") else (k % 5 + 1)
    return [number] * length if length else number


def _payloads():
    """Every message of the dialect, its fields in declared order (as its ``*_encode`` takes them)."""
    for _, cls in sorted(mavlink.mavlink_map.items()):
        kinds = dict(zip(cls.fieldnames, cls.fieldtypes))
        lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths))
        args = tuple(_value(kinds[n], lengths[n], k) for k, n in enumerate(cls.fieldnames))
        yield pytest.param(Payload(cls, args), id=cls.msgname)


@pytest.mark.parametrize("payload", list(_payloads()))
def test_every_message_of_the_dialect_frames_as_pymavlink_packs_it(payload):
    """From pymavlink's object and from the fields alone: the frame pymavlink's ``pack`` sends."""
    mav = mavlink.MAVLink(None, srcSystem=7, srcComponent=191)
    mav.seq = 200
    expected = payload.message().pack(mav)
    assert pack_message(payload.message(), 200, 7, 191) == expected
    assert pack_payload(payload, 200, 7, 191) == expected


def test_trailing_zeros_are_trimmed_to_one_byte_and_the_frame_still_parses():
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    msg = mav.attitude_quaternion_encode(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, [0.0] * 4)
    buf = pack_message(msg, 0, 1, 1)
    assert buf[1] == 1 and len(buf) == 10 + 1 + 2  # header, one payload byte, CRC
    back = mavlink.MAVLink(None).decode(bytearray(buf))
    assert back.get_type() == "ATTITUDE_QUATERNION" and back.q1 == 0.0 and math.isfinite(back.q1)


def test_the_event_frame_is_the_framing_of_its_payload():
    buf = encode_event_frame(5, 1, 1, 123, 456, 7, 3)
    assert buf == frame(MSG_ID_EVENT, EVENT_CRC_EXTRA, buf[10:-2], 5, 1, 1)
