"""The bundled simulated vehicle as a child process: one harness for the demo, the tests and the
benchmarks.

It runs ``python -m sitl`` (the companion never imports ``sitl``: the vehicle is another program on
the wire), on a port the system picks, in a session of its own so that a Ctrl-C in the terminal
reaches the companion — which then holds, lands and disarms — and not the vehicle under it.
:meth:`VehicleProcess.stop` returns the vehicle's exit report.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

__all__ = ["VehicleProcess", "FirmwareVehicle"]

_LISTENING = re.compile(r"listening on udp://([\d.]+):(\d+)")
_FIRMWARE = re.compile(r"flying the plant .*: companion (\S+?)[,;]")


class VehicleProcess:
    def __init__(self, *args: str, speedup: float = 4.0, env: dict[str, str] | None = None,
                 cwd: Path | None = None, own_session: bool = True, port: int = 0,
                 interpreter_args: tuple[str, ...] = ()) -> None:
        """``port`` 0 lets the system pick one (read back from the banner); ``interpreter_args`` go
        before ``-m sitl`` (a benchmark runs the vehicle under ``-m cProfile -o FILE``)."""
        self.speedup = speedup
        cmd = [sys.executable, *interpreter_args, "-m", "sitl", "--listen", f"127.0.0.1:{port}",
               "--speedup", f"{speedup:g}", *args]
        child_env = {k: v for k, v in os.environ.items() if k != "MAVLINK_SIGNING_KEY"} if env is None else env
        child_env = {**child_env, "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=child_env, start_new_session=own_session)
        self.banner: list[str] = []
        self.port = 0
        while True:
            line = self.proc.stdout.readline()  # type: ignore[union-attr]
            self.banner.append(line)
            found = _LISTENING.search(line)
            if found:
                self.port = int(found.group(2))
                break
            if not line or len(self.banner) > 5:
                rest = self.proc.communicate(timeout=5)[0]
                raise RuntimeError(f"the simulated vehicle did not start: {''.join(self.banner)}{rest}")
        self.report: dict | None = None

    @property
    def url(self) -> str:
        """``HOST:PORT`` (connect with ``udp://`` + this)."""
        return f"127.0.0.1:{self.port}"

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout_s: float = 10.0) -> dict:
        """SIGTERM, then the vehicle's exit report (RuntimeError if it gave none)."""
        if self.report is not None:
            return self.report
        if self.alive():
            self.proc.send_signal(signal.SIGTERM)
        try:
            out = self.proc.communicate(timeout=timeout_s)[0]
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out = self.proc.communicate()[0]
        for line in out.splitlines():
            if line.startswith("sitl: stopped "):
                self.report = json.loads(line[len("sitl: stopped "):])
                return self.report
        raise RuntimeError(f"the simulated vehicle gave no report (exit {self.proc.returncode}):\n{out}")

    def kill(self) -> None:
        if self.alive():
            self.proc.kill()
            self.proc.wait()


class FirmwareVehicle(VehicleProcess):
    """A real autopilot's SITL build flying the plant (``python -m sitl --firmware px4|ardupilot``):
    the same harness, the companion's URL read from the banner (PX4: ``udpin://0.0.0.0:14540+N``,
    ArduCopter: ``tcp://127.0.0.1:5760+10N``)."""

    def __init__(self, firmware: str, *args: str, speedup: float = 4.0, lockstep_ms: float = 10.0,
                 instance: int = 0, env: dict[str, str] | None = None, cwd: Path | None = None,
                 own_session: bool = True) -> None:
        self.speedup = speedup
        cmd = [sys.executable, "-m", "sitl", "--firmware", firmware, "--instance", str(instance),
               "--speedup", f"{speedup:g}", *(("--lockstep", f"{lockstep_ms:g}") if lockstep_ms else ()), *args]
        child_env = {k: v for k, v in os.environ.items() if k != "MAVLINK_SIGNING_KEY"} if env is None else env
        self.proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env={**child_env, "PYTHONUNBUFFERED": "1"}, start_new_session=own_session)
        self.banner = []
        self.port = 0
        self.report = None
        while True:
            line = self.proc.stdout.readline()  # type: ignore[union-attr]
            self.banner.append(line)
            found = _FIRMWARE.search(line)
            if found:
                self.companion_url = found.group(1)
                break
            if not line or len(self.banner) > 5:
                rest = self.proc.communicate(timeout=10)[0]
                raise RuntimeError(f"the firmware did not start: {''.join(self.banner)}{rest}")

    @property
    def url(self) -> str:
        return self.companion_url
