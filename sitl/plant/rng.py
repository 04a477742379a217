"""Counter-based Gaussian noise: each draw is a pure function of (seed, stream, channel, counter).

Nothing is stored but one integer key per channel, so a vehicle's noise costs no memory however
long it flies, a batch of vehicles draws inside the compiled loop, and any sample can be
recomputed without replaying the ones before it (the idea of Salmon et al., "Parallel random
numbers: as easy as 1, 2, 3", SC 2011). The mixing function is a 32-bit integer hash (two
xorshift-multiply rounds, constant 0x45d9f3b) kept in 64-bit integers whose products never
overflow, so Python's integers and numba's int64 give the same bits, interpreted or compiled.

- :func:`key` ``(seed, stream, channel)``: one independent sequence per vehicle seed, random
  element (:data:`STREAMS`) and channel (an axis); computed once per vehicle.
- :func:`bits` ``(key, counter, attempt)``: 32 random bits, the counter-th of that sequence
  (``attempt`` > 0 only inside the normal sampler's rare rejections).
- :func:`normal` ``(key, counter)``: a standard normal by Marsaglia and Tsang's ziggurat (128
  layers; "The ziggurat method for generating random variables", J. Stat. Softw. 5(8), 2000) in
  its floating-point form, with the layer and the position in it taken from different bits
  (the 32-bit original shares them, Doornik 2005): one hash and one comparison for 98.8 % of the
  draws, where Box-Muller needs a logarithm, a square root and a sine.
- :func:`uniform` ``(key, counter)``: a uniform in (0, 1).

``tests/sitl/test_rng.py`` checks the moments and tails, the spectrum (white) and the independence
of channels, streams and seeds.
"""

from __future__ import annotations

import math

import numpy as np

from companion.control.jit import depends_on, jitable, lanewise
from companion.control.vector import all_of, where

depends_on(__file__)

__all__ = ["STREAMS", "MASK32", "mix32", "key", "bits", "uniform", "layer_draw", "normal", "beyond_rectangle",
           "normals"]

STREAMS = {
    "gyro": 1,
    "accel": 2,
    "mocap": 3,
    "wind": 4,
    "bias": 5,
    "baro": 6,
    "mag": 7,
    "gnss": 8,
    "gnss_start": 9,
}
"""A fixed number per random element, so adding an element never changes another's numbers."""

MASK32 = 0xFFFFFFFF
_M = 0x45D9F3B  # < 2^27: a 32-bit value times this stays below 2^59
_GOLDEN = 0x9E3779B9


@jitable
def mix32(x: int) -> int:
    """A bijection of [0, 2^32) with full avalanche (every input bit flips each output bit with
    probability ~1/2)."""
    x = (((x >> 16) ^ x) * _M) & MASK32
    x = (((x >> 16) ^ x) * _M) & MASK32
    return (x >> 16) ^ x


@jitable
def key(seed: int, stream: int, channel: int) -> int:
    """The key of one sequence: vehicle ``seed`` (a non-negative integer below 2^64), ``stream``
    (:data:`STREAMS`) and ``channel`` (an axis or a purpose within the stream)."""
    k = mix32((seed & MASK32) ^ mix32((seed >> 32) & MASK32))
    k = mix32(k ^ ((stream * _GOLDEN) & MASK32))
    return mix32(k ^ mix32((channel + 0x51ED27) & MASK32))


@jitable
def bits(k: int, counter: int, attempt: int) -> int:
    """32 random bits: the ``counter``-th (a non-negative integer below 2^64) of sequence ``k``."""
    x = mix32((counter & MASK32) ^ k)
    return mix32(x ^ ((k + (counter >> 32) + attempt * _GOLDEN) & MASK32))


@jitable
def uniform(k: int, counter: int) -> float:
    """The ``counter``-th uniform of sequence ``k``, in (0, 1) (32 bits)."""
    return (bits(k, counter, 0) + 0.5) * 2.3283064365386963e-10


def _ziggurat_tables() -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Layer edges x_0 > x_1 = r > ... > x_128 = 0 of the 128-layer ziggurat of exp(-x^2 / 2)
    (each layer, and the base with its tail, of area v), and f at those edges."""
    r, v = 3.442619855899, 9.91256303526217e-3
    f = math.exp(-0.5 * r * r)
    xs = [v / f, r]
    for _ in range(126):
        xs.append(math.sqrt(-2.0 * math.log(v / xs[-1] + math.exp(-0.5 * xs[-1] * xs[-1]))))
    xs.append(0.0)
    return tuple(xs), tuple(math.exp(-0.5 * x * x) for x in xs)


_X_TABLE, _F_TABLE = _ziggurat_tables()
_X = np.array(_X_TABLE)  # compiled code reads a global array as a constant; a tuple indexed at
_F = np.array(_F_TABLE)  # run time would be copied to the stack at each draw
_R = 3.442619855899
_INV_2_24 = 1.0 / 16777216.0


@jitable
def layer_draw(b: int) -> tuple[float, float, bool]:
    """The ziggurat's first test of 32 random bits ``b``: (z, sign, inside) -- ``sign * z`` is the
    draw when ``inside`` (z under the layer's rectangle: 97.2 % of 200 000 draws). Integer and float
    arithmetic only, so a batch in lanes runs it for its vehicles at once."""
    layer = b & 127
    sign = ((b >> 7) & 1) * 2.0 - 1.0  # exactly 1.0 or -1.0
    z = ((b >> 8) + 0.5) * _INV_2_24 * float(_X[layer])
    return z, sign, z < float(_X[layer + 1])


@jitable
def normal(k: int, counter: int) -> float:
    """The ``counter``-th standard normal of sequence ``k`` (ziggurat, see the module docstring):
    the first test (:func:`layer_draw`) for every vehicle of a batch at once, the rest
    (:func:`beyond_rectangle`) only when one of them needs it."""
    z, sign, inside = layer_draw(bits(k, counter, 0))
    if all_of(inside):
        return sign * z
    return where(inside, sign * z, beyond_rectangle(k, counter))


@lanewise
def beyond_rectangle(k: int, counter: int) -> float:
    """:func:`normal` by the whole ziggurat, the wedges and the tail included (a batch in lanes
    runs it vehicle by vehicle: loops and logarithms)."""
    attempt = 0
    while True:
        b = bits(k, counter, attempt)
        z, sign, inside = layer_draw(b)
        if inside:
            return sign * z
        layer = b & 127
        if layer == 0:  # the base's tail beyond r (Marsaglia 1964)
            while True:
                attempt += 1
                a = -math.log(uniform(k ^ 0x2545F491, counter * 64 + attempt)) / _R
                c = -math.log(uniform(k ^ 0x6C8E9CF5, counter * 64 + attempt))
                if c + c > a * a:
                    return sign * (_R + a)
        attempt += 1
        u = uniform(k ^ 0x7F4A7C15, counter * 64 + attempt)
        f_outer, f_inner = float(_F[layer]), float(_F[layer + 1])
        if f_inner + u * (f_outer - f_inner) < math.exp(-0.5 * z * z):  # in the wedge
            return sign * z


def normals(seed: int, stream: str, channels: int, counter: int) -> list[float]:
    """``channels`` standard normals of ``stream`` at ``counter`` (channel i from sequence i), as a
    vehicle draws them; for tests and one-off draws in Python."""
    s = STREAMS[stream]
    return [normal(key(seed, s, i), counter) for i in range(channels)]
