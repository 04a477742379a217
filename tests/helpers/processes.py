"""Real processes for the tests: the bundled vehicle, the relay, the companion, a ground station,
and a host that stalls them. Shared by tests/integration and tests/autopilots."""

from __future__ import annotations

import contextlib
import json
import math
import os
import random
import signal
import socket
import subprocess
import sys
import threading
import time
from typing import Any
from pathlib import Path

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.events import EventCatalogue, parse_event
from companion.vehicle_process import VehicleProcess
from sitl.autopilot.events import catalogue

_CATALOGUE = EventCatalogue.from_bytes(catalogue())

ROOT = Path(__file__).resolve().parents[2]


def child_env(**extra: str) -> dict[str, str]:
    """The environment for a child process: unbuffered, and no signing key unless a test gives one
    (a developer's own MAVLINK_SIGNING_KEY must not change what the tests fly)."""
    env = {k: v for k, v in os.environ.items() if k != "MAVLINK_SIGNING_KEY"}
    env.update(PYTHONUNBUFFERED="1", **extra)
    return env


class Staller:
    """A host that steals CPU, made repeatable: from a seeded schedule, stops (SIGSTOP) one of the
    given processes or all of them for a random while, lets them run (SIGCONT), waits, again.
    Exponential gaps (mean ``mean_gap_s``), stalls uniform in ``stall_s``, all wall time."""

    def __init__(self, pids: list[int], seed: int, mean_gap_s: float = 0.15,
                 stall_s: tuple[float, float] = (0.01, 0.08)) -> None:
        self.pids, self.rng = pids, random.Random(seed)
        self.mean_gap_s, self.stall_s = mean_gap_s, stall_s
        self.stalls, self.stalled_s = 0, 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        choices = [[p] for p in self.pids] + [self.pids]
        while not self._stop.wait(self.rng.expovariate(1.0 / self.mean_gap_s)):
            which, d = self.rng.choice(choices), self.rng.uniform(*self.stall_s)
            try:
                for p in which:
                    os.kill(p, signal.SIGSTOP)
                time.sleep(d)
            except ProcessLookupError:
                break
            finally:
                for p in which:
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(p, signal.SIGCONT)
            self.stalls, self.stalled_s = self.stalls + 1, self.stalled_s + d

    def stop(self) -> tuple[int, float]:
        """Stop stalling (everything left running); the stalls made and their total [s]."""
        self._stop.set()
        self._thread.join()
        return self.stalls, self.stalled_s


def kill_left_over(procs: list) -> None:
    """Fixture teardown: whatever a test left running is killed (a failed test must not leak processes)."""
    for p in procs:
        if p.proc.poll() is None:
            p.proc.kill()
            p.proc.wait()


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class SitlProcess(VehicleProcess):
    """``python -m sitl`` in its own process (companion/vehicle_process.py), started from the
    checkout with the test environment; :meth:`stop` returns its final report."""

    def __init__(self, *args: str, speedup: float = 2.0, env: dict[str, str] | None = None,
                 port: int | None = None) -> None:
        super().__init__(*args, speedup=speedup, env=child_env(**(env or {})), cwd=ROOT, own_session=False,
                         port=port or 0)


class RelayProcess:
    """``python -m sitl.netem.relay`` between a client and a vehicle; :meth:`stop` returns its counters."""

    def __init__(self, to: str, *args: str) -> None:
        cmd = [sys.executable, "-m", "sitl.netem.relay", "--listen", "127.0.0.1:0", "--to", to, *args]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=child_env())
        line = self.proc.stdout.readline()  # type: ignore[union-attr]
        if "listening on" not in line:
            raise RuntimeError(f"relay did not start: {line}{self.proc.communicate(timeout=5)[0]}")
        self.url = line.split("listening on ")[1].split(",")[0]
        self.report: dict | None = None

    def outage_now(self) -> None:
        self.proc.send_signal(signal.SIGUSR1)

    def stop(self) -> dict:
        if self.report is None:
            if self.proc.poll() is None:
                self.proc.send_signal(signal.SIGTERM)
            out = self.proc.communicate(timeout=10)[0]
            line = next(ln for ln in out.splitlines() if ln.startswith("relay: stopped "))
            self.report = json.loads(line[len("relay: stopped "):])
        return self.report


def text_of(msg) -> str | None:
    """What a STATUSTEXT says, or an EVENT (PX4, and the bundled vehicle's px4 flavour) read with
    the catalogue; None for any other message."""
    kind = msg.get_type()
    if kind == "STATUSTEXT":
        return msg.text
    if kind == "UNKNOWN_410":
        raw = bytes(msg.get_msgbuf())
        event = parse_event(raw[10:10 + raw[1]])
        return _CATALOGUE.text(event) if event is not None else None
    return None


class Client:
    """A pymavlink ground station on a fresh UDP socket, talking to one vehicle."""

    def __init__(self, url: str, source_system: int = 255) -> None:
        self.m = mavutil.mavlink_connection(f"udpout:{url}", source_system=source_system, source_component=190)
        self.m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                  mavlink.MAV_STATE_UNINIT)
        self.seen: dict[str, object] = {}
        self.texts: list[str] = []

    def recv(self, timeout: float = 0.2):
        """The next message, waiting up to ``timeout`` s (0: only what is already queued)."""
        msg = self.m.recv_match(blocking=timeout > 0, timeout=timeout if timeout > 0 else None)
        if msg is not None:
            kind = msg.get_type()
            self.seen[kind] = msg
            text = text_of(msg)
            if text is not None:
                self.texts.append(text)
        return msg

    def wait(self, kind: str | tuple[str, ...], cond=lambda m: True, timeout: float = 10.0):
        kinds = (kind,) if isinstance(kind, str) else kind
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self.recv(0.1)
            if msg is not None and msg.get_type() in kinds and cond(msg):
                return msg
        raise AssertionError(f"no {kinds} within {timeout} s")

    def latest(self, kind: str, timeout: float = 5.0):
        """The newest message of ``kind``: drain what is queued, then wait for one if none."""
        newest = None
        while (msg := self.recv(0.0)) is not None:
            if msg.get_type() == kind:
                newest = msg
        return newest if newest is not None else self.wait(kind, timeout=timeout)

    def text(self, fragment: str, timeout: float = 10.0) -> str:
        """A STATUSTEXT or EVENT text containing ``fragment``, already received or arriving within ``timeout``."""
        end = time.monotonic() + timeout
        while True:
            for t in self.texts:
                if fragment in t:
                    return t
            if time.monotonic() > end:
                raise AssertionError(f"no text with {fragment!r} within {timeout} s: {self.texts[-10:]}")
            self.recv(0.1)

    def command(self, command: int, *params: float, timeout: float = 5.0) -> int:
        p = list(params) + [0.0] * (7 - len(params))
        self.m.mav.command_long_send(1, 1, command, 0, *p)
        ack = self.wait("COMMAND_ACK", lambda a: a.command == command, timeout)
        return ack.result

    def set_mode(self, main: int, sub: int = 0) -> int:
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub)

    def attitude_target(self, q, rates=(0.0, 0.0, 0.0), thrust: float = 0.5, type_mask: int = 0,
                        target=(1, 1)) -> None:
        self.m.mav.set_attitude_target_send(0, target[0], target[1], type_mask, list(q), *rates, thrust)

    def param(self, name: str, timeout: float = 5.0, tries: int = 3) -> float:
        """A parameter's value now; asked again if no answer (a busy vehicle may learn our address
        late). What is already queued is read first: the vehicle announces every change to every
        client, and an old announcement must not pass for the answer."""
        while self.recv(0) is not None:
            pass
        for attempt in range(tries):
            self.m.mav.param_request_read_send(1, 1, name.encode(), -1)
            try:
                return self.wait("PARAM_VALUE", lambda p: p.param_id == name, timeout / tries).param_value
            except AssertionError:
                if attempt == tries - 1:
                    raise
        raise AssertionError(name)

    def close(self) -> None:
        self.m.close()


def quat_angle_deg(a, b) -> float:
    """Rotation angle between two attitudes, accurate near zero (atan2 form, not acos)."""
    from companion.control import quaternion as quat

    return math.degrees(quat.angle_between(tuple(float(x) for x in a), tuple(float(x) for x in b)))


class CompanionProcess:
    """``python -m companion fly ...`` in its own process; :meth:`wait_for` watches its output."""

    def __init__(self, mission: str, url: str, out_dir: Path, *args: str, env: dict[str, str] | None = None) -> None:
        connect = url if "://" in url else f"udp://{url}"
        cmd = [sys.executable, "-m", "companion", "fly", str(ROOT / mission), "--connect", connect,
               "--out", str(out_dir), "--no-plots", *args]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=child_env(**(env or {})))
        self.lines: list[str] = []
        self.out_dir = out_dir
        self._pending = ""
        """output read from the pipe that is not yet a whole line"""
        self._decoder: Any = None

    def wait_for(self, fragment: str, timeout: float = 60.0) -> str:
        """The first new line of output containing ``fragment``. Reads the pipe's bytes itself: a
        text readline() buffers the lines that came with it, which select() no longer sees, so a
        line could wait for more output before it was looked at."""
        import codecs
        import select

        if self._decoder is None:
            self._decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
        fd = self.proc.stdout.fileno()  # type: ignore[union-attr]
        end = time.monotonic() + timeout
        while True:
            while "\n" in self._pending:
                line, self._pending = self._pending.split("\n", 1)
                self.lines.append(line + "\n")
                if fragment in line:
                    return line + "\n"
            if time.monotonic() >= end:
                break
            if select.select([fd], [], [], 0.2)[0]:
                chunk = os.read(fd, 65536)
                if not chunk:
                    break
                self._pending += self._decoder.decode(chunk)
        raise AssertionError(f"companion never printed {fragment!r}; output:\n{''.join(self.lines)}{self._pending}")

    def finish(self, timeout: float = 120.0) -> tuple[int, str]:
        out, _ = self.proc.communicate(timeout=timeout)
        self.lines.append(self._pending + out)
        self._pending = ""
        return self.proc.returncode, "".join(self.lines)

    def flight_dir(self) -> Path:
        for line in reversed("".join(self.lines).splitlines()):  # "companion: <result>: ... -> FOLDER"
            if line.startswith("companion: ") and " -> " in line:
                return Path(line.rsplit(" -> ", 1)[1].strip())
        dirs = sorted(p for p in self.out_dir.iterdir() if p.is_dir())
        assert dirs, "no flight folder written"
        return dirs[-1]


LOCKSTEP = ("--lockstep",)
"""the world advances 10 ms per setpoint (sitl --lockstep): flights whose subject is control measure
the same on a busy host, only slower"""
LOCKSTEP_SPEEDUP = 8.0
PAPER = ("--flavour", "paper")
"""the bundled vehicle with the paper's inner loop (attitude and body rates flown together)"""
PAPER_OUTPUT = ("--output", "attitude_rates")
"""the companion's setpoints for that inner loop: attitude, body rates and thrust"""
POSITION_WAIT = ("--position-wait", "60")
"""the companion waits for the position of a vehicle with the ardupilot flavour, which has none
for its first 40 simulated seconds (ArduCopter's EKF origin): 20 s of wall time at 2x"""
