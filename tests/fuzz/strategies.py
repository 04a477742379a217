"""Hypothesis strategies for hostile MAVLink input: frames of real message types with any field
values (NaN, inf, extremes, garbage strings), then cut, bit-flipped, glued together or replaced by
noise. Frames are packed by pymavlink, so most arrive intact and reach the handlers."""

from __future__ import annotations

import os
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

FUZZ_EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "150"))
"""examples per fuzz test: small in CI (bounded time), large for the documented long run (make fuzz)"""

FUZZ = settings(max_examples=FUZZ_EXAMPLES, deadline=None, database=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.filter_too_much])

# commands the vehicle acts on, and values that mean something to them
COMMANDS = (400, 22, 21, 20, 17, 176, 511, 512, 520, 410, 519, 246, 0, 65535)
MEANINGFUL = (0.0, 1.0, -1.0, 0.5, 2.0, 4.0, 6.0, 21196.0, 1e6, 1e-6, 33.0, 32.0, 31.0)

_INT_RANGES = {
    "uint8_t": (0, 255), "int8_t": (-128, 127), "uint16_t": (0, 65535), "int16_t": (-32768, 32767),
    "uint32_t": (0, 2**32 - 1), "int32_t": (-2**31, 2**31 - 1), "uint64_t": (0, 2**64 - 1),
    "int64_t": (-2**63, 2**63 - 1),
}


def _scalar(name: str, ftype: str) -> st.SearchStrategy[Any]:
    if name == "target_system":
        return st.sampled_from((0, 1, 1, 1, 2, 255))
    if name == "target_component":
        return st.sampled_from((0, 1, 1, 190, 255))
    if name == "command":
        return st.one_of(st.sampled_from(COMMANDS), st.integers(0, 65535))
    if ftype in ("float", "double"):
        return st.one_of(st.sampled_from(MEANINGFUL), st.floats(width=32 if ftype == "float" else 64))
    lo, hi = _INT_RANGES[ftype]
    return st.one_of(st.sampled_from((lo, hi, 0, 1)), st.integers(lo, hi))


def _field(cls: Any, name: str) -> st.SearchStrategy[Any]:
    ftype = cls.fieldtypes[cls.fieldnames.index(name)]
    length = cls.array_lengths[cls.ordered_fieldnames.index(name)]
    if ftype == "char":
        known = (b"SIM_WIND_N", b"MPC_XY_VEL_MAX", b"COM_OF_LOSS_T", b"", b"\xff" * 16)
        return st.one_of(st.sampled_from(known), st.binary(max_size=length or 1))
    if length:
        if name == "q":
            return st.one_of(
                st.sampled_from(([1.0, 0.0, 0.0, 0.0], [0.0] * 4, [float("nan")] * 4, [2.0, 0.0, 0.0, 0.0])),
                st.lists(st.floats(width=32), min_size=length, max_size=length))
        return st.lists(_scalar(name, ftype), min_size=length, max_size=length)
    return _scalar(name, ftype)


def message(cls: Any) -> st.SearchStrategy[Any]:
    """An instance of a pymavlink message class with any field values."""
    return st.fixed_dictionaries({n: _field(cls, n) for n in cls.fieldnames}).map(lambda kw: cls(**kw))


def frame(classes: tuple[Any, ...], srcs: tuple[int, ...] = (255,)) -> st.SearchStrategy[bytes]:
    """One packed MAVLink 2 frame of one of ``classes``, sent from one of ``srcs``."""

    def pack(msg: Any, src: int, seq: int) -> bytes:
        mav = mavlink.MAVLink(None, srcSystem=src, srcComponent=190)
        mav.seq = seq
        return bytes(msg.pack(mav))

    return st.builds(pack, st.one_of(*(message(c) for c in classes)), st.sampled_from(srcs), st.integers(0, 255))


def _mutate(data: bytes, how: int, pos: int, value: int) -> bytes:
    if not data:
        return bytes([value])
    pos %= len(data)
    if how == 0:
        return data[:pos]  # truncated
    if how == 1:
        return data[:pos] + bytes([data[pos] ^ (1 << (value % 8))]) + data[pos + 1:]  # a bit flipped
    if how == 2:
        return data[:pos] + bytes([value]) + data[pos + 1:]  # a byte replaced
    if how == 3:
        return data[:pos] + data[pos:] * 3  # a tail repeated
    return data[:pos] + bytes([value]) * 40 + data[pos:]  # noise inserted


def datagram(classes: tuple[Any, ...], srcs: tuple[int, ...] = (255,)) -> st.SearchStrategy[bytes]:
    """A UDP payload: mostly intact frames (one or several), sometimes damaged, sometimes noise."""
    frames = st.lists(frame(classes, srcs), min_size=1, max_size=4).map(b"".join)
    damaged = st.builds(_mutate, frames, st.integers(0, 4), st.integers(0, 10_000), st.integers(0, 255))
    return st.one_of(frames, frames, damaged, st.binary(max_size=300))
