"""Percentiles of a window of recent samples, in milliseconds, for the processes' exit reports.

Shared by the vehicle (sitl.autopilot.server) and the relay (sitl.netem.relay), two programs that
must not import each other, so it stands at the top of sitl/ and imports nothing of it."""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["percentiles_ms"]


def percentiles_ms(samples_s: Iterable[float]) -> dict[str, float]:
    """p50, p99 and max of ``samples_s`` [s] in ms, and how many there were ({} for none)."""
    xs = sorted(samples_s)
    if not xs:
        return {}
    pick = lambda f: round(1000.0 * xs[min(len(xs) - 1, int(f * len(xs)))], 3)  # noqa: E731
    return {"p50": pick(0.5), "p99": pick(0.99), "max": round(1000.0 * xs[-1], 3), "n": len(xs)}
