"""A man in the middle on real UDP sockets: forwards a client's datagrams to a vehicle and back,
and injects forged frames towards the client from the vehicle's side of the path (where a
router, a second component of the autopilot, or an attacker on that network would send them).

    mitm = Mitm(("127.0.0.1", vehicle_port))     # the client connects to mitm.url
    mitm.latest("ATTITUDE_QUATERNION")            # the newest genuine message of a kind
    mitm.inject([mitm.forge.highres_imu_encode(...)])
"""

from __future__ import annotations

import selectors
import socket
import threading
import time
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["Mitm"]


class Mitm:
    def __init__(self, vehicle: tuple[str, int], sysid: int = 1, compid: int = 1,
                 drop: frozenset[str] = frozenset()) -> None:
        self.vehicle = vehicle
        self.drop = drop
        """message types filtered out on the way to the client (a router configured to drop them)"""
        self.dropped = 0
        self.front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.front.bind(("127.0.0.1", 0))
        self.back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.back.bind(("127.0.0.1", 0))
        self.client: tuple[str, int] | None = None
        self.forge = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        """frames built with this carry the autopilot's own system and component id"""
        self.injected = 0
        self.down = 0
        self._parser = mavlink.MAVLink(None)
        self._parser.robust_parsing = True
        self._latest: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        host, port = self.front.getsockname()
        return f"{host}:{port}"

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self.front, selectors.EVENT_READ)
        sel.register(self.back, selectors.EVENT_READ)
        while not self._stop.is_set():
            for key, _ in sel.select(timeout=0.1):
                try:
                    data, addr = key.fileobj.recvfrom(65535)  # type: ignore[union-attr]
                except OSError:
                    continue
                if key.fileobj is self.front:
                    self.client = addr
                    self.back.sendto(data, self.vehicle)
                elif self.client is not None:
                    with self._lock:  # a forged frame is never sent before the genuine one it copies
                        self._down(data)

    def _down(self, data: bytes) -> None:
        """A genuine datagram to the client: noted (the newest of each kind) and sent, minus what is dropped."""
        msgs = self._note(data)
        if any(m.get_type() in self.drop for m in msgs):  # a datagram may carry several frames
            kept = [m for m in msgs if m.get_type() not in self.drop]
            self.dropped += len(msgs) - len(kept)
            if not kept:
                return
            data = b"".join(bytes(m.get_msgbuf()) for m in kept)
        self.front.sendto(data, self.client)  # type: ignore[arg-type]
        self.down += 1

    def _note(self, data: bytes) -> list[Any]:
        """Remember the newest of each kind; the messages of this datagram."""
        try:
            msgs = self._parser.parse_buffer(data) or []
        except Exception:
            return []
        for m in msgs:
            self._latest[m.get_type()] = m
        return msgs

    def latest(self, kind: str, timeout: float = 5.0) -> Any:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if kind in self._latest:
                return self._latest[kind]
            time.sleep(0.01)
        raise AssertionError(f"no {kind} passed through within {timeout} s")

    def inject(self, msgs: list[Any], gap_s: float = 0.002) -> None:
        assert self.client is not None, "no client yet"
        for m in msgs:
            with self._lock:
                self.front.sendto(m.pack(self.forge), self.client)
            self.injected += 1
            time.sleep(gap_s)

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.front.close()
        self.back.close()
