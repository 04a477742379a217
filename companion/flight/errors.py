"""How a flight ends when it does not complete, and the exit codes the command line returns."""

from __future__ import annotations

__all__ = ["LinkLost", "MissionAbort", "Interrupted", "EXIT_CODES"]

EXIT_CODES = {"completed": 0, "aborted": 1, "link lost": 3, "interrupted": 130}


class LinkLost(RuntimeError):
    """No telemetry from the vehicle for longer than the link-lost bound."""


class MissionAbort(RuntimeError):
    """The mission cannot go on (refused command, offboard left, timeout, safety volume left)."""


class Interrupted(Exception):
    """The operator pressed Ctrl-C (SIGINT) or the process got SIGTERM."""
