"""Nested NamedTuples of numbers as rows of a float64 array, and back inside compiled code.

A batch of vehicles differs in a few numbers (seeds, gains) inside constants that are nested
NamedTuples. Handing compiled code a list of such tuples costs a container type that numba
compiles anew in every process (seconds); a float64 array of one row per vehicle costs nothing.
:func:`codec` writes, for the structure of one example tuple, the two functions that cross:
``pack(value) -> list[float]`` in Python and ``unpack(row, a0, a1, ...)`` (jitable) rebuilding the
tuple, with integers and booleans restored exactly (float64 holds every integer below 2^53) and
the array fields given as arguments, in the order ``arrays(value)`` lists them (arrays are shared by
the whole batch); ``write(row, value)`` (jitable) is ``pack`` inside compiled code. The arrays
travel as plain arguments, not inside a tuple, because numba's parallel loops cannot take a tuple
holding arrays into the loop body.

For a batch flown in lanes (:mod:`.lanes`, W vehicles per register) the same rows, transposed to
columns (``cols[j, i]`` the j-th number of vehicle i), give ``unpack_lanes(cols, i0, a0, ...)``:
the floats of the fields named in ``per_vehicle`` (a dotted path names a field and all below it)
and the integers of those named in ``per_vehicle_ints`` (the noise keys) become lanes of vehicles
``i0 .. i0 + W - 1``; every other number is vehicle ``i0``'s, the batch's own (``uniform``: the
columns that must then hold one value for the whole batch).
"""

from __future__ import annotations

import hashlib
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
    unpack_lanes: Callable[..., Any]
    """``(cols, i0, a0, ...)``: the value of W vehicles (see the module docstring)"""
    uniform: tuple[int, ...]
    """the columns ``unpack_lanes`` reads as the batch's (one value for all vehicles)"""
    write: Callable[[Any, Any], None]
    """``(row, value)`` (jitable): ``pack`` inside compiled code, into a row that exists (arrays left out)"""
    unpack_py: Callable[..., Any]
    """``unpack`` for Python only (a list of the row's numbers: ``row.tolist()``), several times faster"""


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


def codec(example: Any, per_vehicle: tuple[str, ...] = (), per_vehicle_ints: tuple[str, ...] = ()) -> Codec:
    """The codec of ``example``'s structure (NamedTuples and tuples of floats, ints, bools, arrays);
    ``per_vehicle`` (floats) and ``per_vehicle_ints`` (integers): the dotted paths of the fields that
    are lanes in ``unpack_lanes``."""
    shape = _shape(example)
    key = (shape, per_vehicle, per_vehicle_ints)
    if key in _CACHE:
        return _CACHE[key]
    names: dict[str, Any] = {}
    index = [0]
    n_arrays = [0]
    uniform: list[int] = []

    def below(path: str, paths: tuple[str, ...]) -> bool:
        return any(path == p or path.startswith(p + ".") for p in paths)

    writes: list[str] = []

    def build(s: Any, path: str, access: str = "v") -> tuple[str, str, str]:
        """(row expression, lanes expression, Python's row expression) of the field at ``path``
        (``access``: how ``write`` reads it)."""
        if s == "array":
            n_arrays[0] += 1
            return (f"a{n_arrays[0] - 1}",) * 3  # type: ignore[return-value]
        if s in ("bool", "int", "float"):
            j = index[0]
            index[0] += 1
            writes.append(f"    row[{j}] = {'1.0 if ' + access + ' else 0.0' if s == 'bool' else access}\n")
            one = {"bool": f"(row[{j}] != 0.0)", "int": f"int(row[{j}])", "float": f"row[{j}]"}[s]
            if s == "float" and below(path, per_vehicle):
                return one, f"load(cols, {j}, i0)", one
            if s == "int" and below(path, per_vehicle_ints):
                return one, f"load_int(cols, {j}, i0)", one
            uniform.append(j)
            return one, one.replace(f"row[{j}]", f"cols[{j}, i0]"), one
        cls, items = s
        fields = getattr(cls, "_fields", None)
        parts = [build(item, f"{path}.{fields[i] if fields else i}".lstrip("."),
                       f"{access}.{fields[i]}" if fields else f"{access}[{i}]")
                 for i, item in enumerate(items)]
        if cls is tuple:
            return tuple("(" + ", ".join(p[k] for p in parts) + ("," if len(parts) == 1 else "") + ")"
                         for k in (0, 1, 2))  # type: ignore[return-value]
        name = f"T{len(names)}"
        names[name] = cls
        # Python's form skips the NamedTuple's own __new__ (argument handling that costs more than the tuple)
        py = f"_new({name}, (" + ", ".join(p[2] for p in parts) + ("," if len(parts) == 1 else "") + "))"
        return (*(f"{name}(" + ", ".join(p[k] for p in parts) + ")" for k in (0, 1)), py)  # type: ignore[return-value]

    expr, lanes_expr, py_expr = build(shape, "")
    params = "".join(f", a{i}" for i in range(n_arrays[0]))
    # named after the structure: compiled code keeps a function by its name and argument types, and
    # two codecs' unpacks (same arguments, different tuples) compiled in different processes must
    # not meet under one name in a process that loads both from the disk cache
    tag = hashlib.sha256(repr(key).encode()).hexdigest()[:12]
    src = (f"def unpack_{tag}(row{params}):\n    return {expr}\n\n"
           f"def unpack_lanes_{tag}(cols, i0{params}):\n    return {lanes_expr}\n\n"
           f"def write_{tag}(row, v):\n{''.join(writes) or '    pass' + chr(10)}\n"
           f"def unpack_py_{tag}(row{params}):\n    return {py_expr}\n")
    from .lanes import load, load_int

    scope: dict[str, Any] = dict(names, load=load, load_int=load_int, _new=tuple.__new__)
    exec(compile(src, f"<codec of {type(example).__name__}>", "exec"), scope)  # noqa: S102
    unpack = jitable(scope[f"unpack_{tag}"])
    unpack_lanes = jitable(scope[f"unpack_lanes_{tag}"])
    write = jitable(scope[f"write_{tag}"])
    unpack_py = scope[f"unpack_py_{tag}"]

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

    c = Codec(index[0], pack, unpack, arrays, unpack_lanes, tuple(uniform), write, unpack_py)
    _CACHE[key] = c
    return c
