"""A UDP socket on the asyncio event loop that reads every waiting datagram at each wake-up.

asyncio's datagram transport reads **one** datagram per event-loop iteration. A process whose
loop is busy (the simulated vehicle stepping physics at 5x, the companion ticking at 500 Hz of
wall time) then drains a steady stream no faster than it iterates, and a backlog that forms in a
moment of contention never clears: in a 2 h soak the vehicle flew setpoints that had waited
0.1-0.4 s in its socket buffer (0.5-1.9 s of vehicle time) and lost control. Here the reader
callback empties the socket (up to ``max_batch`` datagrams, so a flood cannot starve the
caller's own work) every time it runs. Used by both ends: ``sitl.autopilot.server`` and the pymavlink link.

With ``coalesce_bytes`` the frames sent to one address in one stretch of the loop (one callback
or one step of a task: the simulated vehicle's steps between two waits) leave together, in
datagrams of at most that many bytes, when the loop next runs its ready callbacks, as
ArduPilot's UDP links carry several whole frames per packet (``AP_HAL`` packetise). Each
datagram costs its receiver an event-loop wake-up, a ``recvfrom`` and a queue round, whatever
it carries; the frames and their order are the same. An owner that flushes itself at the end of
each stretch (``flush_soon=False``: the simulated vehicle, before each wait) spares the loop that
callback; what the reader's own callback sent then leaves at its end.
"""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Callable

__all__ = ["UdpEndpoint"]

MAX_DATAGRAM = 65535


class UdpEndpoint:
    def __init__(self, on_datagram: Callable[[bytes, tuple[str, int]], None],
                 on_error: Callable[[OSError], None] | None = None, max_batch: int = 512,
                 coalesce_bytes: int = 0, flush_soon: bool = True,
                 after_batch: Callable[[], None] | None = None) -> None:
        self.on_datagram = on_datagram
        self.after_batch = after_batch
        """called once the datagrams waiting at a wake-up have all been handed over"""
        self.on_error = on_error
        self.max_batch = max_batch
        self.coalesce_bytes = coalesce_bytes
        self.flush_soon = flush_soon
        """coalesced frames leave when the loop next runs its callbacks (False: at :meth:`flush`, which
        the owner calls at the end of each stretch of its own, and at the end of the reader's callback)"""
        self.send_dropped = 0
        """datagrams not sent because the socket's send buffer was full"""
        self._outbox: dict[tuple[str, int], bytearray] = {}
        self._sock: socket.socket | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    def open(self, local_addr: tuple[str, int]) -> None:
        """Bind and start reading (raises OSError as ``socket.bind`` does)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            sock.bind(local_addr)
        except OSError:
            sock.close()
            raise
        self._sock = sock
        self._loop = asyncio.get_running_loop()
        self._loop.add_reader(sock.fileno(), self._readable)

    @property
    def sockname(self) -> tuple[str, int]:
        assert self._sock is not None
        host, port = self._sock.getsockname()[:2]
        return host, port

    def _readable(self) -> None:
        sock = self._sock
        if sock is None:
            return
        for _ in range(self.max_batch):
            try:
                data, addr = sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:  # e.g. an ICMP port-unreachable reported on the socket
                if self.on_error is not None:
                    self.on_error(exc)
                continue
            self.on_datagram(data, addr)
        if self.after_batch is not None:
            self.after_batch()
        if self._outbox and not self.flush_soon:  # what the datagrams' handlers sent
            self.flush()

    def sendto(self, data: bytes, addr: tuple[str, int]) -> None:
        """``data`` (whole frames) to ``addr``: now, or with the frames that follow it in this stretch
        of the loop (``coalesce_bytes``)."""
        if self._sock is None:
            return
        if not self.coalesce_bytes:
            self._send_now(data, addr)
            return
        outbox = self._outbox
        pending = outbox.get(addr)
        if pending is None:
            if not outbox and self._loop is not None and self.flush_soon:
                self._loop.call_soon(self.flush)
            outbox[addr] = bytearray(data)
        elif len(pending) + len(data) > self.coalesce_bytes:
            self._send_now(bytes(pending), addr)
            outbox[addr] = bytearray(data)
        else:
            pending += data

    def flush(self) -> None:
        """Send what waits to be coalesced."""
        outbox, self._outbox = self._outbox, {}
        for addr, pending in outbox.items():
            self._send_now(bytes(pending), addr)

    def _send_now(self, data: bytes, addr: tuple[str, int]) -> None:
        if self._sock is None:
            return
        try:
            self._sock.sendto(data, addr)
        except (BlockingIOError, InterruptedError):
            self.send_dropped += 1  # UDP: a full send buffer loses the datagram, as the wire would
        except OSError as exc:
            if self.on_error is not None:
                self.on_error(exc)

    def close(self) -> None:
        if self._sock is None:
            return
        self.flush()
        if self._loop is not None and not self._loop.is_closed():
            self._loop.remove_reader(self._sock.fileno())
        self._sock.close()
        self._sock = None
