"""MAVLink 2 message signing shared by both ends: the key, signing what we send, checking what arrives.

A signed frame carries ``link_id`` (1 byte), a 48-bit timestamp in 10 µs units since
2015-01-01 00:00 UTC, and the first 6 bytes of SHA-256(key ‖ header ‖ payload ‖ CRC ‖ link_id ‖
timestamp). A frame is accepted when its signature is right and its timestamp is newer than the
last one accepted from the same (link_id, sysid, compid) stream; a stream not seen before must be
no more than one minute behind the newest timestamp we know (the MAVLink signing rules).

Checking is ours, not pymavlink's: pymavlink records a stream's timestamp before it compares the
signature, so one forged frame with a far-future timestamp would lock the real sender out until
restart. Here the signature is checked first and only a genuine frame moves a stream forward.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

__all__ = [
    "KEY_ENV", "SigningError", "SignatureCheck", "key_from_text", "read_key_file", "load_key", "fingerprint",
    "signing_timestamp", "enable_signing", "write_key_file", "is_signed",
]

KEY_ENV = "MAVLINK_SIGNING_KEY"
EPOCH_2015_S = 1420070400
UNITS_PER_S = 100_000
NEW_STREAM_WINDOW = 60 * UNITS_PER_S
"""a stream we have not seen may start at most one minute behind the newest timestamp"""
SIGNED_FLAG = 0x01
SIGNATURE_LEN = 13


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


def signing_timestamp(now_s: float | None = None) -> int:
    """Now, in signing units (10 µs since 2015-01-01 00:00 UTC)."""
    t = time.time() if now_s is None else now_s
    return int((t - EPOCH_2015_S) * UNITS_PER_S)


def enable_signing(mav: Any, key: bytes, link_id: int = 0) -> None:
    """Make a pymavlink ``MAVLink`` object sign everything it packs from now on."""
    if len(key) != 32:
        raise SigningError(f"a signing key is 32 bytes, got {len(key)}")
    mav.signing.secret_key = key
    mav.signing.link_id = link_id & 0xFF
    mav.signing.timestamp = signing_timestamp()
    mav.signing.sign_outgoing = True


def is_signed(msg: Any) -> bool:
    """The decoded frame carries a MAVLink 2 signature (checked or not)."""
    return bool(getattr(msg.get_header(), "incompat_flags", 0) & SIGNED_FLAG)


@dataclass
class SignatureCheck:
    """Accept a decoded frame only if it is signed with ``key`` and not a replay.

    Use it on frames decoded by a parser that has no key (so it hands every frame over);
    :meth:`verdict` is None for an accepted frame, else the reason it is refused.
    """

    key: bytes
    allow_unsigned: frozenset[str] = frozenset()
    """message names accepted without a signature (e.g. a radio's RADIO_STATUS)"""
    newest: int = field(default_factory=signing_timestamp)
    """newest timestamp known: our own clock, or the newest genuine frame"""
    streams: dict[tuple[int, int, int], int] = field(default_factory=dict)
    max_streams: int = 256

    def verdict(self, msg: Any) -> str | None:
        buf = bytes(msg.get_msgbuf())
        header = msg.get_header()
        if not (is_signed(msg) and buf[:1] == b"\xfd"):
            return None if msg.get_type() in self.allow_unsigned else "unsigned"
        if len(buf) < 12 + SIGNATURE_LEN:
            return "bad signature"
        link_id = buf[-13]
        low, high = struct.unpack("<IH", buf[-12:-6])
        timestamp = low | (high << 32)
        if hashlib.sha256(self.key + buf[:-6]).digest()[:6] != buf[-6:]:
            return "bad signature"
        stream = (link_id, header.srcSystem, header.srcComponent)
        last = self.streams.get(stream)
        if last is not None:
            if timestamp <= last:
                return "replayed"
        elif timestamp + NEW_STREAM_WINDOW < max(self.newest, signing_timestamp()):
            return "stale"
        if last is None and len(self.streams) >= self.max_streams:
            self.streams.pop(min(self.streams, key=self.streams.__getitem__))
        self.streams[stream] = timestamp
        self.newest = max(self.newest, timestamp)
        return None
