"""Where the real autopilots' SITL builds are: neither is part of this project (docs/autopilots.md
says how to build them from their own sources).

- ``PX4_SITL_BUILD``: PX4's build directory for ``px4_sitl_default`` (``bin/px4`` and ``etc/``);
- ``ARDUCOPTER_SITL``: ArduPilot's ``arducopter`` SITL binary (``build/sitl/bin/arducopter``);
- otherwise under ``$ISMDO_AUTOPILOTS`` (default ``~/autopilots``):
  ``px4/PX4-Autopilot/build/px4_sitl_default`` and ``ardupilot/ardupilot/build/sitl/bin/arducopter``.

:func:`find_px4` / :func:`find_arducopter` say where, or why not.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

__all__ = ["autopilots_root", "find_px4", "find_arducopter", "px4_build", "arducopter_binary", "die_with_parent"]


def autopilots_root() -> Path:
    return Path(os.environ.get("ISMDO_AUTOPILOTS", str(Path.home() / "autopilots"))).expanduser()


def px4_build(path: str | Path | None = None) -> tuple[Path | None, str]:
    """PX4's build directory (``path``, else PX4_SITL_BUILD, else the default place), or None and why not."""
    env = os.environ.get("PX4_SITL_BUILD")
    if path is not None:
        build, where = Path(path).expanduser(), f"--firmware-path {path}"
    elif env:
        build, where = Path(env).expanduser(), "PX4_SITL_BUILD"
    else:
        build = autopilots_root() / "px4/PX4-Autopilot/build/px4_sitl_default"
        where = f"the default location {build}"
    if not (build / "bin" / "px4").is_file():
        return None, (f"no PX4 SITL build: set PX4_SITL_BUILD to a px4_sitl_default build directory "
                      f"({where} has no bin/px4)")
    if not (build / "etc" / "init.d-posix" / "rcS").is_file():
        return None, f"{build} has no etc/init.d-posix/rcS: not a PX4 SITL build"
    return build, ""


def arducopter_binary(path: str | Path | None = None) -> tuple[Path | None, str]:
    """ArduCopter's SITL binary (``path``, else ARDUCOPTER_SITL, else the default place), or None and why not."""
    env = os.environ.get("ARDUCOPTER_SITL")
    if path is not None:
        binary, where = Path(path).expanduser(), f"--firmware-path {path}"
    elif env:
        binary, where = Path(env).expanduser(), "ARDUCOPTER_SITL"
    else:
        binary = autopilots_root() / "ardupilot/ardupilot/build/sitl/bin/arducopter"
        where = f"the default location {binary}"
    if not binary.is_file() or not os.access(binary, os.X_OK):
        return None, f"no ArduCopter SITL: set ARDUCOPTER_SITL to an arducopter SITL binary ({where} is not one)"
    return binary, ""


def find_px4() -> tuple[Path | None, str]:
    return px4_build()


def find_arducopter() -> tuple[Path | None, str]:
    return arducopter_binary()


PR_SET_PDEATHSIG = 1
"""prctl(2): the signal a child gets when the process that started it dies"""


def die_with_parent() -> None:
    """For ``preexec_fn``: the firmware is killed (SIGKILL) when the bridge that started it dies,
    however it dies. A bridge killed outright used to leave PX4 running in its own session, still
    sending to the relay port the next bridge binds: that one relayed two PX4s of one system id
    ("two autopilots claim system 8", telemetry outages, setpoints sent to the dead flight's PX4).
    Linux only; elsewhere nothing."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        pass
