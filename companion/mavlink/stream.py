"""MAVLink over byte streams — a TCP socket or a serial port — delivered as whole frames.

A UDP datagram carries whole frames; a stream carries bytes, and a frame may arrive in pieces or
several at once. :class:`FrameSplitter` cuts the stream into frames by MAVLink's own framing
(v2: 0xFD, length, incompatibility flags -> 12 + length bytes, + 13 when signed; v1: 0xFE ->
8 + length), skipping garbage up to the next start byte, so the rest of the receive path
(:mod:`.wire`: one frame parsed on its own, counts not raises) is the same as for UDP.

:class:`TcpEndpoint` and :class:`SerialEndpoint` have :class:`~companion.mavlink.udp.UdpEndpoint`'s
shape (``on_datagram(frame, peer)``, ``sendto``, ``close``). Serial ports are opened with the
standard library (``termios``): raw mode, the baud rate, optional RTS/CTS flow control.
"""

from __future__ import annotations

import asyncio
import os
import socket
import termios
import tty
from collections.abc import Callable

__all__ = ["FrameSplitter", "TcpEndpoint", "SerialEndpoint"]

STX_V2, STX_V1 = 0xFD, 0xFE
MAX_BUFFER = 1 << 16


class FrameSplitter:
    def __init__(self) -> None:
        self._buf = bytearray()
        self.skipped = 0
        """bytes thrown away that did not start a frame"""

    def feed(self, data: bytes) -> list[bytes]:
        buf = self._buf
        buf += data
        frames: list[bytes] = []
        while buf:
            if buf[0] not in (STX_V2, STX_V1):
                nxt = next((i for i, b in enumerate(buf) if b in (STX_V2, STX_V1)), len(buf))
                self.skipped += nxt
                del buf[:nxt]
                continue
            if len(buf) < 3:
                break
            if buf[0] == STX_V2:
                size = 12 + buf[1] + (13 if buf[2] & 0x01 else 0)
            else:
                size = 8 + buf[1]
            if len(buf) < size:
                break
            frames.append(bytes(buf[:size]))
            del buf[:size]
        if len(buf) > MAX_BUFFER:  # cannot be a frame (255 + 25 bytes at most): start over
            self.skipped += len(buf)
            buf.clear()
        return frames


class _StreamEndpoint:
    peer: tuple[str, int] = ("stream", 0)

    def __init__(self, on_datagram: Callable[[bytes, tuple[str, int]], None],
                 on_error: Callable[[OSError], None] | None = None,
                 on_closed: Callable[[], None] | None = None) -> None:
        self.on_datagram = on_datagram
        self.on_error = on_error
        self.on_closed = on_closed
        self.splitter = FrameSplitter()
        self.send_dropped = 0
        self._fd: int | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._out = bytearray()

    def _start(self, fd: int) -> None:
        self._fd = fd
        self._loop = asyncio.get_running_loop()
        self._loop.add_reader(fd, self._readable)

    def _read(self, fd: int) -> bytes:
        return os.read(fd, 65536)

    def _write(self, fd: int, data: bytes) -> int:
        return os.write(fd, data)

    def _readable(self) -> None:
        if self._fd is None:
            return
        try:
            data = self._read(self._fd)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            if self.on_error is not None:
                self.on_error(exc)
            self._lost()
            return
        if not data:
            self._lost()
            return
        for frame in self.splitter.feed(data):
            self.on_datagram(frame, self.peer)

    def _lost(self) -> None:
        self.close()
        if self.on_closed is not None:
            self.on_closed()

    def sendto(self, data: bytes, addr: object = None) -> None:
        """Write a frame; what the stream cannot take now waits (bounded: beyond 64 KiB it is dropped,
        as a full radio would)."""
        if self._fd is None:
            return
        if len(self._out) + len(data) > MAX_BUFFER:
            self.send_dropped += 1
            return
        self._out += data
        self._flush()

    def _flush(self) -> None:
        if self._fd is None or not self._out:
            return
        try:
            n = self._write(self._fd, bytes(self._out))
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError as exc:
            if self.on_error is not None:
                self.on_error(exc)
            return
        del self._out[:n]
        if self._out and self._loop is not None:
            self._loop.call_later(0.001, self._flush)

    def close(self) -> None:
        if self._fd is None:
            return
        if self._loop is not None and not self._loop.is_closed():
            self._loop.remove_reader(self._fd)
        self._close_fd(self._fd)
        self._fd = None

    def _close_fd(self, fd: int) -> None:
        os.close(fd)


class TcpEndpoint(_StreamEndpoint):
    """A TCP client (ArduPilot SITL's SERIAL0 listens on 5760)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._sock: socket.socket | None = None

    async def open(self, host: str, port: int, timeout_s: float = 5.0) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)
        try:
            await asyncio.wait_for(asyncio.get_running_loop().sock_connect(sock, (host, port)), timeout_s)
        except (OSError, TimeoutError):
            sock.close()
            raise
        self._sock = sock
        self.peer = (host, port)
        self._start(sock.fileno())

    def _read(self, fd: int) -> bytes:
        assert self._sock is not None
        return self._sock.recv(65536)

    def _write(self, fd: int, data: bytes) -> int:
        assert self._sock is not None
        return self._sock.send(data)

    def _close_fd(self, fd: int) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class SerialEndpoint(_StreamEndpoint):
    """A serial port (a flight controller's TELEM2; a pseudo-terminal in the tests)."""

    def open(self, device: str, baud: int, flow_control: bool = False) -> None:
        fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(fd)
            attrs = termios.tcgetattr(fd)
            speed = getattr(termios, f"B{baud}")
            attrs[4] = attrs[5] = speed  # ispeed, ospeed
            attrs[2] |= termios.CLOCAL | termios.CREAD
            if flow_control:
                attrs[2] |= termios.CRTSCTS
            else:
                attrs[2] &= ~termios.CRTSCTS
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
        except (termios.error, AttributeError, OSError) as exc:
            os.close(fd)
            raise OSError(f"{device}: cannot set {baud} baud raw mode: {exc}") from None
        self.peer = (device, baud)
        self._start(fd)
