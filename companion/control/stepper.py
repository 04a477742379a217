"""What every control law's wrapper shares: its constants built once per step length.

Each law is a ``*_const`` record (gains turned into per-step coefficients), a ``*_state`` record and
a pure ``*_step(const, state, ...)``; the compiled kernel calls the step functions directly, and
the interpreted callers use a thin wrapper that holds the state and derives from :class:`Stepper`.
"""

from __future__ import annotations

from typing import Any, Generic, TypeVar

__all__ = ["Stepper"]

C = TypeVar("C")


class Stepper(Generic[C]):
    """A law's constants from :meth:`_build`, rebuilt only when the step length changes; its state
    held, and put back at rest by :meth:`reset`."""

    _const: C | None = None
    _dt: float = -1.0
    state: Any
    """the law's state record: a dataclass field of the wrapper, its default the state at rest"""

    def _build(self, dt_s: float) -> C:
        raise NotImplementedError

    def const(self, dt_s: float) -> C:
        if self._const is None or self._dt != dt_s:
            self._const, self._dt = self._build(dt_s), dt_s
        return self._const

    def reset(self) -> None:
        """Back to the state at rest: the ``state`` field's default (a dict lookup: the autopilot
        resets its loops every plant step while on the ground)."""
        self.state = type(self).__dataclass_fields__["state"].default_factory()  # type: ignore[attr-defined]
