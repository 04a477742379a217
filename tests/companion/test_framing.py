"""companion/mavlink/framing.py frames every message of the dialect bit for bit as pymavlink does."""

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.events import EVENT_CRC_EXTRA, MSG_ID_EVENT, encode_event_frame
from companion.mavlink.framing import Payload, decode_frame, frame, pack_message, pack_payload


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


@pytest.mark.parametrize("payload", list(_payloads()))
def test_every_message_of_the_dialect_reads_back_as_pymavlinks_decode_builds_it(payload):
    """decode_frame's message is decode's: its type, fields, header and the buffers pymavlink keeps."""
    mav = mavlink.MAVLink(None, srcSystem=7, srcComponent=191)
    mav.seq = 200
    buf = payload.message().pack(mav)
    ours, theirs = decode_frame(buf), mavlink.MAVLink(None).decode(bytearray(buf))
    assert type(ours) is type(theirs)
    assert ours.to_dict() == theirs.to_dict()
    assert vars(ours._header) == vars(theirs._header)
    for name in ("_msgbuf", "_payload", "_crc", "_signed"):
        assert getattr(ours, name) == getattr(theirs, name), name
    assert ours.get_srcSystem() == 7 and ours.get_seq() == 200


def test_a_frame_decode_frame_cannot_vouch_for_goes_to_pymavlink():
    """A bad CRC, a stated length that is not the frame's, a signed frame, MAVLink 1 and an unknown
    message id: None, so that pymavlink's decode judges them (and raises where they are bad)."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    beat = (mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE)
    good = mav.heartbeat_encode(*beat).pack(mav)
    assert decode_frame(good) is not None
    bad_crc = good[:-1] + bytes([good[-1] ^ 1])
    assert decode_frame(bad_crc) is None
    with pytest.raises(mavlink.MAVError):
        mavlink.MAVLink(None).decode(bytearray(bad_crc))
    assert decode_frame(good[:-1]) is None
    signed = bytes([good[0], good[1], mavlink.MAVLINK_IFLAG_SIGNED]) + good[3:]
    assert decode_frame(signed) is None
    v1 = mav.heartbeat_encode(*beat).pack(mav, force_mavlink1=True)
    assert decode_frame(v1) is None
    unknown = frame(0xABCDE, 0, b"\x01", 0, 1, 1)
    assert decode_frame(unknown) is None
