"""The companion's link to the firmware, relayed through the bridge so that lockstep can see it.

The firmware's companion port stays where users expect it (PX4: UDP to 14540, ArduPilot: TCP
5760); the firmware itself is moved behind it (PX4's API link sends to the relay instead of 14540;
ArduPilot's SERIAL0 serves another port) and every byte passes through unchanged, both ways
(under MAVLink 2 signing, :mod:`.signed_link`, frames in are checked and frames out signed). On
the way the relay reads two things from MAVLink headers, never decoding or altering a frame: the
``time_boot_ms`` of the companion's setpoints (SET_ATTITUDE_TARGET, SET_POSITION_TARGET_*) and the
firmware's own time in its telemetry, for :class:`~.lockstep.CompanionGate`.
"""

from __future__ import annotations

import socket
from collections.abc import Callable
from typing import TYPE_CHECKING

from .frames import CLOCKS_MS, CLOCKS_US, COMMANDS, SETPOINTS, armed, for_component, frames, stamps
from .sockets import read_stream

if TYPE_CHECKING:
    from .signed_link import SignedLink

__all__ = ["UdpRelay", "TcpRelay"]

OnStamp = Callable[[float], None]
OnHeartbeat = Callable[[bool], None]
Local = Callable[[bytes], list[bytes]]
"""the bridge's own component: frames addressed to it in, its replies out"""


class _Relay:
    """What both relays hold: the stamp callbacks, the firmware's heartbeat, the bridge's own
    component, signing at the companion's side."""

    def __init__(self, on_setpoint: OnStamp, on_telemetry: OnStamp, local: tuple[int, Local] | None,
                 on_heartbeat: OnHeartbeat | None) -> None:
        self.on_setpoint, self.on_telemetry = on_setpoint, on_telemetry
        """a setpoint's and a telemetry frame's stamp [s], as they pass"""
        self.local = local
        """(component id, handler): what the companion addresses to that component is answered
        here instead of through the firmware's forwarding (PX4 keeps two forwarded messages a link)"""
        self.on_heartbeat = on_heartbeat
        """the firmware's heartbeat: armed or not"""
        self.on_command: Callable[[], None] | None = None
        """the companion sent a command"""
        self.signing: SignedLink | None = None
        """MAVLink 2 signing at the companion's side (frames in checked, frames out signed)"""


class UdpRelay(_Relay):
    """UDP both ways: the firmware sends to ``firmware_side`` (bound here); what it sends goes on
    to the companion at ``companion`` (PX4: 127.0.0.1:14540), and what comes back goes to the
    firmware's address."""

    def __init__(self, firmware_side: tuple[str, int], companion: tuple[str, int], on_setpoint: OnStamp,
                 on_telemetry: OnStamp, local: tuple[int, Local] | None = None,
                 on_heartbeat: OnHeartbeat | None = None) -> None:
        super().__init__(on_setpoint, on_telemetry, local, on_heartbeat)
        self.fw_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.fw_sock.bind(firmware_side)
        self.fw_sock.setblocking(False)
        self.co_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.co_sock.bind((firmware_side[0], 0))
        self.co_sock.setblocking(False)
        self.companion = companion
        self.firmware_addr: tuple[str, int] | None = None
        self.datagrams = {"down": 0, "up": 0, "dropped": 0}

    def sockets(self) -> list[socket.socket]:
        return [self.fw_sock, self.co_sock]

    def readable(self, sock: socket.socket) -> None:
        for _ in range(256):
            try:
                data, addr = sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # ICMP port unreachable from an absent companion
                self.datagrams["dropped"] += 1
                continue
            if sock is self.fw_sock:
                self.firmware_addr = addr
                msgs = frames(data)[0]
                t = stamps(msgs, CLOCKS_MS, CLOCKS_US)
                if t:
                    self.on_telemetry(t)
                if self.on_heartbeat is not None and (a := armed(msgs)) is not None:
                    self.on_heartbeat(a)
                self._down(data)
            elif self.firmware_addr is not None:
                msgs = frames(data)[0]
                if self.signing is not None:
                    msgs = self.signing.inbound(msgs)
                    data = b"".join(m.raw for m in msgs)
                    if not data:
                        continue
                if self.on_command is not None and any(m.msgid in COMMANDS for m in msgs):
                    self.on_command()
                t = stamps(msgs, SETPOINTS)
                if t:
                    self.on_setpoint(t)
                if self.local is not None:
                    mine, data = for_component(data, self.local[0])
                    if mine:
                        for reply in self.local[1](mine):
                            self._down(reply)
                    if not data:
                        continue
                self._send(self.fw_sock, data, self.firmware_addr, "up")

    def inject(self, data: bytes) -> None:
        """A datagram of the bridge's own (the plant component's heartbeat) to the companion."""
        if self.firmware_addr is not None:
            self._down(data)

    def _down(self, data: bytes) -> None:
        if self.signing is not None:
            data = self.signing.outbound(data)
        if data:
            self._send(self.co_sock, data, self.companion, "down")

    def _send(self, sock: socket.socket, data: bytes, to: tuple[str, int], way: str) -> None:
        try:
            sock.sendto(data, to)
            self.datagrams[way] += 1
        except OSError:  # nobody listening yet, or a full buffer: UDP drops it, so do we
            self.datagrams["dropped"] += 1

    def close(self) -> None:
        for s in self.sockets():
            s.close()


class TcpRelay(_Relay):
    """TCP: companions connect to ``listen`` (ArduPilot's 5760); each gets its own connection to
    the firmware at ``firmware``, bytes relayed both ways."""

    def __init__(self, listen: tuple[str, int], firmware: tuple[str, int], on_setpoint: OnStamp,
                 on_telemetry: OnStamp, local: tuple[int, Local] | None = None,
                 on_heartbeat: OnHeartbeat | None = None) -> None:
        super().__init__(on_setpoint, on_telemetry, local, on_heartbeat)
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(listen)
        self.server.listen(4)
        self.server.setblocking(False)
        self.firmware = firmware
        self.pairs: dict[socket.socket, socket.socket] = {}
        self._bufs: dict[socket.socket, bytearray] = {}
        self._up: set[socket.socket] = set()
        self._pending: dict[socket.socket, bytes] = {}
        self._unpaired: list[socket.socket] = []
        """companions connected before the firmware's port was open"""
        self.bytes = {"down": 0, "up": 0}

    def sockets(self) -> list[socket.socket]:
        return [self.server, *self.pairs, *self._unpaired]

    def readable(self, sock: socket.socket) -> None:
        if sock is self.server:
            self._accept()
            return
        if sock in self._unpaired:
            try:
                if not sock.recv(65536):
                    self._unpaired.remove(sock)
                    sock.close()
            except OSError:
                self._unpaired.remove(sock)
                sock.close()
            return
        data = read_stream(sock)
        if data is None:
            return
        other = self.pairs.get(sock)
        if not data or other is None:
            self._drop(sock)
            return
        up = sock in self._up
        buf = self._bufs[sock]
        buf += data
        msgs, used = frames(buf)
        whole = bytes(buf[:used])
        del buf[:used]
        if len(buf) > 4096:  # never a frame: garbage, passed on as it came (dropped under signing)
            if self.signing is None:
                whole += bytes(buf)
            buf.clear()
        if up and self.signing is not None:
            msgs = self.signing.inbound(msgs)
            whole = b"".join(m.raw for m in msgs)
        if up and self.on_command is not None and any(m.msgid in COMMANDS for m in msgs):
            self.on_command()
        t = stamps(msgs, SETPOINTS) if up else stamps(msgs, CLOCKS_MS, CLOCKS_US)
        if t:
            (self.on_setpoint if up else self.on_telemetry)(t)
        if not up and self.on_heartbeat is not None and (a := armed(msgs)) is not None:
            self.on_heartbeat(a)
        if not up:
            whole += self._pending.pop(other, b"")  # between whole frames
            if self.signing is not None:
                whole = self.signing.outbound(whole)
        elif self.local is not None:
            mine, whole = for_component(whole, self.local[0])
            if mine:
                replies = b"".join(self.local[1](mine))
                if replies:
                    self._pending[sock] = self._pending.get(sock, b"") + replies
        try:
            other.sendall(whole)
            self.bytes["up" if up else "down"] += len(whole)
        except OSError:
            self._drop(sock)

    def inject(self, data: bytes) -> None:
        """Bytes of the bridge's own (the plant component's heartbeat) to each companion, between
        whole frames (the firmware's bytes are relayed as they come and may end inside a frame)."""
        for client in [s for s in self._up if s in self.pairs]:
            self._pending[client] = self._pending.get(client, b"") + data

    def _accept(self) -> None:
        try:
            client, _ = self.server.accept()
        except OSError:
            return
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client.settimeout(2.0)  # recv only when select says so; sendall may wait for a full buffer
        self._unpaired.append(client)
        self.retry()

    def retry(self) -> None:
        """Connect each companion that is still waiting to the firmware (whose port opens a moment
        after it starts); until then what the companion sends is dropped, as a serial port would."""
        for client in list(self._unpaired):
            try:
                fw = socket.create_connection(self.firmware, timeout=0.2)
            except OSError:
                return
            self._unpaired.remove(client)
            fw.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            fw.settimeout(2.0)
            for s in (client, fw):
                self._bufs[s] = bytearray()
            self.pairs[client], self.pairs[fw] = fw, client
            self._up.add(client)

    def _drop(self, sock: socket.socket) -> None:
        other = self.pairs.pop(sock, None)
        for s in (sock, other):
            if s is not None:
                self.pairs.pop(s, None)
                self._bufs.pop(s, None)
                self._pending.pop(s, None)
                self._up.discard(s)
                s.close()

    def close(self) -> None:
        for s in [*self.pairs, *self._unpaired]:
            s.close()
        self.pairs.clear()
        self.server.close()
