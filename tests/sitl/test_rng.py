"""The counter-based generator (sitl/plant/rng.py): Gaussian, white, independent, reproducible.

Bounds are four standard errors of the statistic for n independent standard normals (a false
alarm once in ~16,000 checks; the seeds are fixed, so each check is deterministic)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl.plant import rng

N = 40_000


def draws(seed: int, stream: str = "gyro", channel: int = 0, n: int = N, start: int = 0) -> np.ndarray:
    k = rng.key(seed, rng.STREAMS[stream], channel)
    return np.array([rng.normal(k, c) for c in range(start, start + n)])


@pytest.fixture(scope="module")
def z() -> np.ndarray:
    return draws(1)


def test_moments_and_tails_are_a_standard_normals(z: np.ndarray) -> None:
    n = len(z)
    assert abs(z.mean()) < 4.0 / math.sqrt(n)
    assert abs(z.var() - 1.0) < 4.0 * math.sqrt(2.0 / n)
    assert abs(((z - z.mean()) ** 4).mean() - 3.0) < 4.0 * math.sqrt(96.0 / n)  # var of z^4 is 96
    for k in (1.0, 2.0, 3.0):
        p = math.erfc(k / math.sqrt(2.0))
        assert abs((np.abs(z) > k).mean() - p) < 4.0 * math.sqrt(p * (1 - p) / n), k


def test_distribution_passes_kolmogorov_smirnov(z: np.ndarray) -> None:
    s = np.sort(z)
    cdf = 0.5 * (1.0 + np.array([math.erf(x / math.sqrt(2.0)) for x in s]))
    i = np.arange(1, len(s) + 1) / len(s)
    d = max(np.max(i - cdf), np.max(cdf - (i - 1.0 / len(s))))
    assert d < 1.95 / math.sqrt(len(s))  # 0.1 % critical value


def test_sequence_is_white(z: np.ndarray) -> None:
    for lag in (1, 2, 3, 10, 60, 1000):
        r = np.corrcoef(z[:-lag], z[lag:])[0, 1]
        assert abs(r) < 4.0 / math.sqrt(len(z)), lag


@pytest.mark.parametrize("other", [dict(channel=1), dict(stream="accel"), dict(stream="wind"), dict(seed=2),
                                   dict(seed=1 + 2**32)])
def test_channels_streams_and_seeds_are_independent(z: np.ndarray, other: dict) -> None:
    args = dict(seed=1, stream="gyro", channel=0) | other
    w = draws(**args)  # type: ignore[arg-type]
    for lag in (0, 1):
        r = np.corrcoef(z[lag:], w[: len(w) - lag])[0, 1]
        assert abs(r) < 4.0 / math.sqrt(len(z)), (other, lag)


def test_any_sample_is_reproducible_without_the_ones_before() -> None:
    seq = draws(7, "mocap", 3, n=50, start=10**9)
    k = rng.key(7, rng.STREAMS["mocap"], 3)
    assert rng.normal(k, 10**9 + 37) == seq[37]
    assert rng.normals(7, "mocap", 4, 10**9 + 5)[3] == seq[5]


def test_compiled_draws_are_the_interpreted_ones_bit_for_bit() -> None:
    pytest.importorskip("numba")
    from companion.control.jit import kernel

    @kernel
    def compiled(seed: int, n: int, out: np.ndarray) -> None:
        k = rng.key(seed, 4, 2)
        for c in range(n):
            out[c] = rng.normal(k, c)

    out = np.empty(5000)
    compiled(3, len(out), out)
    assert np.array_equal(out, draws(3, "wind", 2, n=len(out)))
