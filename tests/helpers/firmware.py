"""The real autopilots as simulated vehicles: PX4's SIH and ArduCopter's SITL, started headless.

Neither is part of this project: build them from their own sources (docs/autopilots.md) and say
where they are —

- ``PX4_SITL_BUILD``: PX4's build directory for ``px4_sitl_default`` (it holds ``bin/px4`` and
  ``etc/``); PX4 v1.16 with the SIH quadrotor (airframe 10040, no Gazebo);
- ``ARDUCOPTER_SITL``: ArduPilot's ``arducopter`` SITL binary (``build/sitl/bin/arducopter``);
- otherwise they are looked for under ``$ISMDO_AUTOPILOTS`` (default ``~/autopilots``):
  ``px4/PX4-Autopilot/build/px4_sitl_default`` and ``ardupilot/ardupilot/build/sitl/bin/arducopter``.

:func:`find_px4` / :func:`find_arducopter` say where, or why not (the real-autopilot tests skip with
that reason). :class:`Px4Sih` and :class:`ArduCopterSitl` start one instance in a fresh working
directory (factory parameters, nothing left behind) and stop it.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from sitl.firmware.builds import autopilots_root, find_arducopter, find_px4
from sitl.firmware.px4 import PX4_MAX_INSTANCE

__all__ = ["find_px4", "find_arducopter", "Px4Sih", "ArduCopterSitl", "autopilots_root", "worker_instance"]

INSTANCES_PER_WORKER = 5
"""firmware instances each test process may use: pytest-xdist's worker k takes ``5 k .. 5 k + 4``.
PX4's go up to 9 (:data:`~sitl.firmware.px4.PX4_MAX_INSTANCE`), so PX4's tests run on at most two
workers; ArduPilot's have no such limit"""


def worker_instance(n: int = 0) -> int:
    """Firmware instance ``n`` (0-4) of this test process: ``make test`` runs the tier several tests
    at a time, and two firmware instances of one number would share their ports and PX4's lock file.
    ``$FIRMWARE_WORKERS_BEFORE`` shifts a whole pytest run past that many workers' instances: two
    runs side by side (tests/run_tiers.sh's lanes) then never take the same ones."""
    if not 0 <= n < INSTANCES_PER_WORKER:
        raise ValueError(f"instance {n}: a test process has instances 0-{INSTANCES_PER_WORKER - 1}")
    worker = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
    worker += int(os.environ.get("FIRMWARE_WORKERS_BEFORE", "0") or 0)
    return n + INSTANCES_PER_WORKER * worker


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@dataclass
class Px4Sih:
    """One PX4 SIH quadrotor, headless, lockstep at ``speed`` times real time.

    PX4 instance N sends its onboard (API) link from UDP 14580+N to 127.0.0.1:14540+N and latches on
    to whoever answers: the companion listens there (``udpin://127.0.0.1:14540+N``). Its ground-
    station link listens on 18570+N; its system id is N+1."""

    build: Path
    instance: int = field(default_factory=worker_instance)
    speed: float = 4.0
    params: dict[str, float] = field(default_factory=dict)
    """set at boot (PX4_PARAM_<NAME>)"""
    log_ulog: bool = False
    workdir: Path | None = None
    proc: subprocess.Popen[bytes] | None = None

    @property
    def api_port(self) -> int:
        return 14540 + self.instance

    @property
    def url(self) -> str:
        return f"udpin://127.0.0.1:{self.api_port}"

    @property
    def gcs_port(self) -> int:
        return 18570 + self.instance

    @property
    def sysid(self) -> int:
        return self.instance + 1

    def start(self) -> Px4Sih:
        if self.instance > PX4_MAX_INSTANCE:
            raise RuntimeError(f"PX4 instance {self.instance}: PX4's instances are 0-{PX4_MAX_INSTANCE}; run "
                               f"PX4's tests on at most two pytest workers")
        if not (_port_free(self.api_port) and _port_free(14580 + self.instance)):  # a plain `sitl` holds 14580
            first = worker_instance(0)
            free = next((n for n in range(first, first + INSTANCES_PER_WORKER)
                         if _port_free(14540 + n) and _port_free(14580 + n)
                         and not Path(f"/tmp/px4_lock-{n}").exists()), None)
            if free is None:
                raise RuntimeError(f"UDP {self.api_port} is in use, and so are the ports of instances "
                                   f"{first}-{first + INSTANCES_PER_WORKER - 1}")
            self.instance = free  # another instance or client holds this one's ports: take a free one
        self.workdir = Path(tempfile.mkdtemp(prefix=f"px4sih-{self.instance}-"))
        env = {k: v for k, v in os.environ.items() if not k.startswith("PX4_PARAM_")}
        env.update(PX4_SYS_AUTOSTART="10040", PX4_SIMULATOR="sihsim", PX4_SIM_MODEL="sihsim_quadx",
                   PX4_SIM_SPEED_FACTOR=f"{self.speed:g}")
        if not self.log_ulog:
            env["PX4_PARAM_SDLOG_MODE"] = "-1"
        for name, value in self.params.items():
            env[f"PX4_PARAM_{name}"] = f"{value:g}"
        self.proc = subprocess.Popen(
            [str(self.build / "bin" / "px4"), "-d", "-i", str(self.instance), "-w", str(self.workdir),
             str(self.build / "etc")], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
            start_new_session=True)
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.workdir is not None and not self.log_ulog:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> Px4Sih:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


@dataclass
class ArduCopterSitl:
    """One ArduCopter SITL ("+" quad), headless, at ``speedup``; the companion connects over TCP
    (SERIAL0, port 5760+10N, ArduPilot's default; the simulation waits for it) or UDP (``udp_port``:
    SERIAL0 sends there instead)."""

    binary: Path
    instance: int = field(default_factory=worker_instance)
    speedup: float = 4.0
    params: dict[str, float] = field(default_factory=dict)
    home: str = "47.397742,8.545594,488.0,0"
    udp_port: int | None = None
    """SERIAL0 sends to 127.0.0.1:udp_port instead of serving TCP (the companion listens: udpin://)"""
    workdir: Path | None = None
    proc: subprocess.Popen[bytes] | None = None

    DEFAULTS = {"FRAME_CLASS": 1, "FRAME_TYPE": 0, "SIM_SPEEDUP": 1,
                "INS_ACCOFFS_X": 0.001, "INS_ACCOFFS_Y": 0.001, "INS_ACCOFFS_Z": 0.001,
                "INS_ACC2OFFS_X": 0.001, "INS_ACC2OFFS_Y": 0.001, "INS_ACC2OFFS_Z": 0.001}
    """a "+" quad whose accelerometers count as calibrated (else: "3D Accel calibration needed");
    everything else at ArduCopter's own defaults"""

    @property
    def tcp_port(self) -> int:
        return 5760 + 10 * self.instance

    @property
    def url(self) -> str:
        return f"tcp://127.0.0.1:{self.tcp_port}"

    def start(self) -> ArduCopterSitl:
        self.workdir = Path(tempfile.mkdtemp(prefix=f"arducopter-{self.instance}-"))
        params = dict(self.DEFAULTS) | {"SIM_SPEEDUP": self.speedup} | self.params
        defaults = self.workdir / "defaults.parm"
        defaults.write_text("".join(f"{k} {v:g}\n" for k, v in params.items()))
        cmd = [str(self.binary), "--model", "+", "--speedup", f"{self.speedup:g}", "--home", self.home,
               "--defaults", str(defaults), "-I", str(self.instance)]
        if self.udp_port is not None:
            cmd += ["--serial0", f"udpclient:127.0.0.1:{self.udp_port}"]
        self.proc = subprocess.Popen(cmd, cwd=self.workdir, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                     start_new_session=True)
        if self.udp_port is not None:
            return self
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline:  # SERIAL0 listens on TCP once it is up (its clock waits for it)
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.tcp_port)) == 0:
                    break
            if self.proc.poll() is not None:
                raise RuntimeError(f"arducopter exited at start ({self.proc.returncode})")
            time.sleep(0.1)
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> ArduCopterSitl:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
