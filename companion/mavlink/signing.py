"""MAVLink 2 message signing shared by both ends: the key, signing what we send, checking what arrives.

A signed frame carries ``link_id`` (1 byte), a 48-bit timestamp in 10 µs units since
2015-01-01 00:00 UTC, and the first 6 bytes of SHA-256(key ‖ header ‖ payload ‖ CRC ‖ link_id ‖
timestamp). A frame is accepted when its signature is right and its timestamp is newer than the
last one accepted from the same (link_id, sysid, compid) stream; a stream not seen before must be
no more than one minute behind our clock (the MAVLink signing rules), and no frame may be more
than one minute ahead of it.

Timestamps follow the clock, as the MAVLink spec defines them. pymavlink sets a sender's timestamp
once (``setup_signing``) and then adds one unit (10 µs) per frame sent, so a sender's timestamps
fall behind the clock by almost a second per second: a vehicle sending 500 frames/s is 60 s
behind after about 60 s, and every receiver started after that refuses it as a stale new stream.
:func:`enable_signing` installs :class:`ClockSigning`, which signs each frame with
``max(clock, previous + 1)``.

Checking is ours, not pymavlink's: pymavlink records a stream's timestamp before it compares the
signature, so one forged frame with a far-future timestamp would lock the real sender out until
restart, and it compares a new stream with its own outgoing counter (the lagging one above). Here
the signature is checked first and only a genuine frame moves a stream forward; a new stream is
compared with our clock, never with another stream's timestamp, so a genuine frame from a sender
whose clock is far ahead (or a keyed system pushing timestamps ahead) is refused as a future
timestamp instead of locking out every stream that starts after it.

The key never needs to appear on a command line: it comes from a file (32 raw bytes, 64 hex digits,
or a passphrase hashed with SHA-256, as MAVProxy's ``signing setup`` does) or from the environment
variable :data:`KEY_ENV`.
"""

from __future__ import annotations

import hashlib
import os
import secrets
import stat
import struct
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from pymavlink.dialects.v20 import all as every_dialect
from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = [
    "KEY_ENV", "SigningError", "SignatureCheck", "key_from_text", "read_key_file", "load_key", "fingerprint",
    "signing_timestamp", "enable_signing", "write_key_file", "is_signed", "ClockSigning", "REASONS",
    "describe_rejections", "FrameSigner", "VEHICLE_ACCEPTS_UNSIGNED",
]

KEY_ENV = "MAVLINK_SIGNING_KEY"
EPOCH_2015_S = 1420070400
UNITS_PER_S = 100_000
NEW_STREAM_WINDOW = 60 * UNITS_PER_S
"""a stream we have not seen may start at most one minute behind our clock"""
FUTURE_WINDOW = 60 * UNITS_PER_S
"""no frame may be more than one minute ahead of our clock (it is refused, and not remembered)"""
SIGNED_FLAG = 0x01
SIGNATURE_LEN = 13
VEHICLE_ACCEPTS_UNSIGNED = frozenset({"HEARTBEAT", "RADIO_STATUS"})
"""what a vehicle with signing on takes unsigned: it changes nothing, and teaches no peer address"""


class SigningError(ValueError):
    """The key could not be read or makes no sense."""


def key_from_text(text: str) -> bytes:
    """64 hex digits are the key itself; any other text is a passphrase, hashed with SHA-256."""
    text = text.strip()
    if not text:
        raise SigningError("the signing key is empty")
    if len(text) == 64:
        try:
            return bytes.fromhex(text)
        except ValueError:
            pass
    return hashlib.sha256(text.encode("utf-8")).digest()


def read_key_file(path: str | Path) -> tuple[bytes, str | None]:
    """The key in ``path`` and a warning if others may read the file (None if they may not)."""
    p = Path(path)
    try:
        raw = p.read_bytes()
        mode = p.stat().st_mode
    except OSError as exc:
        raise SigningError(f"{p}: cannot read the signing key: {exc.strerror or exc}") from None
    warning = None
    if os.name == "posix" and mode & (stat.S_IRWXG | stat.S_IRWXO):
        warning = f"{p}: signing key file is readable by others (mode {stat.S_IMODE(mode):o}; chmod 600 it)"
    if len(raw) == 32:
        try:
            text = raw.decode("ascii")
        except UnicodeDecodeError:
            return raw, warning  # 32 raw bytes
        if not text.isprintable():
            return raw, warning
    try:
        return key_from_text(raw.decode("utf-8")), warning
    except UnicodeDecodeError:
        raise SigningError(f"{p}: expected 32 raw bytes, 64 hex digits or a passphrase, "
                           f"got {len(raw)} bytes that are not text") from None
    except SigningError as exc:
        raise SigningError(f"{p}: {exc}") from None


def load_key(key_file: str | Path | None, env_var: str | None = KEY_ENV,
             environ: Mapping[str, str] = os.environ) -> tuple[bytes | None, str, str | None]:
    """(key or None, where it came from, warning): the file if given, else the environment variable."""
    if key_file is not None:
        key, warning = read_key_file(key_file)
        return key, f"file {key_file}", warning
    if env_var and environ.get(env_var):
        return key_from_text(environ[env_var]), f"${env_var}", None
    return None, "off", None


def write_key_file(path: str | Path) -> bytes:
    """A new random key, written as 64 hex digits to a file only its owner can read."""
    key = secrets.token_bytes(32)
    p = Path(path)
    fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(key.hex() + "\n")
    return key


def fingerprint(key: bytes) -> str:
    """A short name for a key that does not reveal it (to compare both ends' logs)."""
    return hashlib.sha256(b"fingerprint:" + key).hexdigest()[:8]


def _now() -> float:
    return time.time()  # looked up at each call (a test may replace time.time)


def signing_timestamp(now_s: float | None = None) -> int:
    """Now, in signing units (10 µs since 2015-01-01 00:00 UTC)."""
    t = time.time() if now_s is None else now_s
    return int((t - EPOCH_2015_S) * UNITS_PER_S)


class ClockSigning(mavlink.MAVLinkSigning):
    """pymavlink's signing state, with a ``timestamp`` that follows ``clock``.

    pymavlink signs a frame with ``signing.timestamp`` and then adds 1 to it; here reading it gives
    ``max(clock now, the last value + 1)``, so every frame carries the time it was sent (in signing
    units) and a link's timestamps still strictly increase (a clock stepped back is ridden out).
    """

    def __init__(self, clock: Callable[[], float] = _now) -> None:
        super().__init__()
        self.clock = clock

    @property  # type: ignore[override]
    def timestamp(self) -> int:
        return max(self._next, signing_timestamp(self.clock()))

    @timestamp.setter
    def timestamp(self, value: int) -> None:
        self._next = int(value)

    _next = 0


def enable_signing(mav: Any, key: bytes, link_id: int = 0, clock: Callable[[], float] = _now) -> None:
    """Make a pymavlink ``MAVLink`` object sign everything it packs from now on, each frame stamped
    with ``clock`` (UNIX seconds; a test may pass another clock to play a sender whose clock is off)."""
    if len(key) != 32:
        raise SigningError(f"a signing key is 32 bytes, got {len(key)}")
    signing = ClockSigning(clock)
    signing.secret_key = key
    signing.link_id = link_id & 0xFF
    signing.sign_outgoing = True
    mav.signing = signing


def is_signed(msg: Any) -> bool:
    """The decoded frame carries a MAVLink 2 signature (checked or not)."""
    return bool(getattr(msg.get_header(), "incompat_flags", 0) & SIGNED_FLAG)


REASONS = {
    "unsigned": "not signed",
    "wrong key": "signed with another key (or altered on the way)",
    "replayed": "replayed: a timestamp this stream already used",
    "stale timestamp": "signed with our key, but timestamped more than 60 s behind our clock "
                       "(a clock behind ours, or frames recorded earlier)",
    "future timestamp": "signed with our key, but timestamped more than 60 s ahead of our clock "
                        "(a clock ahead of ours)",
}
"""why :meth:`SignatureCheck.verdict` refuses a frame, and what each reason means"""


def describe_rejections(counts: Mapping[str, int]) -> str:
    """``{reason: frames}`` as one sentence that names each cause, most frequent first."""
    parts = [f"{n} {REASONS.get(reason, reason)}" for reason, n in Counter(counts).most_common()]
    return "; ".join(parts)


@dataclass
class SignatureCheck:
    """Accept a decoded frame only if it is signed with ``key``, not a replay, and timed within a
    minute of our clock.

    Use it on frames decoded by a parser that has no key (so it hands every frame over);
    :meth:`verdict` is None for an accepted frame, else the reason it is refused (a key of
    :data:`REASONS`).
    """

    key: bytes
    allow_unsigned: frozenset[str] = frozenset()
    """message names accepted without a signature (e.g. a radio's RADIO_STATUS)"""
    clock: Callable[[], float] = _now
    """our clock (UNIX seconds): new streams and future timestamps are judged against it alone"""
    streams: dict[tuple[int, int, int], int] = field(default_factory=dict)
    """the newest accepted timestamp of each (link_id, sysid, compid)"""
    max_streams: int = 256

    def verdict(self, msg: Any) -> str | None:
        header = msg.get_header()
        return self.frame_verdict(bytes(msg.get_msgbuf()), msg.get_type(), header.srcSystem, header.srcComponent)

    def frame_verdict(self, buf: bytes, name: str, sysid: int, compid: int) -> str | None:
        """:meth:`verdict` of one whole frame as it came off the wire (``name``: its message's)."""
        if not (buf[:1] == b"\xfd" and len(buf) > 2 and buf[2] & SIGNED_FLAG):
            return None if name in self.allow_unsigned else "unsigned"
        if len(buf) < 12 + SIGNATURE_LEN:
            return "wrong key"
        link_id = buf[-13]
        low, high = struct.unpack("<IH", buf[-12:-6])
        timestamp = low | (high << 32)
        if hashlib.sha256(self.key + buf[:-6]).digest()[:6] != buf[-6:]:
            return "wrong key"
        now = signing_timestamp(self.clock())
        if timestamp > now + FUTURE_WINDOW:
            return "future timestamp"  # not stored: it must not push this stream (or any other) ahead
        stream = (link_id, sysid, compid)
        last = self.streams.get(stream)
        if last is not None:
            if timestamp <= last:
                return "replayed"
        elif timestamp + NEW_STREAM_WINDOW < now:
            return "stale timestamp"
        if last is None and len(self.streams) >= self.max_streams:
            self.streams.pop(min(self.streams, key=self.streams.__getitem__))
        self.streams[stream] = timestamp
        return None


def _crc(header_and_payload: bytes, crc_extra: int) -> bytes:
    crc = mavlink.x25crc(header_and_payload)
    crc.accumulate(bytes([crc_extra]))
    return struct.pack("<H", crc.crc)


@dataclass
class FrameSigner:
    """Sign whole frames that were packed by someone else (a firmware behind a relay): each leaves as
    a MAVLink 2 frame with the signed flag, its CRC recomputed, and a timestamp from ``clock`` that
    strictly increases. A MAVLink 1 frame is carried over into MAVLink 2 first (a signature needs
    the version 2 header); a message no dialect knows cannot be re-framed and is refused (None)."""

    key: bytes
    link_id: int = 0
    clock: Callable[[], float] = _now
    _last: int = 0

    def timestamp(self) -> int:
        self._last = max(self._last + 1, signing_timestamp(self.clock()))
        return self._last

    def sign(self, frame: bytes) -> bytes | None:
        if frame[:1] == b"\xfd" and len(frame) >= 12:
            length = frame[1]
            header = bytearray(frame[:10])
            msgid = frame[7] | frame[8] << 8 | frame[9] << 16
            payload = frame[10:10 + length]
        elif frame[:1] == b"\xfe" and len(frame) >= 8:
            length, seq, sysid, compid, msgid = frame[1], frame[2], frame[3], frame[4], frame[5]
            header = bytearray(b"\xfd" + bytes([length, 0, 0, seq, sysid, compid]) + struct.pack("<I", msgid)[:3])
            payload = frame[6:6 + length]
        else:
            return None
        entry = every_dialect.mavlink_map.get(msgid)
        if entry is None or len(payload) != length:
            return None
        header[2] |= SIGNED_FLAG
        body = bytes(header) + payload
        body += _crc(body[1:], entry.crc_extra)
        tail = bytes([self.link_id & 0xFF]) + struct.pack("<Q", self.timestamp())[:6]
        return body + tail + hashlib.sha256(self.key + body + tail).digest()[:6]
