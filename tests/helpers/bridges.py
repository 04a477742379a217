"""A serial line and a TCP connection in front of the bundled vehicle (which speaks UDP), the way a
telemetry radio or a router sits in front of a real one: the companion's serial and TCP transports
are then exercised end to end against the real vehicle process.

- :class:`PtyBridge`: a pseudo-terminal pair; the companion opens ``device`` (serial:///dev/pts/N:BAUD),
  the bridge carries whole frames between the other end and the vehicle's UDP port;
- :class:`TcpBridge`: a TCP server on 127.0.0.1 (tcp://127.0.0.1:PORT), one client at a time.
"""

from __future__ import annotations

import os
import selectors
import socket
import threading
import tty

from companion.mavlink.stream import FrameSplitter

__all__ = ["PtyBridge", "TcpBridge"]


class _Bridge:
    def __init__(self, vehicle: tuple[str, int]) -> None:
        self.vehicle = vehicle
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp.bind(("127.0.0.1", 0))
        self.frames_up = self.frames_down = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _up(self, data: bytes, splitter: FrameSplitter) -> None:
        for frame in splitter.feed(data):
            self.udp.sendto(frame, self.vehicle)
            self.frames_up += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.udp.close()


class PtyBridge(_Bridge):
    def __init__(self, vehicle: tuple[str, int]) -> None:
        super().__init__(vehicle)
        self.master, slave = os.openpty()
        tty.setraw(self.master)
        self.device = os.ttyname(slave)
        os.close(slave)  # the companion opens it by name
        os.set_blocking(self.master, False)
        self._thread.start()

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self.master, selectors.EVENT_READ)
        sel.register(self.udp, selectors.EVENT_READ)
        splitter = FrameSplitter()
        while not self._stop.is_set():
            for key, _ in sel.select(timeout=0.1):
                try:
                    if key.fileobj == self.master:
                        self._up(os.read(self.master, 65536), splitter)
                    else:
                        data = self.udp.recv(65536)
                        os.write(self.master, data)
                        self.frames_down += 1
                except OSError:  # nobody has the other end open yet (EIO), or a full line
                    continue
        os.close(self.master)


class TcpBridge(_Bridge):
    def __init__(self, vehicle: tuple[str, int]) -> None:
        super().__init__(vehicle)
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(1)
        self.port = self.server.getsockname()[1]
        self._thread.start()

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self.server, selectors.EVENT_READ)
        sel.register(self.udp, selectors.EVENT_READ)
        conn: socket.socket | None = None
        splitter = FrameSplitter()
        while not self._stop.is_set():
            for key, _ in sel.select(timeout=0.1):
                if key.fileobj is self.server:
                    if conn is not None:
                        sel.unregister(conn)
                        conn.close()
                    conn, _ = self.server.accept()
                    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    sel.register(conn, selectors.EVENT_READ)
                    splitter = FrameSplitter()
                elif key.fileobj is self.udp:
                    data = self.udp.recv(65536)
                    if conn is not None:
                        try:
                            conn.sendall(data)
                            self.frames_down += 1
                        except OSError:
                            pass
                elif conn is not None:
                    data = conn.recv(65536)
                    if not data:
                        sel.unregister(conn)
                        conn.close()
                        conn = None
                        continue
                    self._up(data, splitter)
        if conn is not None:
            conn.close()
        self.server.close()
