"""MAVLink 2 signing: keys, and which frames the check accepts (frames packed and parsed by pymavlink)."""

from __future__ import annotations

import hashlib
import os
import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.signing import (
    SignatureCheck, SigningError, enable_signing, fingerprint, key_from_text, load_key, read_key_file,
    EPOCH_2015_S, SignatureCheck as Check, signing_timestamp, write_key_file,
)
from companion.mavlink.wire import new_parser, parse_datagram

KEY = bytes(range(32))
OTHER = bytes(range(1, 33))


def frame(key: bytes | None, sysid: int = 255, link_id: int = 0, timestamp: int | None = None) -> bytes:
    """A signed SET_ATTITUDE_TARGET (unsigned without a key), stamped now or with ``timestamp``."""
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=191)
    if key is not None and timestamp is None:
        enable_signing(mav, key, link_id)
    elif key is not None:  # pymavlink's own signing state, told the timestamp to sign with
        mav.signing.secret_key, mav.signing.link_id, mav.signing.sign_outgoing = key, link_id, True
        mav.signing.timestamp = timestamp
    return mav.set_attitude_target_encode(0, 1, 1, 0, [1, 0, 0, 0], 0, 0, 0, 0.5).pack(mav)


def decode(buf: bytes):  # type: ignore[no-untyped-def]
    parsed = parse_datagram(new_parser(), buf)
    assert len(parsed.messages) == 1 and parsed.bad == 0
    return parsed.messages[0]


def test_a_frame_signed_with_the_key_is_accepted_once() -> None:
    check = SignatureCheck(KEY)
    buf = frame(KEY)
    assert check.verdict(decode(buf)) is None
    assert check.verdict(decode(buf)) == "replayed"  # the same frame again: a replay
    assert check.verdict(decode(frame(KEY))) is None  # the sender's next frame (later timestamp)


def test_unsigned_wrong_key_and_tampered_frames_are_refused() -> None:
    check = SignatureCheck(KEY)
    assert check.verdict(decode(frame(None))) == "unsigned"
    assert check.verdict(decode(frame(OTHER))) == "wrong key"
    buf = bytearray(frame(KEY))
    buf[14] ^= 0x40  # flip a payload bit and fix the CRC so that only the signature can tell
    crc = mavlink.x25crc(bytes(buf[1:-15]))
    crc.accumulate(bytes([mavlink.MAVLink_set_attitude_target_message.crc_extra]))
    buf[-15:-13] = struct.pack("<H", crc.crc)
    assert check.verdict(decode(bytes(buf))) == "wrong key"


def test_allow_unsigned_names_only_the_listed_messages() -> None:
    check = SignatureCheck(KEY, allow_unsigned=frozenset({"HEARTBEAT"}))
    mav = mavlink.MAVLink(None, srcSystem=42, srcComponent=1)
    hb = mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                              mavlink.MAV_STATE_ACTIVE).pack(mav)
    assert check.verdict(decode(hb)) is None
    assert check.verdict(decode(frame(None))) == "unsigned"


def test_a_forged_far_future_timestamp_does_not_lock_out_the_real_sender() -> None:
    """pymavlink's own check records a stream's timestamp before comparing the signature; ours must not."""
    check = SignatureCheck(KEY)
    assert check.verdict(decode(frame(KEY))) is None
    forged = frame(OTHER, timestamp=2**48 - 2)  # same stream (link 0, sysid 255, compid 191)
    assert check.verdict(decode(forged)) == "wrong key"
    assert check.verdict(decode(frame(KEY))) is None

    # the contrast: pymavlink's parser with the key is locked out by the same forged frame
    mav = mavlink.MAVLink(None)
    mav.signing.secret_key = KEY
    mav.robust_parsing = True
    assert mav.parse_buffer(frame(KEY))[0].get_type() == "SET_ATTITUDE_TARGET"
    mav.parse_buffer(forged)
    assert mav.parse_buffer(frame(KEY))[0].get_type() == "BAD_DATA"


def test_a_new_stream_more_than_a_minute_old_is_refused() -> None:
    check = SignatureCheck(KEY)
    old = signing_timestamp() - 61 * 100_000
    assert check.verdict(decode(frame(KEY, sysid=7, timestamp=old))) == "stale timestamp"
    assert check.verdict(decode(frame(KEY, sysid=8, timestamp=old + 2 * 100_000))) is None


def test_streams_are_bounded() -> None:
    check = SignatureCheck(KEY, max_streams=8)
    for link in range(20):
        assert check.verdict(decode(frame(KEY, link_id=link))) is None
    assert len(check.streams) == 8


def test_keys_from_hex_passphrase_and_files(tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert key_from_text(KEY.hex()) == KEY
    assert key_from_text("correct horse") == hashlib.sha256(b"correct horse").digest()
    with pytest.raises(SigningError, match="empty"):
        key_from_text("  \n")
    raw = tmp_path / "raw.key"
    raw.write_bytes(OTHER)
    os.chmod(raw, 0o600)
    assert read_key_file(raw) == (OTHER, None)
    made = tmp_path / "new.key"
    key = write_key_file(made)
    assert oct(made.stat().st_mode & 0o777) == "0o600"
    assert load_key(made) == (key, f"file {made}", None)
    os.chmod(made, 0o644)
    assert "readable by others" in (read_key_file(made)[1] or "")
    with pytest.raises(FileExistsError):
        write_key_file(made)  # never overwrites a key
    with pytest.raises(SigningError, match="cannot read"):
        read_key_file(tmp_path / "missing.key")
    assert load_key(None, environ={"MAVLINK_SIGNING_KEY": KEY.hex()}) == (KEY, "$MAVLINK_SIGNING_KEY", None)
    assert load_key(None, environ={})[0] is None
    assert fingerprint(KEY) != fingerprint(OTHER) and KEY.hex()[:8] not in fingerprint(KEY)


class FakeClock:
    """time.time for a test: starts at a fixed date and moves only when told."""

    def __init__(self) -> None:
        self.now = EPOCH_2015_S + 10 * 365 * 86400.0

    def __call__(self) -> float:
        return self.now


def test_timestamps_follow_the_clock_so_a_receiver_started_minutes_later_accepts_the_sender(monkeypatch) -> None:
    """The sender signs for two minutes at one frame every 0.6 s (a quiet link: 200 frames). A
    receiver that starts then must accept its next frame: its timestamp is the sender's clock, not
    the sender's start time plus 10 us per frame sent (pymavlink's counter, 120 s behind by then,
    which a new receiver refuses as a stale stream)."""
    clock = FakeClock()
    monkeypatch.setattr("time.time", clock)
    sender = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    enable_signing(sender, KEY)
    early = Check(KEY)  # a receiver that was there from the start
    for _ in range(200):
        clock.now += 0.6
        hb = sender.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                     mavlink.MAV_STATE_STANDBY)
        assert early.verdict(decode(hb.pack(sender))) is None
    late = Check(KEY)
    msg = decode(sender.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                         mavlink.MAV_STATE_STANDBY).pack(sender))
    assert late.verdict(msg) is None
    low, high = struct.unpack("<IH", bytes(msg.get_msgbuf())[-12:-6])
    assert abs((low | high << 32) - signing_timestamp(clock.now)) <= 1


def test_timestamps_still_increase_when_the_clock_steps_back(monkeypatch) -> None:
    clock = FakeClock()
    monkeypatch.setattr("time.time", clock)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    enable_signing(mav, KEY)
    stamps = []
    for step in (0.0, 0.0, -5.0, 0.0, 10.0):
        clock.now += step
        buf = mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                   mavlink.MAV_STATE_STANDBY).pack(mav)
        low, high = struct.unpack("<IH", buf[-12:-6])
        stamps.append(low | high << 32)
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert stamps[-1] == signing_timestamp(clock.now)


def test_a_genuine_far_future_frame_is_refused_and_locks_out_no_stream() -> None:
    """A keyed sender whose clock is a day ahead (or a keyed attacker) signs on link 7. Its frame is
    refused as a future timestamp and not remembered: the streams that start after it (the
    companion's, a ground station's) are judged against our clock, not against its timestamp."""
    check = Check(KEY)
    assert check.verdict(decode(frame(KEY, sysid=255, link_id=0))) is None
    ahead = signing_timestamp() + 86400 * 100_000
    assert check.verdict(decode(frame(KEY, sysid=255, link_id=7, timestamp=ahead))) == "future timestamp"
    assert (7, 255, 191) not in check.streams
    assert check.verdict(decode(frame(KEY, sysid=255, link_id=0))) is None  # the companion goes on
    assert check.verdict(decode(frame(KEY, sysid=42, link_id=0))) is None  # a new ground station is let in
    assert check.verdict(decode(frame(KEY, sysid=255, link_id=7))) is None  # link 7 itself, back on time


def test_the_future_bound_is_one_minute_of_our_clock() -> None:
    check = Check(KEY)
    now = signing_timestamp()
    assert check.verdict(decode(frame(KEY, sysid=3, timestamp=now + 61 * 100_000))) == "future timestamp"
    assert check.verdict(decode(frame(KEY, sysid=4, timestamp=now + 50 * 100_000))) is None


def test_rejections_are_described_by_their_cause() -> None:
    from companion.mavlink.signing import describe_rejections

    text = describe_rejections({"stale timestamp": 3, "wrong key": 1})
    assert text.startswith("3 signed with our key, but timestamped more than 60 s behind our clock")
    assert "1 signed with another key" in text
    assert "ahead of our clock" in describe_rejections({"future timestamp": 1})
    assert describe_rejections({"unsigned": 2}) == "2 not signed"
