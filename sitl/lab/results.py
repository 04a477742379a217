"""What an experiment produced: its cases (controller combination and seed) and, per case, the
segment metrics and the flight logs kept for figures. Written by :mod:`sitl.lab.experiments`,
judged by :mod:`sitl.lab.claims`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..plant.scenario import Scenario
from .metrics import SegmentMetrics
from .simulation import FlightLog

__all__ = ["Case", "ExperimentResult"]


@dataclass(frozen=True)
class Case:
    position: str
    attitude: str
    seed: int

    @property
    def key(self) -> str:
        return f"{self.position}__{self.attitude}__seed{self.seed}"


@dataclass
class ExperimentResult:
    scenario: Scenario
    metrics: dict[Case, list[SegmentMetrics]] = field(default_factory=dict)
    logs: dict[Case, FlightLog] = field(default_factory=dict)
    """flight logs kept for plotting: the first seed of every combination"""
    figure: Path | None = None

    def rows(self) -> list[dict[str, object]]:
        out: list[dict[str, object]] = []
        for case, segs in self.metrics.items():
            for m in segs:
                out.append({"position": case.position, "attitude": case.attitude, "seed": case.seed, **m.as_row()})
        return out

    def values(self, field_name: str, segment: str | None = None) -> dict[tuple[str, str], list[float]]:
        """A metric over seeds per (position, attitude), for one segment (default: the first)."""
        out: dict[tuple[str, str], list[float]] = {}
        for case, segs in self.metrics.items():
            m = next(s for s in segs if segment is None or s.segment == segment)
            out.setdefault((case.position, case.attitude), []).append(float(getattr(m, field_name)))
        return out
