"""Which autopilot parameters the companion changed, and what each must be put back to.

A pure, immutable record (no link, no clock): :class:`ParamChanges` (:mod:`.prepare`) asks it
what to write and tells it what happened. Every write goes through it — a mission's ``set_param``
step, a preparation (ArduPilot's GUIDED settings), an implicit one (PX4's ``MIS_TAKEOFF_ALT``,
written by the take-off) — *before* the write is sent, so a flight stopped between the write and
its echo still puts the parameter back.

The rules:

- a parameter is put back to the value it had before the companion's first write (its
  *baseline*);
- a write marked ``keep`` (a step's ``keep = true``: the user means the value to stay) moves the
  baseline to that value: nothing is put back for it, unless a later write without ``keep``
  changes the parameter again, which is then put back to the kept value;
- a parameter whose last written value is its baseline needs nothing.

The record's :meth:`ParamRecord.summary` lists, by name, what was put back, what could not be
(with the value to set by hand) and what was kept as the mission asked.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

__all__ = ["ParamEntry", "ParamRecord", "same_value"]


def same_value(a: float, b: float) -> bool:
    """Equal as a float32 parameter holds them (MAVLink carries parameters as float32)."""
    return math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9)


@dataclass(frozen=True)
class ParamEntry:
    original: float
    """the value before the companion's first write"""
    baseline: float
    """what the parameter is put back to: the original, or the value a ``keep`` write left"""
    written: float
    """the companion's last written value"""
    kept: bool = False
    """a write marked ``keep`` moved the baseline"""
    outcome: str = ""
    """"" (not yet put back), "restored" or "not restored\""""

    @property
    def needs_restore(self) -> bool:
        return self.outcome == "" and not same_value(self.written, self.baseline)


@dataclass(frozen=True)
class ParamRecord:
    entries: tuple[tuple[str, ParamEntry], ...] = ()
    """in the order of the first write"""

    def get(self, name: str) -> ParamEntry | None:
        return dict(self.entries).get(name)

    def written(self, name: str, found: float, value: float, keep: bool = False) -> ParamRecord:
        """The companion is about to write ``value`` to ``name``, which holds ``found`` now."""
        old = self.get(name)
        if old is None:
            entry = ParamEntry(found, value if keep else found, value, kept=keep)
        else:
            entry = dataclasses.replace(old, written=value, baseline=value if keep else old.baseline,
                                        kept=old.kept or keep, outcome="")
        return self._with(name, entry)

    def to_restore(self) -> tuple[tuple[str, float], ...]:
        """(name, value) to write back, the last changed first (a preparation's later writes may
        depend on its earlier ones)."""
        return tuple((name, e.baseline) for name, e in reversed(self.entries) if e.needs_restore)

    def restored(self, name: str) -> ParamRecord:
        return self._outcome(name, "restored")

    def not_restored(self, name: str) -> ParamRecord:
        return self._outcome(name, "not restored")

    def give_up(self) -> ParamRecord:
        """Whatever still needs putting back could not be."""
        record = self
        for name, _ in self.to_restore():
            record = record.not_restored(name)
        return record

    @property
    def pending(self) -> bool:
        return bool(self.to_restore())

    def summary(self) -> dict[str, dict[str, float]]:
        """``restored``: name -> the value put back; ``not_restored``: name -> the value it should
        have (set it by hand); ``kept``: name -> the value left as the mission asked."""
        out: dict[str, dict[str, float]] = {"restored": {}, "not_restored": {}, "kept": {}}
        for name, e in self.entries:
            if e.outcome == "restored":
                out["restored"][name] = e.baseline
            elif e.outcome == "not restored" or e.needs_restore:
                out["not_restored"][name] = e.baseline
            if e.kept and same_value(e.written, e.baseline):
                out["kept"][name] = e.baseline
        return out

    def _outcome(self, name: str, outcome: str) -> ParamRecord:
        old = self.get(name)
        assert old is not None, f"{name} was never written"
        return self._with(name, dataclasses.replace(old, outcome=outcome))

    def _with(self, name: str, entry: ParamEntry) -> ParamRecord:
        items = dict(self.entries)
        items[name] = entry  # a name keeps the place of its first write
        return ParamRecord(tuple(items.items()))
