"""ArduCopter SITL on the project's plant, through its JSON physics interface.

ArduCopter runs with ``--model JSON``: every physics frame it sends its servo outputs (a binary
packet: magic, frame rate, frame count, 16 or 32 PWM values) to UDP 9002+10N and waits for the
answer, one line of JSON with the state after the frame (time, IMU, position, attitude, velocity;
``libraries/SITL/SIM_JSON.cpp``). :class:`ArduPilotBridge` answers each with one plant step
(SIM_RATE_HZ 1000): lockstep, ArduPilot's clock is the plant's. ArduPilot makes its barometer,
compass and GNSS from that state with its own SITL models (SIM_BARO_RND, ...); motion capture
reaches it as VISION_POSITION_ESTIMATE from the plant's component on SERIAL2. SERIAL0, where the
companion connects (TCP 5760+10N), is served by the relay; ArduPilot's own SERIAL0 listens behind
it. The parameters of :func:`~.airframe.ardupilot_parameters` go into its defaults file.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

from .bridge import Bridge
from .world import SensorFrame
from .builds import die_with_parent

__all__ = ["ArduPilotPorts", "ArduPilotProcess", "ArduPilotBridge", "servo_packet", "state_line"]

MAGIC_16, MAGIC_32 = 18458, 29569
_HEADER = struct.Struct("<HHI")


@dataclass(frozen=True)
class ArduPilotPorts:
    instance: int = 0

    @property
    def companion(self) -> int:
        """SERIAL0 as users know it (tcp://127.0.0.1:5760+10N), served by the relay"""
        return 5760 + 10 * self.instance

    @property
    def serial0(self) -> int:
        """ArduPilot's own SERIAL0, behind the relay"""
        return 25760 + 10 * self.instance

    @property
    def json(self) -> int:
        return 9002 + 10 * self.instance

    @property
    def plant(self) -> int:
        """the plant component's UDP port (ArduPilot's SERIAL2 sends here)"""
        return 25762 + 10 * self.instance


def servo_packet(data: bytes) -> tuple[int, int, tuple[int, ...]] | None:
    """``(frame_rate, frame_count, pwm)`` of a servo packet, or None if it is not one."""
    if len(data) < _HEADER.size:
        return None
    magic, rate, count = _HEADER.unpack_from(data)
    n = 16 if magic == MAGIC_16 else 32 if magic == MAGIC_32 else 0
    if n == 0 or len(data) < _HEADER.size + 2 * n:
        return None
    return rate, count, struct.unpack_from(f"<{n}H", data, _HEADER.size)


def state_line(f: SensorFrame) -> bytes:
    """The JSON state ArduPilot reads (it scans for ``"key":[a, b, c]``; the line must be
    framed by newlines)."""
    s = f.state
    doc = {"timestamp": f.t_s, "imu": {"gyro": list(f.gyro_rad_s), "accel_body": list(f.accel_m_s2)},
           "position": list(s.pos_ned_m), "quaternion": list(s.q), "velocity": list(s.vel_ned_m_s)}
    return ("\n" + json.dumps(doc, separators=(",", ":")) + "\n").encode()


class ArduPilotProcess:
    """One ArduCopter SITL process in a fresh working directory (factory parameters)."""

    def __init__(self, binary: Path, ports: ArduPilotPorts, params: dict[str, float], workdir: Path,
                 home: str) -> None:
        self.binary, self.ports, self.params, self.workdir, self.home = binary, ports, params, workdir, home
        self.proc: subprocess.Popen[bytes] | None = None
        self.log = workdir / "arducopter.log"

    def start(self) -> ArduPilotProcess:
        defaults = self.workdir / "defaults.parm"
        defaults.write_text("".join(f"{k} {v:g}\n" for k, v in self.params.items()))
        p = self.ports
        cmd = [str(self.binary), "--model", "JSON:127.0.0.1", "--speedup", "1000", "--home", self.home,
               "--defaults", str(defaults), "-I", str(p.instance), "--sim-port-out", str(p.json),
               "--serial0", f"tcp:{p.serial0}", "--serial2", f"udpclient:127.0.0.1:{p.plant}"]
        with open(self.log, "wb") as log:
            self.proc = subprocess.Popen(cmd, cwd=self.workdir, stdout=log, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True,
                                         preexec_fn=die_with_parent)
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        """SIGKILL: ArduPilot ignores SIGTERM while it waits for the physics (it checks its exit
        flag in its main loop only), and a fresh working directory has nothing to save."""
        p = self.proc
        if p is not None and p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


class ArduPilotBridge(Bridge):
    """The plant on ArduPilot's JSON link (UDP: ArduPilot sends servo packets, we answer)."""

    def __init__(self, *args: object, ports: ArduPilotPorts, vision: bool, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.ports = ports
        self.vision = vision
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", ports.json))
        self.sock.setblocking(False)
        self.register(self.sock, self._readable)
        self.pending: tuple[int, tuple[int, ...], tuple[str, int]] | None = None
        """(frame count, PWM, sender) of the packet waiting for its answer"""
        self.answered: tuple[int, bytes] | None = None
        self.bad_packets = 0
        self.repeats = 0

    def _readable(self, sock: socket.socket) -> None:
        for _ in range(64):
            try:
                data, addr = sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                continue
            packet = servo_packet(data)
            if packet is None:
                self.bad_packets += 1
                continue
            _, count, pwm = packet
            if self.answered is not None and count == self.answered[0]:
                self.repeats += 1  # ArduPilot sends again after 1 s without an answer: answer again
                self._send(self.answered[1], addr)
                continue
            self.pending = (count, pwm, addr)

    def _send(self, line: bytes, addr: tuple[str, int]) -> None:
        try:
            self.sock.sendto(line, addr)
        except OSError:
            pass

    def firmware_waiting(self) -> bool:
        return self.pending is not None

    def step_frame(self) -> None:
        assert self.pending is not None
        count, pwm, addr = self.pending
        self.pending = None
        outputs = tuple((p - 1000) / 1000.0 for p in pwm[:4])
        frame = self.world.step(outputs, True, 1)
        line = state_line(frame)
        self.answered = (count, line)
        self._send(line, addr)
        if self.vision and frame.tracked:
            self.plant.send([self.component.vision(s) for s in frame.tracked])

    def close(self) -> None:
        self.sock.close()
        super().close()
