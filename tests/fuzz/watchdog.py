"""Hang detection for fuzzing: an input that keeps a handler busy for ``seconds`` (orders of
magnitude beyond any real one) fails the example instead of stalling CI."""

from __future__ import annotations

import contextlib
import signal
from typing import Iterator

__all__ = ["Hang", "no_hang"]


class Hang(AssertionError):
    pass


@contextlib.contextmanager
def no_hang(seconds: float) -> Iterator[None]:
    def expired(signum: int, frame: object) -> None:
        raise Hang(f"input still being handled after {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
