"""What a flight record says about itself, so that a figure made from it can be cited and redone:
the software (version, commit), the mission and every parameter of the controller, the autopilot
(kind, version; its parameters go to parameters.json), the link and the host."""

from __future__ import annotations

import dataclasses
import datetime
import os
import platform
import subprocess
import sys
from pathlib import Path

from companion import __version__
from companion.link import VehicleLink
from companion.mission import Mission

__all__ = ["flight_metadata", "source_commit"]

ROOT = Path(__file__).resolve().parents[2]


def source_commit() -> str | None:
    """The git commit the code runs from (with ``+changes`` if the tree differs), or None."""
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=5)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return head.stdout.strip() + ("+changes" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


def flight_metadata(mission: Mission, controller: str, output: str, rate_hz: float, link: VehicleLink,
                    backend: str, connect: str) -> dict:
    st = link.state
    return {
        "software": {"project": "ismdo-companion", "version": __version__, "commit": source_commit(),
                     "python": sys.version.split()[0]},
        "started_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "mission": dataclasses.asdict(mission),
        "controller": {"position": controller, "rate_hz": rate_hz, "output": output},
        "autopilot": {"kind": st.autopilot, "sysid": st.sysid, "compid": st.compid,
                      "version": getattr(link, "autopilot_version", None), "mode_at_connect": st.mode},
        "link": {"backend": backend, "connect": connect},
        "host": {"name": platform.node(), "platform": platform.platform(), "machine": platform.machine(),
                 "cpus": os.cpu_count()},
    }
