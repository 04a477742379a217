"""Seeded Gaussian noise, drawn in blocks for speed, one independent stream per use and vehicle.

Every random element of the simulation takes ``(seed, stream)``: the vehicle's seed and a fixed
stream number for the element (gyro, wind, ...), so adding an element never changes another's
numbers. In a batch, vehicle ``i`` draws from its own generator seeded like a one-vehicle run
with ``seed[i]``: a batched case reproduces the one-vehicle run bit for bit.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from .rng import STREAMS

__all__ = ["GaussianStream", "STREAMS", "rng_for"]


def rng_for(seed: int, stream: str) -> np.random.Generator:
    return np.random.default_rng([int(seed), STREAMS[stream]])


class GaussianStream:
    """Standard-normal samples, ``channels`` per step, for one vehicle or a batch.

    ``next()`` returns a list of ``channels`` floats (one vehicle, ``seeds`` an int) or an array
    of shape ``(channels, N)`` (``seeds`` a sequence of N ints).
    """

    def __init__(self, seeds: int | Sequence[int], stream: str, channels: int, block: int = 1000) -> None:
        self.channels = channels
        self.block = block
        self.batch = not isinstance(seeds, (int, np.integer))
        seed_list = [int(s) for s in seeds] if self.batch else [int(seeds)]  # type: ignore[union-attr]
        self._rngs = [rng_for(s, stream) for s in seed_list]
        self._k = block
        self._buf: list[list[float]] | NDArray[np.float64] = []

    def _refill(self) -> None:
        if self.batch:
            draws = [r.standard_normal((self.block, self.channels)) for r in self._rngs]
            self._buf = np.ascontiguousarray(np.stack(draws, axis=-1))  # (block, channels, N)
        else:
            self._buf = self._rngs[0].standard_normal((self.block, self.channels)).tolist()
        self._k = 0

    def next(self) -> list[float] | NDArray[np.float64]:
        if self._k >= self.block:
            self._refill()
        row = self._buf[self._k]
        self._k += 1
        return row

    def initial(self) -> list[float] | NDArray[np.float64]:
        """One draw outside the block sequence (e.g. a constant bias), same shape as ``next``."""
        if self.batch:
            return np.stack([r.standard_normal(self.channels) for r in self._rngs], axis=-1)
        return self._rngs[0].standard_normal(self.channels).tolist()
