"""A non-blocking stream socket read once: its bytes, nothing yet, or the end of the connection."""

from __future__ import annotations

import socket

__all__ = ["read_stream"]


def read_stream(sock: socket.socket) -> bytes | None:
    """What ``sock`` has: bytes; None when nothing is there yet; ``b""`` when the peer closed the
    connection or it failed (either way the connection is over)."""
    try:
        return sock.recv(65536)
    except (BlockingIOError, InterruptedError, TimeoutError):
        return None
    except OSError:
        return b""
