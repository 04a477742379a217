"""Nested NamedTuples of numbers as rows of a float64 array, and back inside compiled code.

A batch of vehicles differs in a few numbers (seeds, gains) inside constants that are nested
NamedTuples. Handing compiled code a list of such tuples costs a container type that numba
compiles anew in every process (seconds); a float64 array of one row per vehicle costs nothing.
:func:`codec` writes, for the structure of one example tuple, the two functions that cross:
``pack(value) -> list[float]`` in Python and ``unpack(row, a0, a1, ...)`` (jitable) rebuilding the
tuple, with integers and booleans restored exactly (float64 holds every integer below 2^53) and
the array fields given as arguments, in the order ``arrays(value)`` lists them (arrays are shared by
the whole batch). The arrays travel as plain arguments, not inside a tuple, because numba's
parallel loops cannot take a tuple holding arrays into the loop body.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import numpy as np

from companion.control.jit import jitable

__all__ = ["Codec", "codec"]


class Codec(NamedTuple):
    size: int
    """numbers per row"""
    pack: Callable[[Any], list[float]]
    unpack: Callable[..., Any]
    arrays: Callable[[Any], tuple[Any, ...]]
    """the array fields of a value, in the order ``unpack`` takes them"""


_CACHE: dict[tuple[Any, ...], Codec] = {}


def _shape(value: Any) -> Any:
    """A hashable description of ``value``'s structure: types of every leaf, recursively."""
    if isinstance(value, np.ndarray):
        return "array"
    if isinstance(value, tuple):
        return (type(value), tuple(_shape(v) for v in value))
    if isinstance(value, (bool, np.bool_)):
        return "bool"
    if isinstance(value, (int, np.integer)):
        return "int"
    return "float"


def codec(example: Any) -> Codec:
    """The codec of ``example``'s structure (NamedTuples and tuples of floats, ints, bools, arrays)."""
    shape = _shape(example)
    if shape in _CACHE:
        return _CACHE[shape]
    names: dict[str, Any] = {}
    index = [0]
    n_arrays = [0]

    def build(s: Any, path: str) -> str:
        if s == "array":
            n_arrays[0] += 1
            return f"a{n_arrays[0] - 1}"
        if s == "bool":
            index[0] += 1
            return f"(row[{index[0] - 1}] != 0.0)"
        if s == "int":
            index[0] += 1
            return f"int(row[{index[0] - 1}])"
        if s == "float":
            index[0] += 1
            return f"row[{index[0] - 1}]"
        cls, items = s
        parts = [build(item, f"{path}[{i}]") for i, item in enumerate(items)]
        if cls is tuple:
            return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"
        name = f"T{len(names)}"
        names[name] = cls
        return f"{name}(" + ", ".join(parts) + ")"

    expr = build(shape, "value")
    params = "".join(f", a{i}" for i in range(n_arrays[0]))
    src = f"def unpack(row{params}):\n    return {expr}\n"
    scope: dict[str, Any] = dict(names)
    exec(compile(src, f"<codec of {type(example).__name__}>", "exec"), scope)  # noqa: S102
    unpack = jitable(scope["unpack"])

    def pack(value: Any) -> list[float]:
        out: list[float] = []

        def walk(v: Any) -> None:
            if isinstance(v, np.ndarray):
                return
            if isinstance(v, tuple):
                for x in v:
                    walk(x)
            else:
                out.append(float(v))

        walk(value)
        return out

    def arrays(value: Any) -> tuple[Any, ...]:
        out: list[Any] = []

        def walk(v: Any) -> None:
            if isinstance(v, np.ndarray):
                out.append(v)
            elif isinstance(v, tuple):
                for x in v:
                    walk(x)

        walk(value)
        return tuple(out)

    c = Codec(index[0], pack, unpack, arrays)
    _CACHE[shape] = c
    return c
