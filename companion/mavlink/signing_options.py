"""The signing-key options shared by the ``companion`` and ``sitl`` commands (the key is never an argument)."""

from __future__ import annotations

import argparse
import sys

from .signing import KEY_ENV, fingerprint, load_key

__all__ = ["add_signing_options", "signing_key"]


def add_signing_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--signing-key-file", metavar="FILE",
                        help=f"MAVLink 2 signing key: 32 bytes, 64 hex digits or a passphrase "
                             f"(default: ${KEY_ENV} if set, else no signing)")
    parser.add_argument("--no-signing", action="store_true", help=f"ignore ${KEY_ENV}")


def signing_key(args: argparse.Namespace, prog: str) -> bytes | None:
    """The key from ``--signing-key-file`` or the environment (None: off), announced by fingerprint
    only. Raises SigningError for a key that cannot be read."""
    if args.no_signing:
        return None
    key, source, warning = load_key(args.signing_key_file, KEY_ENV)
    if warning:
        print(f"{prog}: warning: {warning}", file=sys.stderr)
    if key is not None and not getattr(args, "quiet", False):
        print(f"{prog}: MAVLink 2 signing on (key from {source}, fingerprint {fingerprint(key)})", flush=True)
    return key
