"""PX4 SITL on the project's plant, through its simulator MAVLink API.

PX4 (``px4_sitl_default``, v1.16) starts with the generic SITL quadrotor (airframe 10016) and
``simulator_mavlink``, which connects to TCP 4560+N, where :class:`Px4Bridge` serves the plant:
HIL_SENSOR at 250 Hz (four plant steps of 1 ms each), HIL_GPS at the receiver's rate or ODOMETRY
(external vision) as tracking samples are delivered; PX4 answers each HIL_SENSOR with
HIL_ACTUATOR_CONTROLS once its modules have run (lockstep: its clock is the plant's). The
parameters of :func:`~.airframe.px4_parameters` are applied through ``PX4_PARAM_*``; PX4 runs from
a copy of its ``etc/`` (symbolic links, in a fresh working directory) whose only change is the
MAVLink links of ``airframes/px4-rc.mavlink``: its API link goes to the bridge's relay, and a link
of its own carries the plant's component. Nothing is written into the user's PX4 tree.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from .airframe import AIRFRAMES
from .bridge import Bridge
from .px4_wire import MotorOutputs, Px4Wire
from .sockets import read_stream
from .builds import die_with_parent

__all__ = ["Px4Ports", "Px4Process", "Px4Bridge", "PX4_AIRFRAME"]

PX4_AIRFRAME = 10016
"""PX4's generic SITL quadrotor (none_iris): simulator_mavlink, no simulator of its own"""
FRAME_STEPS = 4
"""plant steps (1 ms) per HIL_SENSOR: PX4's 250 Hz IMU"""


PX4_MAX_INSTANCE = 9
"""PX4's highest instance: its own px4-rc.mavlink sends the API link of every instance above 9 to
14549, and instance 10's companion port would be 14550, where every instance's ground-station link
sends"""


@dataclass(frozen=True)
class Px4Ports:
    instance: int = 0

    @property
    def simulator(self) -> int:
        return 4560 + self.instance

    @property
    def companion(self) -> int:
        """where the companion listens (udpin://0.0.0.0:14540+N), as with PX4's own simulators"""
        return 14540 + self.instance

    @property
    def gcs(self) -> int:
        """PX4's ground-station link (it sends to QGroundControl on 14550)"""
        return 18570 + self.instance

    @property
    def relay(self) -> int:
        """PX4's API link sends here, the relay passes it on to :attr:`companion`"""
        return 24540 + self.instance

    @property
    def plant(self) -> int:
        return 24560 + self.instance

    @property
    def plant_firmware(self) -> int:
        """PX4's MAVLink instance for the plant component listens here"""
        return 24580 + self.instance


class Px4Process:
    """One PX4 SITL process in a fresh working directory (factory parameters, deleted after)."""

    def __init__(self, build: Path, ports: Px4Ports, params: dict[str, float], workdir: Path) -> None:
        self.build, self.ports, self.params, self.workdir = build, ports, params, workdir
        self.proc: subprocess.Popen[bytes] | None = None
        self.log = workdir / "px4.log"

    def _overlay(self) -> Path:
        """A copy of PX4's etc/ made of links, with our MAVLink links in place of PX4's."""
        src = self.build / "etc"
        dst = self.workdir / "etc"
        dst.mkdir()
        for entry in src.iterdir():
            if entry.name != "init.d-posix":
                (dst / entry.name).symlink_to(entry)
        posix = dst / "init.d-posix"
        posix.mkdir()
        for entry in (src / "init.d-posix").iterdir():
            if entry.name != "px4-rc.mavlink":
                (posix / entry.name).symlink_to(entry)
        ours = posix / "px4-rc.mavlink"
        ours.write_text((AIRFRAMES / "px4-rc.mavlink").read_text())
        ours.chmod(0o755)
        return dst

    def start(self) -> Px4Process:
        etc = self._overlay()
        rootfs = self.workdir / "rootfs"
        rootfs.mkdir()
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PX4_", "ISMDO_"))}
        env.update(PX4_SYS_AUTOSTART=str(PX4_AIRFRAME), PX4_SIM_MODEL="none_iris",
                   ISMDO_API_PORT=str(self.ports.relay), ISMDO_PLANT_PORT=str(self.ports.plant),
                   ISMDO_PLANT_FW_PORT=str(self.ports.plant_firmware))
        env.update({f"PX4_PARAM_{k}": f"{v:g}" for k, v in self.params.items()})
        with open(self.log, "wb") as log:
            self.proc = subprocess.Popen([str(self.build / "bin" / "px4"), "-d", "-i", str(self.ports.instance),
                                          "-w", str(rootfs), str(etc)], stdout=log, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, env=env, start_new_session=True,
                                         preexec_fn=die_with_parent)
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        p = self.proc
        if p is not None and p.poll() is None:
            p.send_signal(signal.SIGINT)
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()


class Px4Bridge(Bridge):
    """The plant on PX4's simulator link (TCP, PX4 connects)."""

    def __init__(self, *args: object, ports: Px4Ports, vision: bool, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.ports = ports
        self.vision = vision
        self.wire = Px4Wire()
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind(("127.0.0.1", ports.simulator))
        self.listener.listen(1)
        self.listener.setblocking(False)
        self.register(self.listener, self._accept)
        self.conn: socket.socket | None = None
        self.outputs = MotorOutputs(0, (0.0,) * 16, False)
        self.lockstep = False
        """PX4 has answered a frame: from now on every frame waits for its answer"""
        self.awaiting_us: int | None = None
        self._sent_wall = 0.0

    def _accept(self, sock: socket.socket) -> None:
        try:
            conn, _ = self.listener.accept()
        except OSError:
            return
        if self.conn is not None:  # one PX4 at a time
            conn.close()
            return
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn.settimeout(2.0)
        self.conn = conn
        self.register(conn, self._readable)

    def _readable(self, sock: socket.socket) -> None:
        data = read_stream(sock)
        if data is None:
            return
        if not data:
            self.unregister(sock)
            sock.close()
            self.conn = None
            return
        for out in self.wire.parse(data):
            self.outputs = out
            self.lockstep = True
            if self.awaiting_us is not None and out.time_usec >= self.awaiting_us:
                self.awaiting_us = None

    def firmware_waiting(self) -> bool:
        return self.conn is not None and self.awaiting_us is None

    def firmware_wait_expired(self, now: float) -> bool:
        if self.awaiting_us is not None and now - self._sent_wall > self.FIRMWARE_WAIT_WALL_S:
            self.stats.firmware_late += 1
            self.awaiting_us = None
            return self.conn is not None
        return False

    def step_frame(self) -> None:
        assert self.conn is not None
        out = self.outputs
        frame = self.world.step(out.controls, out.armed, FRAME_STEPS)
        data = b"".join(self.wire.frame(frame, self.vision))
        try:
            self.conn.sendall(data)
        except OSError:
            return
        if self.lockstep:
            self.awaiting_us = int(round(frame.t_s * 1e6))
            self._sent_wall = time.monotonic()

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
        self.listener.close()
        super().close()
