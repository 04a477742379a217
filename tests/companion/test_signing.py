"""MAVLink 2 signing: keys, and which frames the check accepts (frames packed and parsed by pymavlink)."""

from __future__ import annotations

import hashlib
import os
import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.signing import (
    SignatureCheck, SigningError, enable_signing, fingerprint, key_from_text, load_key, read_key_file,
    signing_timestamp, write_key_file,
)
from companion.mavlink.wire import new_parser, parse_datagram

KEY = bytes(range(32))
OTHER = bytes(range(1, 33))


def frame(key: bytes | None, sysid: int = 255, link_id: int = 0, timestamp: int | None = None) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=191)
    if key is not None:
        enable_signing(mav, key, link_id)
        if timestamp is not None:
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
    assert check.verdict(decode(frame(OTHER))) == "bad signature"
    buf = bytearray(frame(KEY))
    buf[14] ^= 0x40  # flip a payload bit and fix the CRC so that only the signature can tell
    crc = mavlink.x25crc(bytes(buf[1:-15]))
    crc.accumulate(bytes([mavlink.MAVLink_set_attitude_target_message.crc_extra]))
    buf[-15:-13] = struct.pack("<H", crc.crc)
    assert check.verdict(decode(bytes(buf))) == "bad signature"


def test_allow_unsigned_names_only_the_listed_messages() -> None:
    check = SignatureCheck(KEY, allow_unsigned=frozenset({"HEARTBEAT"}))
    mav = mavlink.MAVLink(None, srcSystem=42, srcComponent=1)
    hb = mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav)
    assert check.verdict(decode(hb)) is None
    assert check.verdict(decode(frame(None))) == "unsigned"


def test_a_forged_far_future_timestamp_does_not_lock_out_the_real_sender() -> None:
    """pymavlink's own check records a stream's timestamp before comparing the signature; ours must not."""
    check = SignatureCheck(KEY)
    assert check.verdict(decode(frame(KEY))) is None
    forged = frame(OTHER, timestamp=2**48 - 2)  # same stream (link 0, sysid 255, compid 191)
    assert check.verdict(decode(forged)) == "bad signature"
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
    assert check.verdict(decode(frame(KEY, sysid=7, timestamp=old))) == "stale"
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
