"""The loop that lets a real autopilot's firmware fly the plant: one thread, every socket in one
selector, the world stepped when the firmware asks for its next frame, the companion allows it
(:class:`~.lockstep.CompanionGate`) and the speed-up cap is not exceeded (:class:`Pace`).

:class:`Bridge` owns the plant's own MAVLink component (:mod:`.plant_component`, over UDP) and the
companion relay (:mod:`.relay`); the firmware's simulator link is a subclass's
(:class:`~.px4.Px4Bridge`, :class:`~.ardupilot.ArduPilotBridge`).
"""

from __future__ import annotations

import math
import selectors
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .lockstep import CompanionGate
from .plant_component import PlantComponent
from .relay import TcpRelay, UdpRelay
from .world import FirmwareWorld

__all__ = ["Pace", "Bridge", "PlantSocket"]


@dataclass
class Pace:
    """At most ``speedup`` simulated seconds per wall second. A world that falls behind (a busy
    host, a slow firmware) is not raced back: after ``max_behind_wall_s`` the pace re-anchors."""

    speedup: float
    max_behind_wall_s: float = 0.05
    anchor_wall: float = math.nan
    anchor_t: float = 0.0
    re_anchored: int = 0

    def due_wall(self, t_s: float, now_wall: float) -> float:
        """Wall time at which the world may reach ``t_s``."""
        if math.isnan(self.anchor_wall):
            self.anchor_wall, self.anchor_t = now_wall, t_s
        due = self.anchor_wall + (t_s - self.anchor_t) / self.speedup
        if now_wall - due > self.max_behind_wall_s:
            self.anchor_wall, self.anchor_t = now_wall, t_s
            self.re_anchored += 1
            return now_wall
        return due


class PlantSocket:
    """The plant component's UDP endpoint: bound to ``port``; replies go to whoever sent last
    (PX4's MAVLink instance, ArduPilot's SERIAL2 as a UDP client)."""

    def __init__(self, port: int, peer: tuple[str, int] | None = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.sock.setblocking(False)
        self.peer = peer

    def send(self, datagrams: list[bytes]) -> None:
        if self.peer is None:
            return
        for d in datagrams:
            try:
                self.sock.sendto(d, self.peer)
            except OSError:
                pass

    def recv_all(self) -> list[bytes]:
        out = []
        for _ in range(256):
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                continue
            self.peer = addr
            out.append(data)
        return out


@dataclass
class BridgeStats:
    frames: int = 0
    firmware_late: int = 0
    """frames after which the firmware's outputs did not come within the wait (sent anyway)"""
    counts: dict[str, int] = field(default_factory=dict)


class Bridge:
    """The shared loop; a subclass provides the firmware's simulator link."""

    FIRMWARE_WAIT_WALL_S = 1.0

    def __init__(self, world: FirmwareWorld, component: PlantComponent, plant: PlantSocket,
                 relay: UdpRelay | TcpRelay, gate: CompanionGate, pace: Pace) -> None:
        self.world, self.component, self.plant, self.relay = world, component, plant, relay
        self.gate, self.pace = gate, pace
        self.stats = BridgeStats()
        self.sel = selectors.DefaultSelector()
        self.sel.register(plant.sock, selectors.EVENT_READ, self._plant_readable)
        self._relay_socks: set[socket.socket] = set()
        self._sync_relay()
        self.wall0 = time.monotonic()

    # --- the firmware's side (subclasses) -----------------------------------------------------

    def firmware_waiting(self) -> bool:
        """The firmware waits for its next frame (it has answered the last one)."""
        raise NotImplementedError

    def step_frame(self) -> None:
        raise NotImplementedError

    def firmware_wait_expired(self, now: float) -> bool:
        """The firmware has been silent too long after a frame: proceed without its answer."""
        return False

    # --- the loop ------------------------------------------------------------------------------

    def register(self, sock: socket.socket, handler: Callable[[Any], None]) -> None:
        self.sel.register(sock, selectors.EVENT_READ, handler)

    def unregister(self, sock: socket.socket) -> None:
        try:
            self.sel.unregister(sock)
        except (KeyError, ValueError):
            pass

    def _sync_relay(self) -> None:
        socks = set(self.relay.sockets())
        for s in self._relay_socks - socks:
            self.unregister(s)
        for s in socks - self._relay_socks:
            self.register(s, self._relay_readable)
        self._relay_socks = socks

    def _relay_readable(self, sock: socket.socket) -> None:
        self.relay.readable(sock)
        if isinstance(self.relay, TcpRelay):
            self._sync_relay()

    def _plant_readable(self, sock: socket.socket) -> None:
        for data in self.plant.recv_all():
            self.plant.send(self.component.receive(data))

    def run(self, stop: Callable[[], bool], duration_s: float | None = None) -> None:
        world, gate, pace = self.world, self.gate, self.pace
        next_tick = 0.0
        while not stop():
            if duration_s is not None and world.t >= duration_s:
                break
            now = time.monotonic()
            timeout = 0.01
            if self.firmware_waiting() or self.firmware_wait_expired(now):
                if gate.may_advance(now):
                    due = pace.due_wall(world.t, now)
                    if due <= now:
                        self.step_frame()
                        self.stats.frames += 1
                        timeout = 0.0
                    else:
                        timeout = min(timeout, due - now)
                else:
                    timeout = 0.002
            for key, _ in self.sel.select(timeout):
                key.data(key.fileobj)
            if isinstance(self.relay, TcpRelay) and self.relay._unpaired:
                self.relay.retry()
                self._sync_relay()
            if world.t >= next_tick:
                next_tick = world.t + 0.05
                self.plant.send(self.component.tick(world.t))
                self.plant.send(self.component.said())
                if self.component.heartbeat is not None:
                    # the firmware's forwarding may drop it (PX4 keeps two forwarded messages a
                    # link): the companion hears of the plant directly
                    self.relay.inject(self.component.heartbeat)
                    self.component.heartbeat = None

    def close(self) -> None:
        self.relay.close()
        self.plant.sock.close()
        self.sel.close()

    def report(self) -> dict[str, object]:
        wall = time.monotonic() - self.wall0
        g = self.gate
        return {"t": round(self.world.t, 3), "wall_s": round(wall, 1),
                "speedup": round(self.world.t / wall, 2) if wall > 0 else 0.0, "frames": self.stats.frames,
                "firmware_late": self.stats.firmware_late, "lockstep": {"waits": g.waits,
                                                                        "waited_s": round(g.waited_s, 2),
                                                                        "gave_up": g.gave_up,
                                                                        "gave_up_at_s": g.gave_up_at_s},
                "pace_re_anchored": self.pace.re_anchored, "plant_params": dict(self.component.stats),
                "shadowed": sorted(self.component.shadowed),
                **({"signing_refused": dict(self.relay.signing.refused)} if self.relay.signing is not None else {})}
